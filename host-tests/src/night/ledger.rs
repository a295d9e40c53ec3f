//! What the night's score and its events are made of: the pointing RMS of
//! a stretch of imaging, and for each event the frames the firmware's
//! learner took while it lasted and how many it learned as gear error.

use crate::st4_sim::{FrameLearned, SAMPLE_US};

/// A sum of squared pointing errors and its number of samples.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Rms {
    pub sum_sq: f64,
    pub n: u64,
}

impl Rms {
    /// The samples between two readings of the rig's running sums.
    pub fn between(from: (f64, u64), to: (f64, u64)) -> Rms {
        Rms {
            sum_sq: to.0 - from.0,
            n: to.1 - from.1,
        }
    }

    /// The time the samples cover, s.
    pub fn seconds(&self) -> f64 {
        (self.n * SAMPLE_US) as f64 * 1e-6
    }

    /// The RMS, arcsec (NaN without samples).
    pub fn rms(&self) -> f64 {
        if self.n == 0 {
            f64::NAN
        } else {
            (self.sum_sq / self.n as f64).sqrt()
        }
    }
}

impl std::ops::Add for Rms {
    type Output = Rms;

    fn add(self, other: Rms) -> Rms {
        Rms {
            sum_sq: self.sum_sq + other.sum_sq,
            n: self.n + other.n,
        }
    }
}

impl std::ops::Sub for Rms {
    type Output = Rms;

    /// The samples of `self` without those of `other`, a part of them.
    fn sub(self, other: Rms) -> Rms {
        Rms {
            sum_sq: self.sum_sq - other.sum_sq,
            n: self.n - other.n,
        }
    }
}

/// What the guider or the mount was doing while a window lasted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Activity {
    /// The guider's calibration pulses.
    Calibration,
    /// The guider stopped (from its stop to the next start).
    GuiderOff,
    /// Re-pointed through the port (a flip is one too).
    Slew,
    Flip,
    /// Re-pointed by hand.
    Push,
    /// The guide frames missing while the main camera downloads.
    Download,
    /// A dither's own pulse.
    Dither,
    /// From a dither, or a resume, to the end of settling.
    Settling,
    Refocus,
    Clouds,
    LostStar,
}

impl Activity {
    pub const ALL: [Activity; 11] = [
        Activity::Calibration,
        Activity::GuiderOff,
        Activity::Slew,
        Activity::Flip,
        Activity::Push,
        Activity::Download,
        Activity::Dither,
        Activity::Settling,
        Activity::Refocus,
        Activity::Clouds,
        Activity::LostStar,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Activity::Calibration => "calibration",
            Activity::GuiderOff => "guider_off",
            Activity::Slew => "slew",
            Activity::Flip => "flip",
            Activity::Push => "push",
            Activity::Download => "download",
            Activity::Dither => "dither",
            Activity::Settling => "settling",
            Activity::Refocus => "refocus",
            Activity::Clouds => "clouds",
            Activity::LostStar => "lost_star",
        }
    }
}

/// One stretch of an activity, us of the night.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Window {
    pub activity: Activity,
    pub from_us: u64,
    pub until_us: u64,
    /// Frames the learner takes up to this long after `from_us` may have
    /// been made before the window ([`fill_grace_us`]).
    pub made_before_us: u64,
}

/// How long after it was made a frame may reach the learner, at the
/// guider's cadence `cadence_us`: a frame the firmware fills in for a
/// guider that went quiet comes a quarter of the cadence after it fell
/// due (the firmware's grace for a late pulse), and the learner's queue
/// takes it [`LEARN_LAG_US`] after that at most.
pub fn fill_grace_us(cadence_us: u64) -> u64 {
    cadence_us / 4 + LEARN_LAG_US
}

/// A frame made in a window reaches the learner a little after it: when
/// its pulse ends, and the learner's queue takes it.
pub const LEARN_LAG_US: u64 = 500_000;

/// The frames of one activity over the night.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Tally {
    pub windows: u32,
    pub seconds: f64,
    /// Frames the learner took from [`Window::made_before_us`] after a
    /// window's start to [`LEARN_LAG_US`] after its end, and of them those
    /// it learned as gear error.
    pub frames: u32,
    pub learned: u32,
}

/// The tally of `activity` over `windows`, from the frames the learner took.
pub fn tally(activity: Activity, windows: &[Window], frames: &[FrameLearned]) -> Tally {
    let mut t = Tally::default();
    for w in windows.iter().filter(|w| w.activity == activity) {
        t.windows += 1;
        t.seconds += (w.until_us - w.from_us) as f64 * 1e-6;
        let end = w.until_us + LEARN_LAG_US;
        let start = w.from_us + w.made_before_us;
        let from = frames.partition_point(|f| f.at_us <= start);
        // A window shorter than the frames made before it holds none.
        let until = frames.partition_point(|f| f.at_us < end).max(from);
        let inside = &frames[from..until];
        t.frames += inside.len() as u32;
        t.learned += inside.iter().filter(|f| f.learned).count() as u32;
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_window_counts_the_frames_taken_after_its_start_until_the_lag_after_its_end() {
        assert_eq!(fill_grace_us(10_000_000), 2_500_000 + LEARN_LAG_US);
        let w = Window {
            activity: Activity::Slew,
            from_us: 1_000_000,
            until_us: 2_000_000,
            made_before_us: 250_000,
        };
        let at = |at_us, learned| FrameLearned { at_us, learned };
        let frames = [
            at(1_250_000, true),
            at(1_250_001, false),
            at(2_000_000 + LEARN_LAG_US - 1, true),
            at(2_000_000 + LEARN_LAG_US, true),
        ];
        let t = tally(Activity::Slew, &[w], &frames);
        assert_eq!((t.windows, t.frames, t.learned), (1, 2, 1));
        assert_eq!(t.seconds, 1.0);
        assert_eq!(tally(Activity::Flip, &[w], &frames), Tally::default());
        // A window that ends before the frames made before it could come
        // (a short dither's pulse at a long cadence) holds none.
        let short = Window {
            from_us: 500_000,
            until_us: 500_001,
            made_before_us: 1_000_000,
            ..w
        };
        let t = tally(Activity::Slew, &[short], &frames);
        assert_eq!((t.windows, t.frames), (1, 0));
    }
}
