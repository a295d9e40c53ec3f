//! Stepper drivers: STEP/DIR/ENABLE outputs and the step tick timer.
//!
//! Steps are produced in software from a periodic timer interrupt (the
//! *tick*, [`StepTicker`], on TIM2 at `step_tick_hz`, 50 kHz by default). On
//! each tick the firmware asks the library's `AxisStepper` (step generation
//! and the STEP/DIR waveform: STEP high one tick, DIR a tick ahead, owed
//! steps) what to change, and makes the change with [`StepAxis::set_step`]
//! or [`StepAxis::set_dir`]. This crate decides nothing about steps.
//!
//! ENABLE is active low on A4988, DRV8825 and TMC2209 boards (all three
//! boards' tables in [`crate::board`] wire it so): the outputs start with the
//! drivers disabled (ENABLE high) and [`StepAxis::set_enabled`] turns them on
//! once the configuration has been validated.
//!
//! Timer choice: TIM2 (32-bit general-purpose, own interrupt vector) exists on
//! all four chips; on the L475 board SysTick pends its vector instead
//! (`systick_time`), and its counter stays off. On the F4 boards embassy's
//! time driver is pinned to TIM5 with the `time-driver-tim5` feature
//! (`time-driver-any` would pick TIM9 on these chips today, whose vector is
//! shared with TIM1's break interrupt); TIM1, TIM3, TIM4 and TIM8, whose
//! channel-1 pins are the STEP outputs, stay free for hardware step
//! generation later.
//!
//! The interrupt handler itself lives in the firmware
//! (`src/firmware/step_tick.rs`, `fn TIM2`):
//! it owns the library's steppers, which this crate does not depend on (see
//! [`crate::st4`] for why).

use embassy_stm32::gpio::{Level, Output, Pin, Speed};
use embassy_stm32::interrupt;
use embassy_stm32::interrupt::{InterruptExt, Priority};
use embassy_stm32::peripherals::TIM2;
#[cfg(not(feature = "stm32l475vg"))]
use embassy_stm32::timer::low_level::{RoundTo, Timer};
use embassy_stm32::Peri;

use crate::board::AxisPins;

/// NVIC priority of the step tick: the highest, alone at this level.
pub const TICK_PRIORITY: Priority = Priority::P0;

/// The timer peripheral of the step tick; its interrupt vector is `TIM2`.
pub type StepTimer = TIM2;

/// One stepper driver's outputs.
pub struct StepAxis {
    step: Output<'static>,
    dir: Output<'static>,
    enable: Output<'static>,
    /// DIR level meaning "forward" (positive steps).
    forward_level: Level,
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
        }
    }

    /// Drives ENABLE (active low): `true` powers the motor.
    pub fn set_enabled(&mut self, on: bool) {
        self.enable
            .set_level(if on { Level::Low } else { Level::High });
    }

    /// Drives STEP.
    #[inline]
    pub fn set_step(&mut self, high: bool) {
        self.step.set_level(Level::from(high));
    }

    /// Drives DIR for forward (true) or backward steps.
    #[inline]
    pub fn set_dir(&mut self, forward: bool) {
        let high = forward == (self.forward_level == Level::High);
        self.dir.set_level(Level::from(high));
    }
}

/// Disables both drivers from anywhere, at any time: the fault path's first
/// act (panic, HardFault, a stalled part), when the [`StepAxis`] owners may
/// be in any state.
///
/// # Safety
/// Takes the ENABLE pins behind their owners' backs: call only on the way to
/// a reset, with interrupts disabled, never returning to code that uses the
/// [`StepAxis`]es.
pub unsafe fn force_drivers_off() {
    use crate::board::pins::{DecEnable, RaEnable};
    // SAFETY: as the caller promises, nothing uses these pins again.
    let (ra, dec) = unsafe { (RaEnable::steal(), DecEnable::steal()) };
    // ENABLE high = driver off. Forgotten, not dropped: dropping an Output
    // disconnects the pin, which would let the driver's own pull-down
    // enable it again.
    core::mem::forget(Output::new(ra, Level::High, Speed::Low));
    core::mem::forget(Output::new(dec, Level::High, Speed::Low));
}

/// The step tick could not be set up.
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub enum TickError {
    /// The timer clock is not a whole multiple of the requested tick rate, so
    /// the tick would not be exact and tracking would drift. Pick a rate that
    /// divides `timer_clock_hz` (50 kHz divides the F4 boards' 96, 90 and
    /// 84 MHz). On the L475 board the tick is SysTick's fixed rate, given as
    /// `timer_clock_hz`: the tick rate must be that.
    Inexact { tick_hz: u32, timer_clock_hz: u32 },
    /// Zero, or faster than one tick per 200 timer clocks (the interrupt
    /// would eat the CPU).
    OutOfRange { tick_hz: u32, timer_clock_hz: u32 },
}

/// The periodic step tick on [`StepTimer`] (TIM2), update interrupt at
/// [`TICK_PRIORITY`].
#[cfg(not(feature = "stm32l475vg"))]
pub struct StepTicker {
    timer: Timer<'static, StepTimer>,
    tick_hz: u32,
}

#[cfg(not(feature = "stm32l475vg"))]
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
        if !timer_clock_hz.is_multiple_of(tick_hz) {
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

/// The periodic step tick on the `TIM2` vector, pended by SysTick
/// (`systick_time`) at its fixed rate, at [`TICK_PRIORITY`]; TIM2's
/// counter stays off.
#[cfg(feature = "stm32l475vg")]
pub struct StepTicker {
    _tim: Peri<'static, StepTimer>,
}

#[cfg(feature = "stm32l475vg")]
impl StepTicker {
    /// Takes the vector's timer; `tick_hz` must be SysTick's rate.
    pub fn new(tim: Peri<'static, StepTimer>, tick_hz: u32) -> Result<Self, TickError> {
        use crate::systick_time::TICK_HZ;
        if tick_hz != TICK_HZ {
            return Err(TickError::Inexact {
                tick_hz,
                timer_clock_hz: TICK_HZ,
            });
        }
        Ok(Self { _tim: tim })
    }

    /// The tick rate, exactly.
    pub fn tick_hz(&self) -> u32 {
        crate::systick_time::TICK_HZ
    }

    /// Starts ticking: sets the NVIC priority, enables the vector and lets
    /// SysTick pend it.
    pub fn start(&self) {
        interrupt::TIM2.set_priority(TICK_PRIORITY);
        interrupt::TIM2.unpend();
        // SAFETY: the firmware defines the TIM2 handler, and everything it
        // touches is initialised before start() is called.
        unsafe { interrupt::TIM2.enable() };
        crate::systick_time::set_step_tick(true);
    }

    /// Stops ticking (the outputs keep their levels).
    pub fn stop(&self) {
        crate::systick_time::set_step_tick(false);
        interrupt::TIM2.disable();
    }

    /// Nothing to acknowledge: the vector is pended, not raised by a flag.
    #[inline]
    pub fn ack(&self) {}
}
