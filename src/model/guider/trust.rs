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
//!
//! The reactive term itself is chosen the same way. The reference's
//! hysteresis term (a tenth of the control two frames back) lowers the
//! effective gain and adds momentum; on some guide logs proportional
//! control is better (PHD2's own GP test uses it, docs/model.md). Two more
//! shadows run the guider's law, under the reference blend, with the
//! hysteresis term and with proportional control in its place, from the
//! first frame; the guider uses proportional control while that shadow is
//! measured better by a margin, and goes back when it is measured worse.

use super::control_law::Law;
use super::HYSTERESIS;
use crate::model::additions::Additions;

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
/// Frames scored before the reactive law may change: the two laws differ by
/// a fraction of the noise, so their comparison needs more frames than the
/// model's (with 200, PHD2 log 03 switched on too few and lost 0.2 %).
const LAW_MIN_SCORED: f64 = 400.0;
/// The proportional shadow must beat the hysteretic one by this fraction of
/// its mean square before the guider switches to it.
const LAW_MARGIN: f64 = 0.01;

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
    /// The guider's law under the reference blend, with the hysteresis term
    /// and with proportional control in its place.
    hysteretic: Shadow,
    proportional: Shadow,
    /// Frames the two have scored (every frame with a measurement).
    law_scored: f64,
    use_proportional: bool,
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
    /// consulted. Returns the weight for this frame's control: 1 without
    /// the addition `trust_shadows` (the shadows still run, for the law).
    pub fn measured(
        &mut self,
        gear: f64,
        law: &Law<f64>,
        prediction: Option<(f64, f64)>,
        adds: &Additions,
    ) -> f64 {
        let weight = self.score(gear, law, prediction);
        if adds.trust_shadows {
            weight
        } else {
            1.0
        }
    }

    /// Run the shadows one frame and move the weight; returns it.
    fn score(&mut self, gear: f64, law: &Law<f64>, prediction: Option<(f64, f64)>) -> f64 {
        let reactive = self.reactive.step(gear, law, None);
        let model = self.model.step(gear, law, prediction);
        let hysteretic = Law {
            hysteresis: HYSTERESIS,
            ..*law
        };
        let proportional = Law {
            hysteresis: 0.0,
            ..*law
        };
        let with_hysteresis = self.hysteretic.step(gear, &hysteretic, prediction);
        // Without a prediction the shadow's law is the reactive term alone
        // (a blend of 0), here proportional control.
        let without = self.proportional.step(gear, &proportional, prediction);
        if !(gear.is_finite()
            && reactive.is_finite()
            && model.is_finite()
            && with_hysteresis.is_finite()
            && without.is_finite())
        {
            *self = Self {
                weight: 0.0,
                ..Self::default()
            };
            return 0.0;
        }
        self.choose_law(with_hysteresis, without);
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

    /// Score the two laws' measurements and switch the reactive law when
    /// one is measured better.
    fn choose_law(&mut self, with_hysteresis: f64, without: f64) {
        self.law_scored += 1.0;
        self.hysteretic.score(with_hysteresis, self.law_scored);
        self.proportional.score(without, self.law_scored);
        if self.law_scored < LAW_MIN_SCORED {
            return;
        }
        let (h, p) = (self.hysteretic.mean_square, self.proportional.mean_square);
        if p < (1.0 - LAW_MARGIN) * h {
            self.use_proportional = true;
        } else if p > h {
            self.use_proportional = false;
        }
    }

    /// Weight of the older control in the guider's hysteresis term: the
    /// reference's, or 0 while proportional control is measured better
    /// (with the addition `law_choice`).
    pub fn hysteresis(&self, adds: &Additions) -> f64 {
        if self.use_proportional && adds.law_choice {
            0.0
        } else {
            HYSTERESIS
        }
    }

    /// A frame without a measurement, or after a dither: the shadows cannot
    /// run, and start again from the guider's own loop (`applied`, its
    /// controls' sum after this frame, and its last two controls).
    pub fn follow(&mut self, applied: f64, controls: [f64; 2]) {
        for s in [
            &mut self.reactive,
            &mut self.model,
            &mut self.hysteretic,
            &mut self.proportional,
        ] {
            s.applied = applied;
            s.controls = controls;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const LAW: Law<f64> = Law {
        control_gain: 0.6,
        prediction_gain: 0.5,
        min_move: 0.0,
        hysteresis: HYSTERESIS,
    };

    fn without(name: &str) -> Additions {
        let mut adds = Additions::ALL;
        adds.set(name, false).unwrap();
        adds
    }

    #[test]
    fn without_trust_shadows_a_worse_model_keeps_its_weight() {
        // No gear error, and a prediction that pushes 2 px every frame: the
        // model's shadow measures worse than the reactive one from the
        // first scored frame; the weight moves after MIN_SCORED of them.
        for (adds, last) in [
            (Additions::ALL, 1.0 - FALL_PER_FRAME),
            (without("trust_shadows"), 1.0),
        ] {
            let mut trust = Trust::new();
            let weights: [f64; MIN_SCORED as usize] =
                core::array::from_fn(|_| trust.measured(0.0, &LAW, Some((2.0, 1.0)), &adds));
            assert!(weights[..weights.len() - 1].iter().all(|&w| w == 1.0));
            assert_eq!(weights[weights.len() - 1], last);
        }
    }

    #[test]
    fn without_law_choice_the_hysteresis_term_stays() {
        // A steady drift of 0.5 px a frame: the hysteresis term, a tenth
        // from the control two frames back, lags it and measures worse
        // than proportional control (mean squares 0.75 and 0.69 px²).
        for (adds, hysteresis) in [(Additions::ALL, 0.0), (without("law_choice"), HYSTERESIS)] {
            let mut trust = Trust::new();
            for k in 0..LAW_MIN_SCORED as usize {
                trust.measured(0.5 * k as f64, &LAW, None, &adds);
            }
            assert_eq!(trust.hysteresis(&adds), hysteresis);
        }
    }
}
