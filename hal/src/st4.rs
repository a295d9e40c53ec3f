//! The ST4 autoguider port: four active-low inputs, each edge timestamped.
//!
//! The inputs use the MCU's pull-ups (the camera's opto-couplers or
//! open-collector outputs pull a line to ground for the length of a guide
//! pulse) and interrupt on both edges through EXTI. The interrupt handler
//! (below, on `EXTI9_5` and `EXTI15_10`, the vectors of every board's ST4
//! lines) stamps the time with `embassy_time::Instant::now()` (1 µs ticks)
//! *in the interrupt*, so the timestamp does not depend on when a task gets
//! to run, and pushes a [`PinEdge`] into a queue that one task drains with
//! [`St4Edges::next`].
//!
//! The handler tracks levels rather than trusting edge flags: it clears the
//! pending flags first, then reads the four lines and queues an edge for each
//! line whose level differs from the last one it reported. An edge that
//! arrives while it runs pends the interrupt again, so the final level of
//! every line is always reported; a pulse shorter than the interrupt latency
//! (a few µs) can be missed entirely, which is harmless since it would be
//! discarded as a glitch anyway.
//!
//! Edge storms: before it queues an edge the handler asks the firmware's
//! `allow` function (the library's storm guard); when that refuses, the
//! handler masks the line's interrupt and reports the line released. The
//! guiding task polls a masked line ([`St4Edges::masked_level`]) and
//! unmasks it ([`St4Edges::unmask`]) when the guard says it is quiet, so a
//! storm cannot keep this interrupt busy.
//!
//! What the edges mean (debounce, pulses, both lines of an axis at once, the
//! cap, resynchronising after a loss, storms) is decided by the library
//! (`mkgp_mount::control_loop`), which the firmware feeds with these edges.
//! This crate does not depend on the library: the firmware package depends
//! on this one, and a dependency back would be a package cycle. So an edge
//! names its input by index, in the order of [`St4Pins`]
//! (RA+, RA-, Dec+, Dec-), the order of the library's `Line::ALL`.
//!
//! Interrupt priority: both EXTI vectors run at [`EXTI_PRIORITY`] (`P1`),
//! below the step timer (`P0`) and above the high-priority executor.
//! The handlers are this crate's, and no EXTI vector may be bound to
//! embassy's `exti::InterruptHandler` (no async `ExtiInput` anywhere): on
//! any vector it takes every pending line, masks it and clears its flag, so
//! an ST4 edge pending at that moment is lost and its line stays masked
//! (the worm index has its own handler for that reason:
//! [`crate::worm_index`]).

use core::cell::RefCell;
use core::sync::atomic::{AtomicU32, Ordering};

use embassy_stm32::exti::{ExtiInput, TriggerEdge};
use embassy_stm32::gpio::Pin;
use embassy_stm32::gpio::Pull;
use embassy_stm32::interrupt;
use embassy_stm32::interrupt::{InterruptExt, Priority};
use embassy_stm32::mode::Blocking;
use embassy_stm32::pac;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::channel::Channel;
use embassy_time::Instant;

use crate::board::St4Pins;

/// NVIC priority of the ST4 EXTI interrupts.
pub const EXTI_PRIORITY: Priority = Priority::P1;

/// Edges the queue holds before the consumer must run. An ST4 line changes a
/// few times per guide cycle; 32 covers a burst of contact bounce.
pub const QUEUE_LEN: usize = 32;

/// A level change of one input: `index` is its place in
/// [`St4Pins`] (0 RA+, 1 RA-, 2 Dec+, 3 Dec-),
/// `asserted` the new level (true = pulled low by the camera), `at_us` the
/// embassy-time instant of the interrupt in microseconds since boot.
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub struct PinEdge {
    pub index: u8,
    pub asserted: bool,
    pub at_us: u64,
}

/// Asked before an edge of input `index` at `at_us` is queued: `false`
/// masks the input (an edge storm).
pub type AllowEdge = fn(index: u8, at_us: u64) -> bool;

struct Inputs {
    lines: [ExtiInput<'static, Blocking>; 4],
    /// Each input's EXTI line (its pin number).
    exti: [u8; 4],
    /// The level last reported per line (true = asserted).
    asserted: [bool; 4],
    /// Inputs whose interrupt is masked (storming).
    masked: [bool; 4],
    allow: AllowEdge,
}

// Borrowed only inside critical sections and never across one, so a borrow
// cannot fail; `try_borrow*` all the same, so that no borrow panic is linked
// into the firmware.
static INPUTS: Mutex<CriticalSectionRawMutex, RefCell<Option<Inputs>>> =
    Mutex::new(RefCell::new(None));
static EDGES: Channel<CriticalSectionRawMutex, PinEdge, QUEUE_LEN> = Channel::new();
/// Edges lost because the queue was full.
static DROPPED: AtomicU32 = AtomicU32::new(0);
/// Bit i set: line i is asserted (as last seen by the interrupt).
static LEVELS: AtomicU32 = AtomicU32::new(0);

/// The consumer side of the edge queue; [`start`] returns the only one.
pub struct St4Edges {
    _private: (),
}

impl St4Edges {
    /// The next edge, in the order they occurred.
    pub async fn next(&mut self) -> PinEdge {
        EDGES.receive().await
    }

    /// The next edge if one is queued.
    ///
    /// Inlined into its one caller (the guiding task's edge source): an
    /// outlined copy, which the compiler chose once the loop grew, carries
    /// a second copy of the channel's internal panic path (test.sh counts
    /// panic call sites).
    #[inline(always)]
    pub fn try_next(&mut self) -> Option<PinEdge> {
        EDGES.try_receive().ok()
    }

