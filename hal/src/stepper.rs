//! Stepper drivers: STEP/DIR/ENABLE outputs and the step tick timer.
//!
//! Steps are produced in software from a periodic timer interrupt (the
//! *tick*, [`StepTicker`], on TIM2 at `step_tick_hz`, 50 kHz by default):
//! on each tick the firmware advances each axis' phase accumulator
//! (`mkgp_mount::mount::stepgen::PhaseAccumulator`, integer only) and hands the
//! result to that axis' [`StepAxis::tick`], which drives the pins. Timing of
//! the outputs, in ticks (20 µs at 50 kHz):
//!
//! - STEP is high for exactly one tick and low for at least one tick, so the
//!   highest step rate is half the tick rate (25 kHz), the limit
//!   `MountConfig::validate` enforces. A4988 needs 1 µs high / 1 µs low,
//!   DRV8825 1.9 µs / 1.9 µs, TMC2209 100 ns: 20 µs is ample.
//! - DIR changes one tick before the STEP rising edge that needs it (set-up
//!   time 20 µs; drivers need 20-650 ns) and never while STEP is high (hold).
//! - A step that cannot go out on the tick it is due (STEP still high, or DIR
//!   about to change) is owed and goes out on the next free tick; a step due
//!   in the opposite direction cancels an owed one. The emitted count is what
//!   [`StepAxis::tick`] returns, so the position the firmware keeps is the
//!   motor's, step for step.
//!
//! ENABLE is active low on A4988, DRV8825 and TMC2209 boards (all three
//! boards' tables in [`crate::board`] wire it so): the outputs start with the
//! drivers disabled (ENABLE high) and [`StepAxis::set_enabled`] turns them on
//! once the configuration has been validated.
//!
//! Timer choice: TIM2 (32-bit general-purpose, own interrupt vector) exists on
//! all three chips. embassy's time driver is pinned to TIM5 with the
//! `time-driver-tim5` feature (`time-driver-any` would pick TIM9 on these
//! chips today, whose vector is shared with TIM1's break interrupt); TIM1,
//! TIM3, TIM4 and TIM8, whose channel-1 pins are the STEP outputs, stay free
//! for hardware step generation later.
//!
//! The interrupt handler itself lives in the firmware (`main.rs`, `fn TIM2`):
//! it owns the phase accumulators of the library, which this crate does not
//! depend on (see [`crate::st4`] for why).

use embassy_stm32::gpio::{Level, Output, Pin, Speed};
use embassy_stm32::interrupt;
use embassy_stm32::interrupt::{InterruptExt, Priority};
use embassy_stm32::peripherals::TIM2;
use embassy_stm32::timer::low_level::{RoundTo, Timer};
use embassy_stm32::Peri;

use crate::board::AxisPins;

/// NVIC priority of the step tick: the highest, alone at this level.
pub const TICK_PRIORITY: Priority = Priority::P0;

/// The timer peripheral of the step tick; its interrupt vector is `TIM2`.
pub type StepTimer = TIM2;

/// One stepper driver's outputs and its pulse state.
pub struct StepAxis {
    step: Output<'static>,
    dir: Output<'static>,
    enable: Output<'static>,
    /// DIR level meaning "forward" (positive steps).
    forward_level: Level,
    step_high: bool,
    dir_forward: bool,
    /// Steps due but not yet emitted (signed: positive = forward).
    owed: i32,
}

impl StepAxis {
    /// Takes the axis' pins: STEP low, DIR forward, ENABLE high (driver
    /// disabled). `dir_forward_high`: DIR is high for forward steps (swap
    /// it, or one coil's wires, if the axis turns the wrong way).
    pub fn new<S: Pin, D: Pin, E: Pin>(pins: AxisPins<S, D, E>, dir_forward_high: bool) -> Self {
        let forward_level = if dir_forward_high {
            Level::High
        } else {
            Level::Low
        };
        Self {
            step: Output::new(pins.step, Level::Low, Speed::VeryHigh),
            dir: Output::new(pins.dir, forward_level, Speed::Low),
            enable: Output::new(pins.enable, Level::High, Speed::Low),
            forward_level,
            step_high: false,
            dir_forward: true,
            owed: 0,
        }
    }

