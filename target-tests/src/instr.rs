//! Instruction counting on the emulated Cortex-M4, for benchmarks.
//!
//! Under `qemu-system-arm -machine mps2-an386 -icount shift=0` (the runner in
//! .cargo/config.toml) QEMU's virtual clock advances exactly 1 ns per
//! executed instruction, and SysTick, clocked from the 25 MHz system clock
//! of the MPS2 board (CLKSOURCE = processor clock), ticks once every
//! 40 ns, i.e. once per 40 instructions. DWT's cycle counter is not emulated.
//!
//! [`start`] runs SysTick with the full 24-bit reload (a wrap every 2^24
//! ticks = 671,088,640 instructions) and counts wraps in the SysTick
//! exception; [`elapsed_instructions`] combines both.
//!
//! Resolution: 40 instructions (one tick). Overhead: the reads in
//! `elapsed_instructions` add about one tick, and each wrap adds the few tens
//! of instructions of the SysTick handler. These are instructions, not
//! cycles: on real silicon loads, branches, divisions and flash wait states
//! cost more than one cycle. Without `-icount` the figures follow host time
//! and mean nothing. Call `elapsed_instructions` with interrupts enabled.

use core::sync::atomic::{AtomicU32, Ordering};
use cortex_m::peripheral::{syst::SystClkSource, SYST};
use cortex_m_rt::exception;

/// SysTick clock of mps2-an386 (processor clock), in Hz.
pub const SYSTICK_HZ: u64 = 25_000_000;
/// Instructions per SysTick tick under `-icount shift=0` (1 ns each).
pub const INSTRUCTIONS_PER_TICK: u64 = 1_000_000_000 / SYSTICK_HZ;

const RELOAD: u32 = 0x00ff_ffff;

static WRAPS: AtomicU32 = AtomicU32::new(0);
static mut BASE: u32 = 0;

#[exception]
fn SysTick() {
    WRAPS.fetch_add(1, Ordering::Relaxed);
}

/// (Re)starts the counter at zero.
pub fn start() {
    // SAFETY: the test binary owns SysTick; nothing else uses it.
    let mut syst = unsafe { cortex_m::Peripherals::steal() }.SYST;
    syst.disable_interrupt();
    syst.disable_counter();
    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload(RELOAD);
    syst.clear_current();
    syst.enable_counter();
    // Writing CVR clears it to 0; the counter reloads on the next tick.
    // Take the baseline once it counts down from the reload value.
    while SYST::get_current() == 0 {}
    WRAPS.store(0, Ordering::SeqCst);
    syst.enable_interrupt();
    // SAFETY: single-threaded; the SysTick handler does not touch BASE.
    unsafe { BASE = SYST::get_current() };
}

/// SysTick ticks since [`start`].
pub fn elapsed_ticks() -> u64 {
    // SAFETY: see `start`.
    let base = unsafe { BASE } as u64;
    loop {
        let w1 = WRAPS.load(Ordering::SeqCst);
        let now = SYST::get_current() as u64;
        let w2 = WRAPS.load(Ordering::SeqCst);
        if w1 == w2 {
            return ((w1 as u64) << 24) + base - now;
        }
    }
}

/// Instructions executed since [`start`], to within
/// [`INSTRUCTIONS_PER_TICK`].
pub fn elapsed_instructions() -> u64 {
    elapsed_ticks() * INSTRUCTIONS_PER_TICK
}
