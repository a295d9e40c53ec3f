//! One axis's stepping, as the step tick runs it: the step generator, the
//! STEP/DIR waveform and the count of the steps that went out.

use crate::mount::step_pulse::{PinChange, StepPulse};
use crate::mount::stepgen::PhaseAccumulator;

/// One axis: rate in, pin changes out, position kept.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AxisStepper {
    generator: PhaseAccumulator,
    pulse: StepPulse,
    /// Steps emitted, signed (forward positive).
    steps: i64,
    /// The axis's highest rate, steps/s (`Mount`'s maximum for it).
    max_steps_per_s: f32,
    tick_hz: u32,
}

impl AxisStepper {
    /// Stopped, at step 0.
    pub const fn new(max_steps_per_s: f32, tick_hz: u32) -> Self {
        AxisStepper {
            generator: PhaseAccumulator::new(),
            pulse: StepPulse::new(),
            steps: 0,
            max_steps_per_s,
            tick_hz,
        }
    }

    /// The same axis, its count starting at `steps` (the counts a park
    /// saved: the gear's phase carries over).
    pub const fn with_steps(mut self, steps: i64) -> Self {
        self.steps = steps;
        self
    }

    /// Sets the signed rate (steps/s), clamped to the axis's maximum and
    /// half the tick rate; NaN stops the axis. Returns the rate set.
    pub fn set_rate(&mut self, steps_per_s: f32) -> f32 {
        self.generator
            .set_rate(steps_per_s, self.max_steps_per_s, self.tick_hz)
    }

    /// One tick of the step timer: the pin change to make now.
    #[inline]
    pub fn tick(&mut self) -> PinChange {
        let due = self.generator.tick();
        let (change, step) = self.pulse.tick(due);
        self.steps += i64::from(step);
        change
    }

    /// `ticks` ticks at once, for the simulator: the steps the generator
    /// makes due are counted as emitted (the waveform's hold of a step by a
    /// tick or two around a reversal is not modelled; the count is exact
    /// between reversals).
    pub fn advance(&mut self, ticks: u64) {
        self.steps += self.generator.advance(ticks);
    }

    /// Steps emitted so far, signed.
    pub fn steps(&self) -> i64 {
        self.steps
    }

    pub fn tick_hz(&self) -> u32 {
        self.tick_hz
    }
}
