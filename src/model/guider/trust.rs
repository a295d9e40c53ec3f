//! Trust the multi-kernel guider earns by measurement (docs/model.md,
//! "Trust earned by measurement").
//!
//! The reference blend (INDIGO's) trusts the model as soon as it has two
//! worm periods of data and a settled period. With noise and a modest worm
//! that is too soon: the blended control (proportional gain plus the
//! prediction) then passes more noise than the hysteresis it replaces, and
//! gains less than that from the prediction.
//!
//! So the guider runs shadow loops on the gear error it reconstructs (the
//! sum of its controls plus the measured error, i.e. the true gear error
//! plus this frame's noise): two with a reactive law alone, the reference's
//! hysteresis term and proportional control, and one with the guider's law
//! under the reference blend. Each shadow sees what the guider would have
//! measured under its own control, with the same noise; the mean square of
//! a shadow's measurements is its residual's plus the noise's, so they
//! compare causally and paired, frame by frame.
//!
//! The reactive term is chosen from the two reactive shadows: the
//! reference's hysteresis term (a tenth of the control two frames back)
//! lowers the effective gain and adds momentum; on some guide logs
//! proportional control is better (PHD2's own GP test uses it,
//! docs/model.md). The guider uses proportional control while its shadow is
//! measured better by a margin, and goes back when it is measured worse.
//!
//! The weight the guider gives the reference blend rises while the model's
//! shadow is measured better than the better reactive one by a margin,
//! falls while it is measured worse, and holds between. When the model's
//! stages change (a stage found, given up or moved to another line) what
//! was scored measured another model: it counts from then on as a short
//! score, so that an old lead does not carry a worse model for long.

use super::control_law::Law;
use super::HYSTERESIS;
use crate::model::additions::Additions;
use crate::model::numeric::frame_interval::FrameInterval;

/// Frames a mean square averages over (about half an hour at 2 s frames; a
/// worm period or more of a modest worm, so that its slopes both ways
/// count).
const SCORE_FRAMES: f64 = 1000.0;
/// Weight gained per frame while the model's shadow is better by
/// [`MARGIN`]: from none to full in 10 frames.
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
}

impl Shadow {
    /// One frame: its measurement of `gear`, and its control under `law`
    /// with the reference blend `blend` of `prediction` (none: the reactive
    /// law alone).
    fn step(&mut self, gear: f64, law: &Law<f64>, prediction: Option<(f64, f64)>) -> f64 {
        let input = gear - self.applied;
        // No prediction: the reactive law alone (a blend of 0).
        let prediction = prediction.or(Some((0.0, 0.0)));
        let mut control = law.control(input, self.controls[1], prediction);
        if !control.is_finite() {
            control = 0.0;
        }
        self.applied += control;
        self.controls = [control, self.controls[0]];
        input
    }
}

/// A running mean square of a shadow's measurements.
#[derive(Clone, Copy, Debug, Default)]
struct MeanSquare(f64);

impl MeanSquare {
    /// Add a measurement, the `frames`th scored, over a window of
    /// `window` frames.
    fn add(&mut self, input: f64, frames: f64, window: f64) {
        self.0 += (input * input - self.0) / frames.min(window);
    }
}

