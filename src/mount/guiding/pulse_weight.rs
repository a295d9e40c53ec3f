//! How much of a guide pulse the model takes for gear error, earned by
//! measurement (docs/decisions.md, "A guider that overcorrects").
//!
//! A measured frame's observation is the correction applied plus the pulse
//! divided by the guider's assumed aggressiveness (`super`, "Frames"). A
//! guider whose real gain (its aggressiveness over the error of its
//! calibration) is well above the assumed one makes that observation
//! overshoot: it carries part of the loop's own residual, the model learns
//! it and feeds it forward, and the loop swings ever wider at four to five
//! frames a period. At 8 s exposures that swing is slow enough for the
//! model to follow it as a gear stage (docs/results.md, "Where the guider
//! alone is unstable").
//!
//! Such a swing makes pulses two frames apart anti-correlated. A loop's
//! reaction to noise never does so by much: for a loop of gain G on white
//! noise that correlation is `(1 - G)` times the neighbours' one, `-G/2`,
//! so never below -1/8 on average (the earned share's 64-frame running means
//! spread it: -0.34 at the least over 3,000 frames of noise). So while the
//! pulses two frames apart are correlated below [`SWING`], the model takes
//! a smaller part of each pulse, down to [`LEAST`]. The weight does not
//! come back (a swing is the only evidence, and it stops once the weight
//! is low enough); it is saved with the model, and starts at 1 again with
//! a model reset. A real gear error of four to five frames a period left
//! to the pulses reads the same; at such periods the model has nothing to
//! learn of it anyway (its shortest stage is 20 s).
//!
//! The same evidence widens the pulses the firmware shares: a pulse beyond
//! the earned share's bound is otherwise carried out in full, and from a guider
//! that overcorrects that is its own swing starting, doubled (at 2 s
//! exposures, a single noisy measurement set off a swing that lasted the
//! rest of the night). The bound grows as the weight falls: a guider that
//! asks `1 / weight` times the correction it needs asks that much more
//! beyond its noise too.

use crate::model::numeric::clamp;
use crate::mount::frame::PulseShare;

/// Correlation of pulses two frames apart below which the loop swings.
pub const SWING: f32 = -0.5;
/// Relative fall of the weight per frame of swing: from 1 to [`LEAST`] in
/// about 120 frames.
const FALL: f32 = 0.01;
/// The least weight: a guider of gain 2 behind the assumed 0.7 needs 0.35.
pub const LEAST: f32 = 0.3;

/// The part of a guide pulse the model learns as gear error.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PulseWeight {
    weight: f32,
}

impl PulseWeight {
    pub const FULL: PulseWeight = PulseWeight { weight: 1.0 };

    /// A weight saved with the model, clamped to [`LEAST`]..=1 (NaN: 1).
    pub fn restored(weight: f32) -> Self {
        PulseWeight {
            weight: if weight.is_nan() {
                1.0
            } else {
                clamp(weight, LEAST, 1.0)
            },
        }
    }

    /// After a guide frame: `swing` is the measured correlation of pulses
    /// two frames apart (0 while not measured).
    pub fn frame(&mut self, swing: f32) {
        if swing < SWING {
            self.weight = (self.weight * (1.0 - FALL)).max(LEAST);
        }
    }

    /// The observation with this weight of the pulse's part: `applied`
    /// plus the weighted rest of `observed`.
    pub fn observation(&self, applied: f64, observed: f64) -> f64 {
        applied + self.weight as f64 * (observed - applied)
    }

    /// `share` with its bound widened by `1 / weight`.
    pub fn share(&self, share: PulseShare) -> PulseShare {
        PulseShare {
            up_to_arcsec: share.up_to_arcsec / self.weight,
            ..share
        }
    }

    pub fn weight(&self) -> f32 {
        self.weight
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_swing_lowers_the_weight_to_the_least_and_nothing_else_does() {
        let mut w = PulseWeight::FULL;
        for swing in [0.0, 1.0, -0.49, f32::NAN] {
            w.frame(swing);
        }
        assert_eq!(w, PulseWeight::FULL);
        assert_eq!(w.observation(2.0, 5.0), 5.0);
        w.frame(-0.6);
        assert_eq!(w.weight(), 0.99);
        for _ in 0..120 {
            w.frame(-0.9);
        }
        assert_eq!(w.weight(), LEAST);
        assert!((w.observation(2.0, 5.0) - 2.9).abs() < 1e-6);
        let share = PulseShare {
            fraction: 0.5,
            up_to_arcsec: 3.0,
        };
        assert_eq!(w.share(share).up_to_arcsec, 10.0);
        assert_eq!(PulseWeight::FULL.share(share), share);
        assert_eq!(PulseWeight::restored(0.5).weight(), 0.5);
        assert_eq!(PulseWeight::restored(0.0).weight(), LEAST);
        assert_eq!(PulseWeight::restored(f32::NAN), PulseWeight::FULL);
    }
}
