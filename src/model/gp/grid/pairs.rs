//! Pairs of long frames, for the mount's grid (`grid::Averaging::Paired`).
//!
//! A loop that overcorrects swings from frame to frame. At frames more
//! than half a cell and at most a cell apart the swing's period (two
//! frames) lies between one and two cells, where a cell's mean neither
//! cancels nor resolves it: the cells pass it on at an alias, as if it
//! were gear error. The mean of two consecutive frames, at the middle of
//! their times, cancels it and is still centred. It also smooths the gear
//! error and stands half a frame further back, which costs where the
//! frames are smooth (a quiet sky), so frames are paired only while the
//! steps between consecutive frames are anti-correlated: while a swing or
//! the seeing, not the gear's motion, moves them from frame to frame.

use super::{CELL_S, UNMEASURED_VARIANCE};

/// Frames over which the steps' correlation is averaged: a few minutes of
/// long frames, short beside a worm period.
const SWING_FRAMES: f64 = 64.0;

/// A sample: time (s), accumulated gear error, measurement variance.
pub type Sample = (f64, f64, f64);

/// The frames' pairing state. 56 bytes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pairs {
    /// The newest measured sample as it came.
    last: Option<Sample>,
    /// The step from the measured sample before it to it.
    last_step: Option<f64>,
    /// Running mean of a step times the step before it.
    step_product: f64,
}

impl Pairs {
    pub const NEW: Self = Self {
        last: None,
        last_step: None,
        step_product: 0.0,
    };

    /// What the grid takes for `sample`: the mean of it and the measured
    /// sample before it, at the middle of their times, where the two are
    /// more than half a cell and at most a cell apart and the steps are
    /// anti-correlated; else the sample as it came.
    pub fn pair(&mut self, sample: Sample) -> Sample {
        let (time, gear, variance) = sample;
        if !(time.is_finite() && gear.is_finite() && variance.is_finite())
            || variance >= UNMEASURED_VARIANCE
        {
            *self = Self {
                step_product: self.step_product,
                ..Self::NEW
            };
            return sample;
        }
        let Some((t0, g0, v0)) = self.last else {
            self.last = Some(sample);
            return sample;
        };
        let apart = time - t0;
        if apart < 0.0 {
            return sample;
        }
        self.last = Some(sample);
        if !(apart > 0.5 * CELL_S && apart <= CELL_S) {
            self.last_step = None;
            return sample;
        }
        let step = gear - g0;
        if let Some(before) = self.last_step {
            self.step_product += (step * before - self.step_product) / SWING_FRAMES;
        }
        self.last_step = Some(step);
        if self.step_product < 0.0 {
            (0.5 * (t0 + time), 0.5 * (g0 + gear), 0.5 * (v0 + variance))
        } else {
            sample
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Feeds measured samples `gear(k)` every 4 s; returns what was taken.
    fn taken(pairs: &mut Pairs, gear: impl Fn(usize) -> f64, frames: usize) -> Vec<Sample> {
        (0..frames)
            .map(|k| pairs.pair((4.0 * k as f64, gear(k), 1.0)))
            .collect()
    }

    #[test]
    fn a_swing_is_paired_and_the_gears_motion_is_not() {
        let swing = |k: usize| 0.05 * k as f64 + if k.is_multiple_of(2) { 1.0 } else { -1.0 };
        let mut pairs = Pairs::NEW;
        let out = taken(&mut pairs, swing, 10);
        // The first two frames, and the third (one step product, not yet
        // below zero when it came), as they came; then pairs.
        for (k, &s) in out.iter().enumerate().take(2) {
            assert_eq!(s, (4.0 * k as f64, swing(k), 1.0));
        }
        for (k, &(t, g, v)) in out.iter().enumerate().skip(3) {
            assert_eq!((t, v), (4.0 * k as f64 - 2.0, 1.0));
            assert!((g - 0.05 * (k as f64 - 0.5)).abs() < 1e-12, "{k}: {g}");
        }
        // A gear that moves smoothly is taken as it comes, also after the
        // swing, once the steps' product has turned.
        let ramp = |k: usize| 0.3 * k as f64;
        let mut pairs = Pairs::NEW;
        for (k, &s) in taken(&mut pairs, ramp, 10).iter().enumerate() {
            assert_eq!(s, (4.0 * k as f64, ramp(k), 1.0));
        }
        let mut pairs = Pairs::NEW;
        taken(&mut pairs, swing, 10);
        let out: Vec<Sample> = (100..300)
            .map(|k| pairs.pair((4.0 * k as f64, ramp(k), 1.0)))
            .collect();
        assert_eq!(out[199], (4.0 * 299.0, ramp(299), 1.0));
    }

    #[test]
    fn frames_too_close_or_too_far_or_unmeasured_are_taken_as_they_come() {
        let swing = |t: f64, k: usize| (t, if k.is_multiple_of(2) { 1.0 } else { -1.0 }, 1.0);
        for spacing in [2.5, 5.5] {
            let mut pairs = Pairs::NEW;
            for k in 0..20 {
                let s = swing(spacing * k as f64, k);
                assert_eq!(pairs.pair(s), s, "{spacing}");
            }
        }
        let mut pairs = Pairs::NEW;
        for k in 0..20 {
            pairs.pair(swing(4.0 * k as f64, k));
        }
        // Paired now; a frame without a star breaks the pairs, and the
        // next measured one comes as it is.
        assert_ne!(pairs.pair(swing(80.0, 20)), swing(80.0, 20));
        let dark = (84.0, 0.0, UNMEASURED_VARIANCE);
        assert_eq!(pairs.pair(dark), dark);
        assert_eq!(pairs.pair(swing(88.0, 22)), swing(88.0, 22));
        assert_ne!(pairs.pair(swing(92.0, 23)), swing(92.0, 23));
        // A time that runs back, or a value not finite, is no pair.
        assert_eq!(pairs.pair(swing(50.0, 1)), swing(50.0, 1));
        let nan = (96.0, f64::NAN, 1.0);
        assert_eq!(pairs.pair(nan).0, 96.0);
        assert_eq!(pairs.pair(swing(100.0, 25)), swing(100.0, 25));
    }
}
