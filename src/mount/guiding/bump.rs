//! A step of the star no model explains (a cable snag, a gust, a knock on
//! the tripod), taken out of the observations as a dither's move is
//! (docs/decisions.md, "A bump").
//!
//! After such a step the guider brings the star back, and the mount's
//! correction keeps the step from then on: the observations (correction
//! plus measured error) stand higher by the step for good. Learned, it is
//! a level jump the model has to explain with its stages and its trend,
//! and it does so badly for minutes (a 30 arcsec bump on C5: 1.2-6.0
//! arcsec of error for the next 30 s, where the guider alone is back
//! within 0.9 in 6 s). So a pulse far beyond the recent ones settles the
//! model as a dither does, and the step is measured: the observations less
//! the model's own predicted path, over the settling frames against the
//! frames before. Every later observation is lowered by the steps measured
//! so far ([`Bump::level`]). That holds before the model is trusted too: a
//! step learned then stays in the data the model is trusted on (a 100
//! arcsec bump while the model earned its trust left C5, noise-free, with
//! stages of 900-1,400 s and its feed-forward off by up to 0.7 arcsec/s
//! for the minute after).

/// A pulse beyond this many times the earned share's bound (itself 4 RMS of
/// the recent pulses) is a step of the star.
pub const BOUNDS: f32 = 2.0;
/// Frames the mean before a step averages over (a running mean).
const BEFORE_FRAMES: f64 = 8.0;
/// Settling frames skipped before the step is measured: the exposure that
/// saw the step begin, and the one after.
const SKIP_FRAMES: u8 = 2;

/// A step being measured over the settling frames.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Measuring {
    frames_left: u8,
    skip: u8,
    sum: f64,
    n: u32,
}

/// The steps taken out of the observations.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bump {
    /// Arcsec taken off every observation.
    level: f64,
    /// The model's predicted path: its feed-forward summed over gear time
    /// (arcsec).
    path: f64,
    /// The feed-forward rate in effect since the last frame.
    rate: f64,
    /// Running mean of observation less path (arcsec), before a step.
    before: Option<f64>,
    measuring: Option<Measuring>,
}

impl Bump {
    pub const NONE: Bump = Bump {
        level: 0.0,
        path: 0.0,
        rate: 0.0,
        before: None,
        measuring: None,
    };

    /// A step began with this frame: measure it over `frames` settling
    /// frames. Nothing to measure it against yet: ignored.
    pub fn start(&mut self, frames: u8) {
        if self.before.is_some() {
            self.measuring = Some(Measuring {
                frames_left: frames,
                skip: SKIP_FRAMES,
                sum: 0.0,
                n: 0,
            });
        }
    }

    /// One frame `interval_s` after the previous one, with its observation
    /// (raw, before [`level`](Self::level) is taken off) if measured;
    /// `learned`: not a settling frame (only those set the mean before).
    pub fn frame(&mut self, interval_s: f64, observed: Option<f64>, learned: bool) {
        if interval_s.is_finite() && interval_s > 0.0 {
            self.path += self.rate * interval_s;
        }
        let x = observed.map(|o| o - self.path).filter(|x| x.is_finite());
        let Some(m) = self.measuring.as_mut() else {
            if let Some(x) = x.filter(|_| learned) {
                self.before = Some(match self.before {
                    Some(b) => b + (x - b) / BEFORE_FRAMES,
                    None => x,
                });
            }
            return;
        };
        if m.skip > 0 {
            m.skip -= 1;
        } else if let Some(x) = x {
            m.sum += x;
            m.n += 1;
        }
        m.frames_left = m.frames_left.saturating_sub(1);
        if m.frames_left == 0 {
            if let (Some(b), true) = (self.before, m.n > 0) {
                let after = m.sum / m.n as f64;
                self.level += after - b;
                self.before = Some(after);
            }
            self.measuring = None;
        }
    }

    /// The feed-forward rate installed now (arcsec per second of gear
    /// time), for the path to the next frame.
    pub fn installed(&mut self, rate_arcsec_per_s: f32) {
        self.rate = if rate_arcsec_per_s.is_finite() {
            rate_arcsec_per_s as f64
        } else {
            0.0
        };
    }

    /// Arcsec to take off every observation.
    pub fn level(&self) -> f64 {
        self.level
    }

    /// The path means nothing across what came (the port slewed the
    /// axis): steps are measured afresh, the level stays.
    pub fn interrupt(&mut self) {
        self.before = None;
        self.measuring = None;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_step_is_measured_against_the_predicted_path() {
        let mut b = Bump::NONE;
        // The model predicts a slope of 0.125 arcsec/s, the gear follows it.
        b.installed(0.125);
        for k in 0..20 {
            b.frame(2.0, Some(0.25 * k as f64 + 5.0), true);
        }
        assert_eq!(b.level(), 0.0);
        b.start(10);
        for k in 20..30 {
            b.frame(2.0, Some(0.25 * k as f64 + 5.0 + 30.0), false);
        }
        assert!((b.level() - 30.0).abs() < 1e-9, "{}", b.level());
        // And back.
        b.start(10);
        for k in 30..40 {
            b.frame(2.0, Some(0.25 * k as f64 + 5.0), false);
        }
        assert!(b.level().abs() < 1e-9, "{}", b.level());
    }

    #[test]
    fn nothing_before_no_step_and_bad_input_is_ignored() {
        let mut b = Bump::NONE;
        b.start(10);
        b.frame(2.0, Some(3.0), true);
        b.installed(f32::NAN);
        b.frame(f64::NAN, Some(f64::INFINITY), true);
        b.frame(2.0, None, true);
        // Settling frames (a dither's) set nothing before a step.
        let mut c = Bump::NONE;
        c.frame(2.0, Some(3.0), false);
        c.start(10);
        for _ in 0..10 {
            c.frame(2.0, Some(9.0), false);
        }
        assert_eq!((b.level(), c.level()), (0.0, 0.0));
    }
}