    /// Edges lost to a full queue since start (an input storm). After a loss
    /// the consumer should resynchronise with [`levels`](Self::levels).
    pub fn dropped(&self) -> u32 {
        DROPPED.load(Ordering::Relaxed)
    }

    /// The level of each input as last seen by the interrupt handler, indexed
    /// like [`PinEdge::index`] (true = asserted).
    pub fn levels(&self) -> [bool; 4] {
        let bits = LEVELS.load(Ordering::Relaxed);
        [bits & 1 != 0, bits & 2 != 0, bits & 4 != 0, bits & 8 != 0]
    }

    /// The level of input `index` read now if its interrupt is masked
    /// (true = asserted); `None` while it is not masked.
    pub fn masked_level(&self, index: u8) -> Option<bool> {
        critical_section::with(|cs| {
            let inputs = INPUTS.borrow(cs).try_borrow().ok()?;
            let inputs = inputs.as_ref()?;
            let i = usize::from(index);
            let masked = *inputs.masked.get(i)?;
            masked.then(|| inputs.lines.get(i).is_some_and(|l| l.is_low()))
        })
    }

    /// Unmasks input `index` and reports its level now, as an edge if it
    /// differs from the level last reported.
    pub fn unmask(&mut self, index: u8) {
        critical_section::with(|cs| {
            let mut inputs = INPUTS.borrow(cs).try_borrow_mut();
            if let Some(inputs) = inputs.as_deref_mut().ok().and_then(Option::as_mut) {
                let i = usize::from(index);
                if let (Some(masked), Some(&line)) = (inputs.masked.get_mut(i), inputs.exti.get(i))
                {
                    *masked = false;
                    set_interrupt(line, true);
                }
            }
        });
        on_exti();
    }
}

/// Enables or masks the interrupt of EXTI line `line` (a pin number, below
/// 16: the mask changes nothing and spares the PAC's range assertion).
fn set_interrupt(line: u8, enabled: bool) {
    pac::EXTI
        .imr(0)
        .modify(|w| w.set_line(usize::from(line & 15), enabled));
}

/// Configures the four ST4 inputs (pull-up, EXTI on both edges), sets the
/// EXTI interrupt priority and starts reporting edges, each first offered to
/// `allow`. Lines already asserted at start are reported as edges at the
/// start time. Call once.
pub fn start(pins: St4Pins, allow: AllowEdge) -> St4Edges {
    interrupt::EXTI9_5.set_priority(EXTI_PRIORITY);
    interrupt::EXTI15_10.set_priority(EXTI_PRIORITY);
    // Built and stored with interrupts masked: an edge during set-up finds
    // the inputs in place (an interrupt that found none could not clear its
    // flag and would fire forever).
    critical_section::with(|cs| {
        let exti = [
            pins.ra_plus.pin(),
            pins.ra_minus.pin(),
            pins.dec_plus.pin(),
            pins.dec_minus.pin(),
        ];
        let lines = [
            ExtiInput::new_blocking(pins.ra_plus, pins.ra_plus_exti, Pull::Up, TriggerEdge::Any),
            ExtiInput::new_blocking(
                pins.ra_minus,
                pins.ra_minus_exti,
                Pull::Up,
                TriggerEdge::Any,
            ),
            ExtiInput::new_blocking(
                pins.dec_plus,
                pins.dec_plus_exti,
                Pull::Up,
                TriggerEdge::Any,
            ),
            ExtiInput::new_blocking(
                pins.dec_minus,
                pins.dec_minus_exti,
                Pull::Up,
                TriggerEdge::Any,
            ),
        ];
        if let Ok(mut inputs) = INPUTS.borrow(cs).try_borrow_mut() {
            *inputs = Some(Inputs {
                lines,
                exti,
                asserted: [false; 4],
                masked: [false; 4],
                allow,
            });
        }
    });
    // embassy-stm32's init enabled every EXTI vector in the NVIC already; the
    // first scan reports the lines asserted now.
    on_exti();
    St4Edges { _private: () }
}

/// The shared body of both EXTI handlers: clear, then compare levels; a
/// masked input counts as released.
fn on_exti() {
    let at_us = Instant::now().as_micros();
    critical_section::with(|cs| {
        let Ok(mut inputs) = INPUTS.borrow(cs).try_borrow_mut() else {
            return;
        };
        let Some(inputs) = inputs.as_mut() else {
            return;
        };
        for line in inputs.lines.iter_mut() {
            line.clear_pending();
        }
        let mut bits = 0;
        for i in 0..inputs.lines.len() {
            let index = i as u8;
            let mut asserted = !inputs.masked[i] && inputs.lines[i].is_low();
            if asserted != inputs.asserted[i] && !inputs.masked[i] && !(inputs.allow)(index, at_us)
            {
                inputs.masked[i] = true;
                set_interrupt(inputs.exti[i], false);
                asserted = false;
            }
            if asserted {
                bits |= 1 << i;
            }
            if asserted != inputs.asserted[i] {
                inputs.asserted[i] = asserted;
                let edge = PinEdge {
                    index,
                    asserted,
                    at_us,
                };
                if EDGES.try_send(edge).is_err() {
                    DROPPED.fetch_add(1, Ordering::Relaxed);
                }
            }
        }
        LEVELS.store(bits, Ordering::Relaxed);
    });
}

#[interrupt]
fn EXTI9_5() {
    on_exti();
}

#[interrupt]
fn EXTI15_10() {
    on_exti();
}
