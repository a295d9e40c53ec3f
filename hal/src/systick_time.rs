//! The L475 board's time base: SysTick, the core's own timer, as
//! embassy-time's driver and as the step tick's source.
//!
//! The F4 boards use embassy's TIM5 driver and TIM2 for the step tick. On
//! the B-L475E-IOT01A the core's SysTick does both: it interrupts
//! [`TICK_HZ`] times a second, counts the periods for the clock and wakes
//! the timers that are due, and once the step tick is on it pends `TIM2`,
//! so that the firmware's own step-tick handler runs on the same vector
//! and at the same priority as on the other boards (TIM2's counter itself
//! is left off). SysTick is also the one timer that QEMU's model of the
//! board has, which is what lets test.sh boot the whole binary there
//! (docs/firmware.md).
//!
//! [`now`](embassy_time_driver::Driver::now) counts 1 µs ticks: the periods
//! since start and the clocks into the current one, so an ST4 edge is
//! stamped to the microsecond as on the F4 boards.

use core::cell::{Cell, RefCell};
use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use cortex_m::peripheral::scb::SystemHandler;
use cortex_m::peripheral::syst::SystClkSource;
use cortex_m::peripheral::{NVIC, SCB, SYST};
use critical_section::CriticalSection;
use embassy_stm32::interrupt::Priority;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use embassy_time_driver::Driver;
use embassy_time_queue_utils::Queue;

/// SysTick interrupts per second, and so the step tick's rate on this
/// board: the configuration's `step_tick_hz` must be this.
#[cfg(not(feature = "emulator-tick"))]
pub const TICK_HZ: u32 = 50_000;
/// Test-only (feature `emulator-tick`, never for a board): a fiftieth of
/// the interrupts, the lowest tick the configuration allows (main.rs lowers
/// the top speed to match). QEMU's cost is per interrupt, so the board
/// test's long run emulates its 31 minutes in a few (docs/decisions.md,
/// "Booting the binary in QEMU").
#[cfg(feature = "emulator-tick")]
pub const TICK_HZ: u32 = 1_000;

/// embassy-time's ticks per second (its default tick rate).
const DRIVER_HZ: u32 = 1_000_000;

struct SysTickDriver {
    /// SysTick periods since [`start`].
    periods: Mutex<CriticalSectionRawMutex, Cell<u64>>,
    /// Core clocks per period and per driver tick (0 before [`start`]).
    clocks_per_period: AtomicU32,
    clocks_per_tick: AtomicU32,
    /// The earliest instant a timer waits for (`u64::MAX`: none).
    alarm: Mutex<CriticalSectionRawMutex, Cell<u64>>,
    queue: Mutex<CriticalSectionRawMutex, RefCell<Queue>>,
}

embassy_time_driver::time_driver_impl!(static DRIVER: SysTickDriver = SysTickDriver {
    periods: Mutex::new(Cell::new(0)),
    clocks_per_period: AtomicU32::new(0),
    clocks_per_tick: AtomicU32::new(0),
    alarm: Mutex::new(Cell::new(u64::MAX)),
    queue: Mutex::new(RefCell::new(Queue::new())),
});

/// The step tick is on: each SysTick pends `TIM2`.
static STEP_TICK: AtomicBool = AtomicBool::new(false);

impl SysTickDriver {
    fn now_in(&self, cs: CriticalSection) -> u64 {
        let per_period = self.clocks_per_period.load(Ordering::Relaxed);
        let per_tick = u64::from(self.clocks_per_tick.load(Ordering::Relaxed).max(1));
        let mut periods = self.periods.borrow(cs).get();
        let mut left = SYST::get_current();
        // The counter wrapped and its exception has not run yet (this is a
        // critical section, or an interrupt above it): the value read may
        // be from before the wrap or after it; read it again, after.
        if SCB::is_pendst_pending() {
            left = SYST::get_current();
            periods += 1;
        }
        let into_period = per_period.saturating_sub(1).saturating_sub(left);
        (periods * u64::from(per_period) + u64::from(into_period)) / per_tick
    }

    /// One SysTick period has passed: count it and wake the timers due.
    fn on_period(&self) {
        critical_section::with(|cs| {
            let periods = self.periods.borrow(cs);
            periods.set(periods.get() + 1);
            let now = self.now_in(cs);
            let alarm = self.alarm.borrow(cs);
            if now < alarm.get() {
                return;
            }
            // Borrowed only in critical sections and never across one:
            // cannot fail (and no borrow panic is linked in).
            if let Ok(mut queue) = self.queue.borrow(cs).try_borrow_mut() {
                alarm.set(queue.next_expiration(now));
            }
        })
    }
}

impl Driver for SysTickDriver {
    fn now(&self) -> u64 {
        critical_section::with(|cs| self.now_in(cs))
    }

    fn schedule_wake(&self, at: u64, waker: &core::task::Waker) {
        critical_section::with(|cs| {
            if let Ok(mut queue) = self.queue.borrow(cs).try_borrow_mut() {
                if queue.schedule_wake(at, waker) {
                    let now = self.now_in(cs);
                    self.alarm.borrow(cs).set(queue.next_expiration(now));
                }
            }
        })
    }
}

/// Starts SysTick on the core clock (`sysclk_hz`, a whole multiple of
/// [`TICK_HZ`]) at `priority`. Called once, by [`crate::clocks::init`].
pub(crate) fn start(sysclk_hz: u32, priority: Priority) {
    let per_period = sysclk_hz / TICK_HZ;
    DRIVER
        .clocks_per_period
        .store(per_period, Ordering::Relaxed);
    DRIVER
        .clocks_per_tick
        .store(sysclk_hz / DRIVER_HZ, Ordering::Relaxed);
    // SAFETY: SysTick and its priority are this module's alone; nothing
    // else in the firmware takes the core peripherals.
    let mut core = unsafe { cortex_m::Peripherals::steal() };
    // SAFETY: the priority is set before the exception is enabled.
    unsafe {
        core.SCB
            .set_priority(SystemHandler::SysTick, u8::from(priority))
    };
    core.SYST.set_clock_source(SystClkSource::Core);
    core.SYST.set_reload(per_period.saturating_sub(1));
    core.SYST.clear_current();
    core.SYST.enable_interrupt();
    core.SYST.enable_counter();
}

/// Turns the step tick on or off: while on, each SysTick pends `TIM2`.
pub(crate) fn set_step_tick(on: bool) {
    STEP_TICK.store(on, Ordering::Relaxed);
}

#[cortex_m_rt::exception]
fn SysTick() {
    if STEP_TICK.load(Ordering::Relaxed) {
        NVIC::pend(embassy_stm32::interrupt::TIM2);
    }
    DRIVER.on_period();
}
