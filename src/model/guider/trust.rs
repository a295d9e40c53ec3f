//! Trust the multi-kernel guider earns by measurement (docs/model.md,
//! "Trust earned by measurement").
//!
//! The reference blend (INDIGO's) trusts the model as soon as it has two
//! worm periods of data and a settled period. With noise and a modest worm
//! that is too soon: the blended control (proportional gain plus the
//! prediction) then passes more noise than the hysteresis it replaces, and
//! gains less than that from the prediction.
//!
//! So the guider runs two shadow loops on the gear error it reconstructs
//! (the sum of its controls plus the measured error, i.e. the true gear
//! error plus this frame's noise): one with the hysteresis control alone,
//! one with the reference blend. Each shadow sees what the guider would have
//! measured under its own control, with the same noise; the mean square of
//! a shadow's measurements is its residual's plus the noise's, so the two
//! compare causally and paired, frame by frame. The weight the guider gives
//! the reference blend rises while the model's shadow is measured better by
//! a margin, falls while it is measured worse, and holds between.

use super::control_law::Law;

/// Frames a mean square averages over (about 7 minutes at 2 s frames; a
/// worm period or more of a modest worm, so that its slopes both ways count).
const SCORE_FRAMES: f64 = 1000.0;
/// Weight gained per frame while the model's shadow is better by
/// [`MARGIN`]: from none to full in 100 frames.
const RISE_PER_FRAME: f64 = 0.1;
/// Weight lost per frame while the model's shadow is worse: a model that
/// stops helping loses its weight faster than it earned it.
const FALL_PER_FRAME: f64 = 0.05;
/// Frames scored before the comparison may move the weight: fewer measure
/// the noise more than the model (PHD2 log 04 lost its gain over INDIGO
/// when the weight moved from the first scored frame).
const MIN_SCORED: f64 = 200.0;
/// The model's shadow must beat the reactive one by this fraction of its
/// mean square before the weight rises (the hysteresis of the decision).
const MARGIN: f64 = 0.001;

/// One virtual loop on the reconstructed gear error.
#[derive(Clone, Copy, Debug, Default)]
struct Shadow {
    /// The sum of its controls.
    applied: f64,
    /// Its last two controls, newest first (the hysteresis term reads the
    /// older, as the guider's).
    controls: [f64; 2],
    /// Running mean square of its measurements.
    mean_square: f64,
}

impl Shadow {
    /// One frame: its measurement of `gear`, and its control under `law`
    /// with the reference blend `blend` of `prediction` (none: hysteresis).
    fn step(&mut self, gear: f64, law: &Law<f64>, prediction: Option<(f64, f64)>) -> f64 {
        let input = gear - self.applied;
        // No prediction: the hysteresis term alone (a blend of 0).
        let prediction = prediction.or(Some((0.0, 0.0)));
        let mut control = law.control(input, self.controls[1], prediction);
        if !control.is_finite() {
            control = 0.0;
        }
        self.applied += control;
        self.controls = [control, self.controls[0]];
        input
    }

    /// Add a measurement to the mean square, the `frames`th scored.
    fn score(&mut self, input: f64, frames: f64) {
        self.mean_square += (input * input - self.mean_square) / frames.min(SCORE_FRAMES);
    }
}

/// The measured trust in the reference blend, 0..=1, and the two shadows
/// that measure it.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Trust {
    reactive: Shadow,
    model: Shadow,
    /// Frames scored: those where the model's shadow differed from the
    /// reactive one (until then both score the same, which would only
    /// dilute the comparison).
    scored: f64,
    weight: f64,
}

impl Trust {
    /// Full weight until the model's shadow is measured worse: the
    /// reference blend's own ramp governs the start, and the short PHD2
    /// logs lose their gain to any slower start (docs/model.md).
    pub fn new() -> Self {
        Self {
            weight: 1.0,
            ..Self::default()
        }
    }

    /// A frame with a measurement: `gear` is the reconstructed gear error
    /// (the guider's controls so far plus its measurement), `prediction`
    /// the model's prediction and the reference blend, if the model was
    /// consulted. Returns the weight for this frame's control.
    pub fn measured(&mut self, gear: f64, law: &Law<f64>, prediction: Option<(f64, f64)>) -> f64 {
        let reactive = self.reactive.step(gear, law, None);
        let model = self.model.step(gear, law, prediction);
        if !(gear.is_finite() && reactive.is_finite() && model.is_finite()) {
            *self = Self {
                weight: 0.0,
                ..Self::default()
            };
            return 0.0;
        }
        if prediction.is_none_or(|(_, blend)| !(blend > 0.0)) {
            return self.weight;
        }
        self.scored += 1.0;
        self.reactive.score(reactive, self.scored);
        self.model.score(model, self.scored);
        let (r, m) = (self.reactive.mean_square, self.model.mean_square);
        if self.scored < MIN_SCORED {
            return self.weight;
        }
        if m < (1.0 - MARGIN) * r {
            self.weight += RISE_PER_FRAME;
        } else if m > r {
            self.weight -= FALL_PER_FRAME;
        }
        self.weight = self.weight.clamp(0.0, 1.0);
        self.weight
    }

    /// A frame without a measurement, or after a dither: the shadows cannot
    /// run, and start again from the guider's own loop (`applied`, its
    /// controls' sum after this frame, and its last two controls).
    pub fn follow(&mut self, applied: f64, controls: [f64; 2]) {
        for s in [&mut self.reactive, &mut self.model] {
            s.applied = applied;
            s.controls = controls;
        }
    }
}
