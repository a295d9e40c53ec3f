//! How much of the model's feed-forward the firmware applies, earned
//! against the guider alone (docs/model.md, "Additions and their worth").
//!
//! The model's own trust (`model::guider::trust`) compares shadows of the
//! model's control law with the hysteresis guider's. The firmware's loop is
//! another one: the PC's guider corrects what the feed-forward leaves, one
//! exposure late, and a prediction that helps the model's loop can hurt
//! there (a fast stage behind long exposures, which the model takes for a
//! harmonic of a slower one and predicts at a drifting phase).
//!
//! So the learner runs one shadow of the firmware's loop without a
//! learner: the guider alone, a proportional loop of the assumed
//! aggressiveness on the reconstructed gear error, started from the real
//! loop's state. The real loop's measured error `e` is the shadow's `e_A`
//! less the feed-forward's effect; the loop is linear in its corrections,
//! so at weight `w` that effect is `w h` with `h = (e_A - e) / w`, the
//! noise cancelling (both see the same measurement). The mean square at
//! weight `v` is then `<e_A^2> - 2 v <e_A h> + v^2 <h^2>`, least at
//! `v = <e_A h> / <h^2>`, the target the weight moves to, within 0..=1. A
//! weight below [`PROBE`] would no longer measure `h`, so a target below it
//! is none: the feed-forward is switched off and stays off (the guider
//! alone is the safe outcome) until a model reset or restore measures again.
//!
//! Its windows are counted at 2 s frames: behind longer frames the counts
//! are cut in proportion (`FrameInterval`, as the model's trust's are; the
//! addition `weight_by_time`), so that the weight moves after as much time.
//! Its pace stays per frame: scaled with the frames' length too, the weight
//! fell further on a drawn mount whose model still improved (population
//! mount 97, docs/model.md).

use crate::model::numeric::clamp;
use crate::model::numeric::frame_interval::FrameInterval;

/// Frames the running means average over (about 30 minutes at 2 s).
const WINDOW_FRAMES: f32 = 1000.0;
/// Frames with a feed-forward scored before the weight moves.
const MIN_SCORED: f32 = 200.0;
/// The gain in mean square, as a fraction of the guider alone's, below
/// which the feed-forward stays in full: the shadow, a proportional loop,
/// measures a guider with hysteresis and a min move a little better than it
/// is, and a smaller gain is within that error (without it the noisy cases
/// lost to a weight a little below 1).
const MARGIN: f32 = 0.05;
/// Largest change of the weight per frame: from full to none in 100 frames.
const STEP: f32 = 0.01;
/// The least weight at which the feed-forward's effect is measured: below
/// it, the effect is too small against the shadow's own error.
pub const PROBE: f32 = 0.1;

/// The share of the feed-forward applied, and the shadow that earns it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FeedForwardWeight {
    /// The shadow's correction so far (None: taken from the real loop at
    /// the next measured frame).
    shadow_applied: Option<f32>,
    /// Running means of `e_A h`, `h^2` and `e_A^2`.
    cross: f32,
    power: f32,
    shadow_square: f32,
    scored: f32,
    /// Where the weight moves: the best share last measured.
    target: f32,
    weight: f32,
    /// The frame interval the windows are counted in.
    interval: FrameInterval<f32>,
}

impl FeedForwardWeight {
    /// The feed-forward in full, nothing measured yet.
    pub const FULL: FeedForwardWeight = FeedForwardWeight {
        shadow_applied: None,
        cross: 0.0,
        power: 0.0,
        shadow_square: 0.0,
        scored: 0.0,
        target: 1.0,
        weight: 1.0,
        interval: FrameInterval::UNKNOWN,
    };

    /// The share of the feed-forward to apply, 0..=1.
    pub fn weight(&self) -> f32 {
        self.weight
    }

    /// The model changed (a stage found, given up or moved): its
    /// feed-forward is another, measured again from full.
    pub fn remeasure(&mut self) {
        *self = FeedForwardWeight {
            shadow_applied: self.shadow_applied,
            interval: self.interval,
            ..Self::FULL
        };
    }

    /// A frame that is no measurement of the loop (unmeasured, a dither or
    /// its settling, a calibration, a slew, a refused observation): the
    /// shadow starts again from the real loop's state.
    pub fn interrupt(&mut self) {
        self.shadow_applied = None;
    }

    /// A measured guide frame came `interval_s` after the previous one:
    /// the windows follow the frames' length (`weight_by_time`).
    pub fn frame_interval(&mut self, interval_s: f32) {
        self.interval.measure(interval_s);
    }

