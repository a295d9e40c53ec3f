//! The step tick: the `TIM2` interrupt at the highest priority runs each
//! axis's `AxisStepper` and makes the pin change it asks for. The guiding
//! task sets the rates and reads the step counts in short critical
//! sections.

use core::cell::RefCell;
use core::sync::atomic::{AtomicU32, Ordering};

use embassy_stm32::interrupt;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex;

use hal::stepper::{StepAxis, StepTicker};
use mkgp_mount::control_loop::stepping::AxisStepper;
use mkgp_mount::mount::config::Mount;
use mkgp_mount::mount::frame::Rates;
use mkgp_mount::mount::step_pulse::PinChange;

/// One axis: the library's stepper and the pins it drives.
struct Axle {
    stepper: AxisStepper,
    pins: StepAxis,
}

impl Axle {
    #[inline]
    fn tick(&mut self) {
        match self.stepper.tick() {
            PinChange::None => {}
            PinChange::StepLow => self.pins.set_step(false),
            PinChange::StepHigh => self.pins.set_step(true),
            PinChange::Dir { forward } => self.pins.set_dir(forward),
        }
    }
}

/// Everything the step tick touches. Owned by the `TIM2` handler; the
/// guiding task changes the rates and reads the counts in critical
/// sections. Borrowed only inside critical sections and never across one,
/// so a borrow cannot fail: `try_borrow*` keeps the borrow panics (and their
/// messages) out of the step tick.
struct Stepping {
    ticker: StepTicker,
    ra: Axle,
    dec: Axle,
}

static STEPPING: Mutex<CriticalSectionRawMutex, RefCell<Option<Stepping>>> =
    Mutex::new(RefCell::new(None));

/// Step ticks so far (wrapping), for the liveness check.
static TICKS: AtomicU32 = AtomicU32::new(0);

/// The step tick (hal::stepper::StepTimer = TIM2): integer work only.
#[interrupt]
fn TIM2() {
    TICKS.fetch_add(1, Ordering::Relaxed);
    critical_section::with(|cs| {
        let Ok(mut stepping) = STEPPING.borrow(cs).try_borrow_mut() else {
            return;
        };
        if let Some(s) = stepping.as_mut() {
            s.ticker.ack();
            s.ra.tick();
            s.dec.tick();
        }
    });
}

/// The rates last set (f32 bits), for the status log.
static RA_RATE_BITS: AtomicU32 = AtomicU32::new(0);
static DEC_RATE_BITS: AtomicU32 = AtomicU32::new(0);

/// Sets both axes' rates; returns the rates actually set. One critical
/// section per axis: `set_rate` does a software `f64` division, so each
/// holds the step tick off for a few µs, well inside a tick.
pub fn set_rates(rates: Rates) -> Rates {
    let set = |rate: f32, axle: fn(&mut Stepping) -> &mut Axle| {
        critical_section::with(|cs| {
            STEPPING.borrow(cs).try_borrow_mut().map_or(0.0, |mut s| {
                s.as_mut().map_or(0.0, |s| axle(s).stepper.set_rate(rate))
            })
        })
    };
    let set = Rates {
        ra_steps_per_s: set(rates.ra_steps_per_s, |s| &mut s.ra),
        dec_steps_per_s: set(rates.dec_steps_per_s, |s| &mut s.dec),
    };
    RA_RATE_BITS.store(set.ra_steps_per_s.to_bits(), Ordering::Relaxed);
    DEC_RATE_BITS.store(set.dec_steps_per_s.to_bits(), Ordering::Relaxed);
    set
}

/// Step ticks so far (wrapping).
pub fn ticks() -> u32 {
    TICKS.load(Ordering::Relaxed)
}

/// Steps emitted so far on (RA, Dec).
pub fn step_counts() -> (i64, i64) {
    critical_section::with(|cs| {
        STEPPING.borrow(cs).try_borrow().map_or((0, 0), |s| {
            s.as_ref()
                .map_or((0, 0), |s| (s.ra.stepper.steps(), s.dec.stepper.steps()))
        })
    })
}

/// Takes the timer and both axes' pins, starts the tick and enables the
/// drivers: from here on the motors follow the rates set.
/// Starts the step tick with the axes' counts at `counts` (RA, Dec).
pub fn start(ticker: StepTicker, ra: StepAxis, dec: StepAxis, mount: &Mount, counts: (i64, i64)) {
    let tick_hz = mount.config().step_tick_hz;
    STEPPING.lock(|s| {
        let Ok(mut s) = s.try_borrow_mut() else {
            return;
        };
        *s = Some(Stepping {
            ticker,
            ra: Axle {
                stepper: AxisStepper::new(mount.max_ra_steps_per_s(), tick_hz).with_steps(counts.0),
                pins: ra,
            },
            dec: Axle {
                stepper: AxisStepper::new(mount.max_dec_steps_per_s(), tick_hz)
                    .with_steps(counts.1),
                pins: dec,
            },
        });
    });
    critical_section::with(|cs| {
        let Ok(mut stepping) = STEPPING.borrow(cs).try_borrow_mut() else {
            return;
        };
        if let Some(s) = stepping.as_mut() {
            s.ticker.start();
            s.ra.pins.set_enabled(true);
            s.dec.pins.set_enabled(true);
        }
    });
}

/// The rates last set, steps/s (RA, Dec).
pub fn rates_set() -> (f32, f32) {
    (
        f32::from_bits(RA_RATE_BITS.load(Ordering::Relaxed)),
        f32::from_bits(DEC_RATE_BITS.load(Ordering::Relaxed)),
    )
}
