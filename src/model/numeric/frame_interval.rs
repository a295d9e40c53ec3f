//! The guider's frame interval, followed over its recent frames, and the
//! counts of frames that judge a loop cut to last no longer than they do
//! at 2 s frames.
//!
//! The model's trust (`model::guider::trust`) and the firmware's
//! feed-forward weight (`mount::guiding::feed_forward_weight`) both score a
//! loop over windows of frames, counted at 2 s frames. Behind longer frames
//! the gear moves on further within such a window (a stage that fades, a
//! model gone wrong), so each count is cut in proportion; shorter frames
//! keep the count, which is the comparison's statistics.

use super::Scalar;

/// The frame interval the counts are written for, s.
pub const COUNTED_FRAME_S: f64 = 2.0;
/// Frames the measured interval averages over: a gap (a download, a lost
/// star) moves it by a fraction of its length over this.
const INTERVAL_FRAMES: f64 = 32.0;

/// The measured frame interval (none until the first), in the scalar type
/// of the counts it scales: the model's trust counts in `f64`, the
/// firmware's feed-forward weight in `f32`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrameInterval<S> {
    seconds: S,
}

impl<S: Scalar> FrameInterval<S> {
    /// Nothing measured yet: counts as they are written.
    pub const UNKNOWN: FrameInterval<S> = FrameInterval { seconds: S::ZERO };

    /// One frame `interval_s` after the previous (not finite or not
    /// positive: unknown, nothing changes): the first sets the interval,
    /// later ones move it by a share of the difference (`INTERVAL_FRAMES`).
    pub fn measure(&mut self, interval_s: S) {
        if !(interval_s.is_finite() && interval_s > S::ZERO) {
            return;
        }
        if self.seconds > S::ZERO {
            self.seconds += (interval_s - self.seconds) / S::from_f64(INTERVAL_FRAMES);
        } else {
            self.seconds = interval_s;
        }
    }

    /// `count` frames at [`COUNTED_FRAME_S`], cut in proportion where the
    /// measured frames are longer.
    pub fn frames(&self, count: S) -> S {
        let counted = S::from_f64(COUNTED_FRAME_S);
        if self.seconds > counted {
            count * counted / self.seconds
        } else {
            count
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn longer_frames_cut_the_count_and_shorter_keep_it() {
        let mut f = FrameInterval::<f64>::UNKNOWN;
        assert_eq!(f.frames(200.0), 200.0);
        f.measure(f64::NAN);
        f.measure(0.0);
        f.measure(-4.0);
        assert_eq!(f, FrameInterval::UNKNOWN);
        f.measure(4.0);
        assert_eq!(f.frames(200.0), 100.0);
        // A gap of 36 s moves the interval by a 32nd of its excess.
        f.measure(36.0);
        assert_eq!(f.frames(200.0), 80.0);
        let mut short = FrameInterval::<f32>::UNKNOWN;
        short.measure(0.5);
        assert_eq!(short.frames(200.0), 200.0);
    }
}