    /// A measured guide frame: `gear` the reconstructed gear error, `applied`
    /// the firmware's correction (so the guider measured `gear - applied`),
    /// `gain` the guider's assumed aggressiveness, `feeding` whether a
    /// feed-forward was in effect. Moves the weight.
    pub fn measured(&mut self, gear: f32, applied: f32, gain: f32, feeding: bool) {
        let shadow = *self.shadow_applied.get_or_insert(applied);
        let (e, e_a) = (gear - applied, gear - shadow);
        if !(e.is_finite() && e_a.is_finite() && gain.is_finite()) {
            self.shadow_applied = None;
            return;
        }
        self.shadow_applied = Some(shadow + gain * e_a);
        if !feeding {
            return;
        }
        // The counts' share at the frames' length (1 at 2 s or shorter).
        let cut = self.interval.frames(1.0);
        let min_scored = MIN_SCORED * cut;
        if self.weight >= PROBE {
            let h = (e_a - e) / self.weight;
            self.scored += 1.0;
            let n = self.scored.min(WINDOW_FRAMES * cut);
            self.cross += (e_a * h - self.cross) / n;
            self.power += (h * h - self.power) / n;
            self.shadow_square += (e_a * e_a - self.shadow_square) / n;
            if self.scored >= min_scored && self.power > 0.0 {
                // A share below the probe cannot be measured: none. Less
                // than the feed-forward in full only where that gains more
                // than the shadow's own error.
                let best = clamp(self.cross / self.power, 0.0, 1.0);
                let better_by = self.power * (1.0 - best) * (1.0 - best);
                self.target = if better_by <= MARGIN * self.shadow_square {
                    1.0
                } else if best < PROBE {
                    0.0
                } else {
                    best
                };
            }
        }
        if self.scored >= min_scored {
            self.weight = clamp(self.target, self.weight - STEP, self.weight + STEP);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The real loop: a guider of `gain` on `gear`, the firmware adding
    /// `ff(k)` at the earned weight of the feed-forward; returns the state
    /// after `frames`.
    fn run(
        gear: impl Fn(usize) -> f32,
        ff: impl Fn(usize) -> f32,
        frames: usize,
    ) -> FeedForwardWeight {
        let gain = 0.7;
        let mut fw = FeedForwardWeight::FULL;
        let mut applied = 0.0;
        for k in 0..frames {
            let g = gear(k);
            fw.measured(g, applied, gain, true);
            let e = g - applied;
            applied += gain * e + fw.weight() * ff(k);
        }
        fw
    }

    #[test]
    fn a_feed_forward_that_predicts_the_gear_keeps_its_weight() {
        // The gear rises 0.1 per frame; the feed-forward adds that.
        let fw = run(|k| 0.1 * k as f32, |_| 0.1, 2000);
        assert_eq!(fw.weight(), 1.0);
    }

    #[test]
    fn a_feed_forward_of_noise_loses_its_weight() {
        // A still gear; the feed-forward swings (a prediction at the wrong
        // phase): every frame it adds is error.
        let fw = run(|_| 0.0, |k| if k % 7 < 3 { 0.5 } else { -0.375 }, 2000);
        assert_eq!(fw.weight(), 0.0);
    }

    /// [`run`] on a sine of 5 arcsec, the feed-forward predicting `scale`
    /// times its change to the next frame.
    fn sine(scale: f32) -> FeedForwardWeight {
        let gear = |k: usize| (k as f32 * 0.05).sin() * 5.0;
        run(gear, |k| scale * (gear(k + 1) - gear(k)), 3000)
    }

    #[test]
    fn half_a_feed_forward_earns_half() {
        // The feed-forward predicts twice the gear's rise: the best share
        // of it is a half.
        let fw = sine(2.0);
        assert!((fw.weight() - 0.5).abs() < 0.05, "{}", fw.weight());
    }

    #[test]
    fn a_share_that_would_gain_little_keeps_the_feed_forward_in_full() {
        // The feed-forward predicts 1.2 times the gear's rise: a sixth less
        // of it would be best, but gains less than the margin.
        assert_eq!(sine(1.2).weight(), 1.0);
    }

    #[test]
    fn nothing_moves_before_the_scored_frames_or_without_a_feed_forward() {
        let mut fw = FeedForwardWeight::FULL;
        for k in 0..(MIN_SCORED as usize - 1) {
            fw.measured(0.0, if k % 2 == 0 { 1.0 } else { -1.0 }, 0.7, true);
        }
        assert_eq!(fw.weight(), 1.0);
        for _ in 0..1000 {
            fw.measured(5.0, -5.0, 0.7, false);
        }
        assert_eq!(fw.weight(), 1.0);
    }

    /// The frames at which the weight first moves and reaches none, with a
    /// feed-forward of noise on a still gear, each frame `interval_s` after
    /// the last (None: the interval not measured, as without
    /// `weight_by_time`).
    fn frames_to_none(interval_s: Option<f32>) -> (usize, usize) {
        let mut fw = FeedForwardWeight::FULL;
        let mut applied = 0.0;
        let mut first = None;
        for k in 1..=1000 {
            if let Some(i) = interval_s {
                fw.frame_interval(i);
            }
            fw.measured(0.0, applied, 0.7, true);
            applied += -0.7 * applied + fw.weight() * if k % 2 == 0 { 1.0 } else { -1.0 };
            if fw.weight() < 1.0 && first.is_none() {
                first = Some(k);
            }
            if fw.weight() == 0.0 {
                return (first.unwrap(), k);
            }
        }
        panic!("the weight stays at {}", fw.weight());
    }

    #[test]
    fn behind_longer_frames_the_weight_moves_after_as_much_time() {
        let min = MIN_SCORED as usize;
        // At the counted interval, and not measured: MIN_SCORED frames,
        // then none 100 frames later.
        assert_eq!(frames_to_none(Some(2.0)), (min, min + 100));
        assert_eq!(frames_to_none(None), (min, min + 100));
        // Twice as long: half the frames, at the same pace.
        assert_eq!(frames_to_none(Some(4.0)), (min / 2, min / 2 + 100));
        // Shorter frames keep the counts.
        assert_eq!(frames_to_none(Some(0.5)), (min, min + 100));
    }

    #[test]
    fn bad_input_restarts_the_shadow_and_leaves_the_weight() {
        let mut fw = FeedForwardWeight::FULL;
        fw.measured(f32::NAN, 0.0, 0.7, true);
        fw.measured(1.0, f32::INFINITY, 0.7, true);
        assert_eq!(fw, FeedForwardWeight::FULL);
    }
}