/// The measured trust in the reference blend, 0..=1, the reactive law, and
/// the shadows that measure them.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Trust {
    /// The reactive laws alone: with the hysteresis term, and with
    /// proportional control in its place.
    hysteretic: Shadow,
    proportional: Shadow,
    /// The guider's law under the reference blend.
    model: Shadow,
    /// The two reactive laws' mean squares, from the first frame, and the
    /// frames they have scored.
    law_scores: [MeanSquare; 2],
    law_scored: f64,
    use_proportional: bool,
    /// The mean squares of the model's shadow and of the two reactive
    /// ones over the frames where the model's shadow differed from the
    /// reactive ones (until then all score the same, which would only
    /// dilute the comparison), and how many they count as
    /// ([`stages_changed`] cuts it).
    ///
    /// [`stages_changed`]: Trust::stages_changed
    model_score: MeanSquare,
    reactive_scores: [MeanSquare; 2],
    scored: f64,
    weight: f64,
    /// The frame interval the windows are counted in (`trust_by_time`).
    interval: FrameInterval<f64>,
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
    /// consulted; `time_step` the time to the next frame, s (0: unknown).
    /// Returns the weight for this frame's control: 1 without the addition
    /// `trust_shadows` (the shadows still run, for the law).
    pub fn measured(
        &mut self,
        gear: f64,
        law: &Law<f64>,
        prediction: Option<(f64, f64)>,
        time_step: f64,
        adds: &Additions,
    ) -> f64 {
        if adds.trust_by_time {
            self.interval.measure(time_step);
        }
        let hysteretic = Law {
            hysteresis: HYSTERESIS,
            ..*law
        };
        let proportional = Law {
            hysteresis: 0.0,
            ..*law
        };
        let reactive = [
            self.hysteretic.step(gear, &hysteretic, None),
            self.proportional.step(gear, &proportional, None),
        ];
        let model = self.model.step(gear, law, prediction);
        if gear.is_finite() && reactive.iter().all(|r| r.is_finite()) && model.is_finite() {
            self.choose_law(reactive);
            if prediction.is_some_and(|(_, blend)| blend > 0.0) {
                self.move_weight(model, reactive, adds.law_choice);
            }
        } else {
            *self = Self {
                weight: 0.0,
                interval: self.interval,
                ..Self::default()
            };
        }
        if adds.trust_shadows {
            self.weight
        } else {
            1.0
        }
    }

    /// The model's stages changed: what was scored measured another model,
    /// and counts from now on as [`MIN_SCORED`] frames, no more (the new
    /// model's frames weigh a 200th at first, not a 1000th). Nothing is
    /// held: a model whose new stages are worse loses its old lead within
    /// about as many frames. Starting the score afresh held the weight for
    /// those frames, and cost the short PHD2 logs (02: 0.26 -> 0.17 %).
    /// Without the addition `trust_rescore` the old score stands.
    pub fn stages_changed(&mut self, adds: &Additions) {
        if adds.trust_rescore {
            self.scored = self.scored.min(self.interval.frames(MIN_SCORED));
        }
    }

    /// Score a frame where the model's shadow differs from the reactive
    /// ones, and move the weight: against the better reactive law where
    /// the guider may choose it (`law_choice`), else the hysteresis.
    fn move_weight(&mut self, model: f64, reactive: [f64; 2], law_choice: bool) {
        self.scored += 1.0;
        let window = self.interval.frames(SCORE_FRAMES);
        self.model_score.add(model, self.scored, window);
        for (score, r) in self.reactive_scores.iter_mut().zip(reactive) {
            score.add(r, self.scored, window);
        }
        if self.scored < self.interval.frames(MIN_SCORED) {
            return;
        }
        let [h, p] = self.reactive_scores.map(|s| s.0);
        let r = if law_choice { h.min(p) } else { h };
        let m = self.model_score.0;
        if m < (1.0 - MARGIN) * r {
            self.weight += RISE_PER_FRAME;
        } else if m > r {
            self.weight -= FALL_PER_FRAME;
        }
        self.weight = self.weight.clamp(0.0, 1.0);
    }

    /// Score the two reactive laws' measurements and switch the law when
    /// one is measured better.
    fn choose_law(&mut self, reactive: [f64; 2]) {
        self.law_scored += 1.0;
        let window = self.interval.frames(SCORE_FRAMES);
        for (score, r) in self.law_scores.iter_mut().zip(reactive) {
            score.add(r, self.law_scored, window);
        }
        if self.law_scored < self.interval.frames(LAW_MIN_SCORED) {
            return;
        }
        let [h, p] = self.law_scores.map(|s| s.0);
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
            &mut self.hysteretic,
            &mut self.proportional,
            &mut self.model,
        ] {
            s.applied = applied;
            s.controls = controls;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::SplitMix64;

    const LAW: Law<f64> = Law {
        control_gain: 0.6,
        prediction_gain: 0.5,
        min_move: 0.0,
        hysteresis: HYSTERESIS,
    };

    const FRAME_S: f64 = crate::model::numeric::frame_interval::COUNTED_FRAME_S;
    const MIN_SCORED: usize = super::MIN_SCORED as usize;
    const LAW_MIN_SCORED: usize = super::LAW_MIN_SCORED as usize;

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
            let weights: [f64; MIN_SCORED] = core::array::from_fn(|_| {
                trust.measured(0.0, &LAW, Some((2.0, 1.0)), FRAME_S, &adds)
            });
            assert!(weights[..weights.len() - 1].iter().all(|&w| w == 1.0));
            assert_eq!(weights[weights.len() - 1], last);
        }
    }

    /// Frames until the weight first moves, as above, at frames of
    /// `time_step(k)` s, with the additions `adds`.
    fn frames_to_move(adds: &Additions, time_step: impl Fn(usize) -> f64) -> Option<usize> {
        let mut trust = Trust::new();
        (0..2 * MIN_SCORED)
            .position(|k| trust.measured(0.0, &LAW, Some((2.0, 1.0)), time_step(k), adds) < 1.0)
            .map(|n| n + 1)
    }

    #[test]
    fn behind_longer_frames_the_weight_waits_fewer() {
        // Twice the counted interval (a time step of 0, unknown, keeps the
        // interval measured): half the frames, the same time.
        let twice = |k: usize| {
            if k.is_multiple_of(2) {
                2.0 * FRAME_S
            } else {
                0.0
            }
        };
        assert_eq!(frames_to_move(&Additions::ALL, twice), Some(MIN_SCORED / 2));
        // Shorter frames keep the count.
        assert_eq!(
            frames_to_move(&Additions::ALL, |_| 0.5 * FRAME_S),
            Some(MIN_SCORED)
        );
        // Without `trust_by_time` longer frames keep it too.
        let longer = |_| 4.0 * FRAME_S;
        assert_eq!(
            frames_to_move(&without("trust_by_time"), longer),
            Some(MIN_SCORED)
        );
    }

    /// Frames of a faded stage until the weight first falls: a sine of 2 px
    /// and 50 frames under uniform noise of 1 px either way, predicted
    /// exactly for 3,000 frames; then gone while the model still predicts
    /// it. The model's lead before and its loss after are alike. The stages
    /// change where the stage goes.
    fn frames_to_fall(adds: &Additions) -> usize {
        let sine = |k: usize| 2.0 * (k as f64 * core::f64::consts::TAU / 50.0).sin();
        // The prediction of the next frame's change of the sine, over the
        // prediction gain the law applies it with.
        let predicted = |k: usize| (sine(k + 1) - sine(k)) / LAW.prediction_gain;
        let mut rng = SplitMix64::new(1);
        let mut noise = move || rng.f64_in(-1.0, 1.0);
        let mut trust = Trust::new();
        for k in 0..3000 {
            let gear = sine(k) + noise();
            trust.measured(gear, &LAW, Some((predicted(k), 1.0)), FRAME_S, adds);
        }
        assert_eq!(trust.weight, 1.0);
        trust.stages_changed(adds);
        (3000..20_000)
            .position(|k| {
                let prediction = Some((predicted(k), 1.0));
                trust.measured(noise(), &LAW, prediction, FRAME_S, adds) < 1.0
            })
            .map_or(usize::MAX, |n| n + 1)
    }

    #[test]
    fn a_model_whose_stages_changed_is_scored_again() {
        // What was scored counts as MIN_SCORED frames: the new model's
        // loss outweighs the old lead within about as many.
        let with = frames_to_fall(&Additions::ALL);
        assert!(with < MIN_SCORED, "{with}");
        // Without `trust_rescore` the old lead fades over the whole window.
        let without = frames_to_fall(&without("trust_rescore"));
        assert!(without > 2 * MIN_SCORED, "{without}");
    }

    #[test]
    fn without_law_choice_the_hysteresis_term_stays() {
        // A steady drift of 0.5 px a frame: the hysteresis term, a tenth
        // from the control two frames back, lags it and measures worse
        // than proportional control (mean squares 0.75 and 0.69 px²).
        for (adds, hysteresis) in [(Additions::ALL, 0.0), (without("law_choice"), HYSTERESIS)] {
            let mut trust = Trust::new();
            for k in 0..LAW_MIN_SCORED {
                trust.measured(0.5 * k as f64, &LAW, None, FRAME_S, &adds);
            }
            assert_eq!(trust.hysteresis(&adds), hysteresis);
        }
    }
}