    /// Drives ENABLE (active low): `true` powers the motor.
    pub fn set_enabled(&mut self, on: bool) {
        self.enable
            .set_level(if on { Level::Low } else { Level::High });
    }

    /// One tick: `due` is the accumulator's output (`Some(forward)` when a
    /// step is due). Returns the step emitted on this tick: +1, -1 or 0.
    #[inline]
    pub fn tick(&mut self, due: Option<bool>) -> i32 {
        match due {
            Some(true) => self.owed += 1,
            Some(false) => self.owed -= 1,
            None => {}
        }
        if self.step_high {
            self.step.set_low();
            self.step_high = false;
            return 0;
        }
        if self.owed == 0 {
            return 0;
        }
        let forward = self.owed > 0;
        if forward != self.dir_forward {
            self.dir_forward = forward;
            let high = forward == (self.forward_level == Level::High);
            self.dir.set_level(Level::from(high));
            return 0;
        }
        self.step.set_high();
        self.step_high = true;
        if forward {
            self.owed -= 1;
            1
        } else {
            self.owed += 1;
            -1
        }
    }

    /// Steps due but not yet emitted (at most a few at any time).
    pub fn owed(&self) -> i32 {
        self.owed
    }
}

/// The step tick could not be set up.
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub enum TickError {
    /// The timer clock is not a whole multiple of the requested tick rate, so
    /// the tick would not be exact and tracking would drift. Pick a rate that
    /// divides `timer_clock_hz` (50 kHz divides all three boards' 96, 90 and
    /// 84 MHz).
    Inexact { tick_hz: u32, timer_clock_hz: u32 },
    /// Zero, or faster than one tick per 200 timer clocks (the interrupt
    /// would eat the CPU).
    OutOfRange { tick_hz: u32, timer_clock_hz: u32 },
}

/// The periodic step tick on [`StepTimer`] (TIM2), update interrupt at
/// [`TICK_PRIORITY`].
pub struct StepTicker {
    timer: Timer<'static, StepTimer>,
    tick_hz: u32,
}

impl StepTicker {
    /// Sets the timer up for exactly `tick_hz` update interrupts per second
    /// (not started).
    pub fn new(tim: Peri<'static, StepTimer>, tick_hz: u32) -> Result<Self, TickError> {
        let timer_clock_hz = embassy_stm32::rcc::frequency::<StepTimer>().0;
        if tick_hz == 0 || tick_hz > timer_clock_hz / 200 {
            return Err(TickError::OutOfRange {
                tick_hz,
                timer_clock_hz,
            });
        }
        if timer_clock_hz % tick_hz != 0 {
            return Err(TickError::Inexact {
                tick_hz,
                timer_clock_hz,
            });
        }
        let timer = Timer::new(tim);
        timer.stop();
        // 32-bit counter: prescaler 1, ARR = clocks - 1; exact.
        timer.set_period_clocks(u64::from(timer_clock_hz / tick_hz), RoundTo::Faster);
        timer.generate_update_event();
        timer.clear_update_interrupt();
        Ok(Self { timer, tick_hz })
    }

    /// The tick rate, exactly.
    pub fn tick_hz(&self) -> u32 {
        self.tick_hz
    }

    /// Starts ticking: sets the NVIC priority, enables the update interrupt
    /// and the counter. The firmware's `TIM2` handler must call
    /// [`ack`](Self::ack) first thing.
    pub fn start(&self) {
        interrupt::TIM2.set_priority(TICK_PRIORITY);
        self.timer.enable_update_interrupt(true);
        interrupt::TIM2.unpend();
        // SAFETY: the firmware defines the TIM2 handler, and everything it
        // touches is initialised before start() is called.
        unsafe { interrupt::TIM2.enable() };
        self.timer.start();
    }

    /// Stops ticking (the outputs keep their levels).
    pub fn stop(&self) {
        self.timer.stop();
        interrupt::TIM2.disable();
    }

    /// Clears the update flag; call at the start of the handler (clearing at
    /// the end can re-enter the handler through the write buffer's delay).
    #[inline]
    pub fn ack(&self) {
        self.timer.clear_update_interrupt();
    }
}
