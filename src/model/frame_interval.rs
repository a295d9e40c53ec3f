//! Windows counted in frames that last no longer than at 2 s frames.
//!
//! The scores that decide how much of a prediction to apply (the guider's
//! trust, `guider::trust`; the firmware's feed-forward weight,
//! `crate::mount::guiding::feed_forward_weight`) average over, and wait
//! for, counts of frames tuned at 2 s frames. Behind longer frames the
//! gear moves on further within such a window (a stage that fades, a model
//! gone wrong), so each count is cut in proportion. Shorter frames keep the
//! count: the comparison's statistics need the frames.

use super::guider::MAX_TIME_STEP_S;

/// The frame interval the counts are for, s.
pub const COUNTED_FRAME_S: f64 = 2.0;
/// Frames the measured interval averages over: a gap (a download, a lost
/// star) moves it by a fraction of its length over this.
const INTERVAL_FRAMES: f64 = 32.0;

/// The measured frame interval.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrameInterval {
    /// s; 0: none measured yet.
    frame_s: f64,
}

impl FrameInterval {
    /// None measured yet: counts are kept.
    pub const UNMEASURED: FrameInterval = FrameInterval { frame_s: 0.0 };

    /// Follow the frame interval: the first time step sets it, later ones
    /// move it by a share of `INTERVAL_FRAMES`. A step that is not finite
    /// and positive (unknown) is skipped; a longer one than any the guider
    /// predicts over counts as that.
    pub fn measure(&mut self, time_step: f64) {
        if !(time_step.is_finite() && time_step > 0.0) {
            return;
        }
        let time_step = time_step.min(MAX_TIME_STEP_S);
        if self.frame_s > 0.0 {
            self.frame_s += (time_step - self.frame_s) / INTERVAL_FRAMES;
        } else {
            self.frame_s = time_step;
        }
    }

    /// `count` frames at [`COUNTED_FRAME_S`], cut in proportion where the
    /// measured frames are longer.
    pub fn frames(&self, count: f64) -> f64 {
        if self.frame_s > COUNTED_FRAME_S {
            count * COUNTED_FRAME_S / self.frame_s
        } else {
            count
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn longer_frames_cut_the_count_in_proportion_and_shorter_keep_it() {
        let mut interval = FrameInterval::default();
        assert_eq!(interval.frames(200.0), 200.0);
        for step in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            interval.measure(step);
        }
        assert_eq!(interval, FrameInterval::default());
        interval.measure(4.0);
        assert_eq!(interval.frames(200.0), 100.0);
        // A gap of ten minutes counts as the longest step, by a share.
        interval.measure(600.0);
        assert_eq!(
            interval.frame_s,
            4.0 + (MAX_TIME_STEP_S - 4.0) / INTERVAL_FRAMES
        );
        let mut short = FrameInterval::default();
        short.measure(0.5);
        assert_eq!(short.frames(200.0), 200.0);
    }
}
