//! How much of the guider's RA pulses the firmware carries out, earned by
//! measurement (docs/decisions.md, "The earned pulse share").
//!
//! Behind a learned feed-forward the guider's pulses do two things: they
//! correct what the model does not explain, and they react to the noise of
//! the star's measurement. Obeyed in full, the reaction to the noise is the
//! loop's floor (docs/results.md). The pulses themselves tell the two
//! apart: a loop that reacts to white noise more than it should makes
//! successive measurements, hence successive pulses, anti-correlated (a
//! loop of gain G on white noise alone: correlation -G/2 between
//! neighbours), while an error the loop follows too slowly makes them
//! correlated. The loop that weighs the noise against the error it
//! follows at best (a Kalman filter's gain) leaves its measurements
//! uncorrelated. So the learner scales the share of each pulse it carries
//! out by the measured correlation of neighbouring pulses, frame by frame,
//! down to the configured least share. No guider setting enters: the
//! correlation does not depend on the pulses' scale.
//!
//! Full pulses at once: while the model is not trusted in full, and for a
//! frame that is not a plain guide frame (a dither and its settling, the
//! guider silent or its pulses queued). A pulse far beyond the recent ones
//! is carried out in full by the fast part, which makes up what it held
//! back of any pulse longer than [`PulseShare::up_to_arcsec`]
//! (`super::share`). Full pulses come back only after two such pulses in a
//! row the same way (an error no model explains: a calibration's steps, a
//! bump). One alone leaves the share: put back to full by a single noisy
//! measurement, a guider that overcorrects (an effective gain of 2) and
//! that the share had held would swing again, and that swing, at about
//! four frames a period, makes neighbouring pulses correlated: nothing here
//! would lower the share again (docs/results.md, "Where the guider alone is
//! unstable"). Such a swing makes pulses two frames apart anti-correlated;
//! [`EarnedShare::swing`] measures that for `super::pulse_weight`.
//!
//! A guider's calibration is recognised from its third equal step
//! (`super::calibration`); its first two look like guide pulses beyond the
//! recent ones, twice the same way. Once it is recognised they are taken
//! back out ([`EarnedShare::calibrating`]): guiding after it goes on with
//! the share earned before. Where its frames come further apart
//! (`CARRY_INTERVAL`) more of the error falls to each pulse: the share is
//! scaled up by the square root of the intervals' ratio and earned on
//! from the new frames' pulses ([`LongerFrames::Scale`]), or earned again
//! from full pulses ([`LongerFrames::EarnAgain`]).
//!
//! Across a power cycle: the share and the statistics behind it are saved
//! with the model ([`SavedShare`], in the learner's record), so a night
//! restored with a trusted model does not spend its first minutes earning
//! the share again (about 7 minutes of full pulses otherwise). The saved
//! share is used only while the restored model is trusted.

use crate::model::numeric::clamp;
use crate::model::snapshot::{crc32, Field, SnapshotError};
use crate::mount::frame::PulseShare;
use crate::mount::guiding::pulse_weight::LEAST;

/// Frames the pulse statistics average over (about two minutes at 2 s):
/// the correlation's spread is about 1 / sqrt(frames).
const WINDOW_FRAMES: u32 = 64;
/// Relative change of the share per frame and unit of correlation: from
/// full to a third in about 100 frames of noise alone.
const RATE: f32 = 0.05;
/// After a restore, the share above the saved one while the pulses are
/// anti-correlated (noise again, the restored model's placement over)
/// returns this fraction of the way to it per frame: within a minute.
const BACK_PER_FRAME: f32 = 0.05;
/// A pulse beyond this many times the RMS of the recent pulses is no
/// reaction to noise.
const OUTLIER_RMS: f32 = 4.0;
/// The share earned before a calibration holds after it while the guide
/// frames come at most this many times as far apart as before: a loop
/// whose frames come further apart leaves more of the error to each pulse.
const CARRY_INTERVAL: f32 = 1.5;
/// Bounds of the saved statistics (arcsec^2): far beyond any pulse a
/// guider sends, inside what the running means take in `f32`.
const MAX_SAVED_SQUARE: f32 = 1e6;

/// How the share earned before a calibration is carried to guide frames
/// more than 1.5 times as far apart as before it (`CARRY_INTERVAL`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LongerFrames {
    /// Full pulses, the share earned again.
    EarnAgain,
    /// The share scaled by the square root of the intervals' ratio, and
    /// earned on from there.
    Scale,
}

/// The measured share of the RA guide pulses to carry out.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EarnedShare {
    /// The configured least share; 1: every pulse in full.
    least: f32,
    stats: Statistics,
    /// The statistics before the first of the pulses beyond the bound
    /// since the last plain one: a calibration's first steps look like
    /// that until it is recognised ([`EarnedShare::calibrating`]).
    before_run: Option<Statistics>,
    /// A calibration was recognised: the first guide frame after it
    /// decides whether the share earned before it holds, and how it is
    /// carried to frames further apart.
    after_calibration: Option<LongerFrames>,
    /// The pulses of the previous two frames, while those were guide
    /// frames.
    previous: Option<f32>,
    before_previous: Option<f32>,
    /// The last pulse beyond its bound, while no pulse within it followed.
    last_beyond: Option<f32>,
    /// The share was carried to longer frames across a calibration
    /// ([`LongerFrames::Scale`]): earned on from the new frames' first
    /// pulses, where a share not yet measured is full.
    carried: bool,
    /// A share restored with the model, returned to while the pulses are
    /// anti-correlated.
    restored: Option<f32>,
}

/// The share and the pulse statistics it is earned from.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Statistics {
    fraction: f32,
    /// Running means of the pulse squared and of the products of pulses
    /// one and two frames apart, arcsec^2.
    square: f32,
    lagged: f32,
    lagged_two: f32,
    /// Running mean of the intervals between them, s.
    interval_s: f32,
    /// Pulses taken in, up to the window.
    scored: u32,
}

impl Statistics {
    const NONE: Statistics = Statistics {
        fraction: 1.0,
        square: 0.0,
        lagged: 0.0,
        lagged_two: 0.0,
        interval_s: 0.0,
        scored: 0,
    };
}

/// The earned share and the pulse weight as saved with the model: [`SAVED_LEN`]
/// bytes, little-endian: the share, the mean square of the pulses, the
/// mean product of neighbouring ones and the pulse weight
/// (`super::pulse_weight`; `f32` each), and the CRC-32 of those 16 bytes.
/// A share that has measured nothing yet saves share 1 and zeros:
/// nothing to restore.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SavedShare {
    fraction: f32,
    square: f32,
    lagged: f32,
    weight: f32,
}

/// Bytes of a [`SavedShare`].
pub const SAVED_LEN: usize = 20;

impl SavedShare {
    /// Checks everything before anything is used: length, checksum, and
    /// each value finite and in range (a share in (0, 1], a mean square
    /// >= 0, a weight in [`LEAST`]..=1).
    pub fn parse(bytes: &[u8]) -> Result<Self, SnapshotError> {
        if bytes.len() != SAVED_LEN {
            return Err(SnapshotError::Length {
                expected: SAVED_LEN,
                found: bytes.len(),
            });
        }
        let word = |k: usize| {
            let mut w = [0u8; 4];
            w.copy_from_slice(bytes.get(4 * k..4 * k + 4).unwrap_or(&[0; 4]));
            w
        };
        if crc32(bytes.get(..16).unwrap_or(&[])) != u32::from_le_bytes(word(4)) {
            return Err(SnapshotError::Checksum);
        }
        let [fraction, square, lagged, weight] = [0, 1, 2, 3].map(|k| f32::from_le_bytes(word(k)));
        let ok = fraction > 0.0
            && fraction <= 1.0
            && (0.0..=MAX_SAVED_SQUARE).contains(&square)
            && lagged.abs() <= MAX_SAVED_SQUARE
            && (LEAST..=1.0).contains(&weight);
        if !ok {
            return Err(SnapshotError::Invalid(Field::PulseShare));
        }
        Ok(SavedShare {
            fraction,
            square,
            lagged,
            weight,
        })
    }

    /// The same with the pulse weight `weight`.
    pub fn with_weight(self, weight: f32) -> Self {
        SavedShare { weight, ..self }
    }

    pub fn weight(&self) -> f32 {
        self.weight
    }

    /// The bytes [`parse`](Self::parse) reads.
    pub fn to_bytes(&self) -> [u8; SAVED_LEN] {
        let mut out = [0u8; SAVED_LEN];
        let words = [self.fraction, self.square, self.lagged, self.weight].map(f32::to_le_bytes);
        for (chunk, w) in out.chunks_exact_mut(4).zip(words) {
            chunk.copy_from_slice(&w);
        }
        let crc = crc32(out.get(..16).unwrap_or(&[])).to_le_bytes();
        if let Some(tail) = out.get_mut(16..) {
            tail.copy_from_slice(&crc);
        }
        out
    }
}

impl EarnedShare {
    /// `least`: the least share
    /// ([`MountConfig::least_pulse_share`](crate::mount::config::MountConfig::least_pulse_share)).
    pub const fn new(least: f32) -> Self {
        EarnedShare {
            least,
            stats: Statistics::NONE,
            before_run: None,
            after_calibration: None,
            previous: None,
            before_previous: None,
            last_beyond: None,
            carried: false,
            restored: None,
        }
    }

    /// What to save with the model: the share and its statistics once
    /// measured, else nothing earned; the pulse weight 1 (the learner's
    /// [`SavedShare::with_weight`]).
    pub fn saved(&self) -> SavedShare {
        if !self.measured() {
            return SavedShare {
                fraction: 1.0,
                square: 0.0,
                lagged: 0.0,
                weight: 1.0,
            };
        }
        SavedShare {
            fraction: self.stats.fraction,
            square: self.stats.square,
            lagged: self.stats.lagged,
            weight: 1.0,
        }
    }

    /// After a power cycle, the model restored: start from a saved share
    /// (`None`: none saved, earn it again), the statistics going on from the
    /// saved ones. Used only on frames the restored model is trusted (full
    /// pulses before); after a rise (an untrusted frame, correlated
    /// pulses) the share returns to it within a
    /// minute once the pulses are anti-correlated again.
    pub fn restore(&mut self, s: SavedShare) {
        self.reset();
        if !(s.square > 0.0) {
            return;
        }
        self.stats.square = s.square;
        self.stats.lagged = s.lagged;
        self.stats.scored = WINDOW_FRAMES;
        self.stats.fraction = s.fraction;
        self.restored = (s.fraction < 1.0).then_some(s.fraction);
    }

    /// Forget the statistics (the model was reset): full pulses.
    pub fn reset(&mut self) {
        *self = Self::new(self.least);
    }

    /// One frame: `pulse` the correction its RA pulse asked for (arcsec, 0
    /// for a frame the guider sent none), `None` for a frame that is no
    /// plain guide frame; `interval_s` the time since the frame before;
    /// `trusted`: the model's feed-forward is in full effect. Returns the
    /// share for the pulses to come.
    pub fn frame(&mut self, pulse: Option<f32>, interval_s: f32, trusted: bool) -> PulseShare {
        let Some(u) = pulse.filter(|u| u.is_finite()) else {
            self.previous = None;
            self.before_previous = None;
            self.last_beyond = None;
            return PulseShare::FULL;
        };
        if let Some(longer) = self.after_calibration.take() {
            self.carry_to(interval_s, longer);
        }
        let before = self.stats;
        self.stats.scored = self.stats.scored.saturating_add(1);
        let w = self.stats.scored.min(WINDOW_FRAMES) as f32;
        if interval_s.is_finite() {
            // A share restored across a power cycle has no interval yet:
            // the first one starts the mean.
            let w = if self.stats.interval_s > 0.0 { w } else { 1.0 };
            self.stats.interval_s += (interval_s - self.stats.interval_s) / w;
        }
        self.stats.square += (u * u - self.stats.square) / w;
        let previous = self.previous.replace(u);
        if let Some(p) = previous {
            self.stats.lagged += (u * p - self.stats.lagged) / w;
        }
        if let Some(p) = self.before_previous {
            self.stats.lagged_two += (u * p - self.stats.lagged_two) / w;
        }
        self.before_previous = previous;
        let bound = self.outlier_bound();
        let measured = self.measured();
        // Two pulses in a row beyond the bound (frames without a pulse
        // between them), the same way: an error the loop follows (a
        // calibration's steps, a bump). One alone, or one answered the
        // other way (a guider that overcorrects), leaves the share as it
        // is: the fast part carries such a pulse out in full.
        let beyond = u.abs() > bound;
        let step = beyond && self.last_beyond.is_some_and(|b| b * u > 0.0);
        if beyond {
            self.last_beyond = Some(u);
            self.before_run.get_or_insert(before);
        } else if u != 0.0 {
            self.last_beyond = None;
            self.before_run = None;
        }
        self.carried &= !measured;
        if self.least >= 1.0 || !trusted || step || !(measured || self.carried) {
            self.stats.fraction = 1.0;
            self.carried = false;
        } else if !beyond {
            let correlation = clamp(self.stats.lagged / self.stats.square, -1.0, 1.0);
            let mut f = self.stats.fraction * (1.0 + RATE * correlation);
            if let Some(share) = self.restored.filter(|&s| s < f && correlation < 0.0) {
                f -= BACK_PER_FRAME * (f - share);
            }
            self.stats.fraction = clamp(f, self.least, 1.0);
        }
        if self.stats.fraction >= 1.0 || !self.stats.fraction.is_finite() {
            self.stats.fraction = 1.0;
            return PulseShare::FULL;
        }
        PulseShare {
            fraction: self.stats.fraction,
            up_to_arcsec: bound,
        }
    }

    /// The guider is calibrating: the pulses beyond the bound since the
    /// last plain one were its first steps, no guide pulses. The share and
    /// the statistics go back to what they were before them (a step's full
    /// pulses too), so that guiding after the calibration goes on with the
    /// share earned before it.
    pub fn calibrating(&mut self, longer: LongerFrames) {
        if let Some(before) = self.before_run.take() {
            self.stats = before;
        }
        self.after_calibration = Some(longer);
    }

    /// The first guide frame after a calibration, `interval_s` after the
    /// frame before: guide frames at most [`CARRY_INTERVAL`] times as far
    /// apart as before keep the share; further apart, `longer` says how
    /// it is carried to them.
    fn carry_to(&mut self, interval_s: f32, longer: LongerFrames) {
        let ratio = interval_s / self.stats.interval_s;
        if ratio <= CARRY_INTERVAL {
            return;
        }
        match longer {
            LongerFrames::Scale if ratio.is_finite() && self.measured() => {
                // The gain that weighs a walking error against white noise
                // (a Kalman filter's, the walk small beside the noise)
                // grows as the walk per frame's RMS, the square root of
                // the interval. The statistics start again: the pulses
                // before were another loop's.
                let fraction = (self.stats.fraction * libm::sqrtf(ratio)).min(1.0);
                self.stats = Statistics {
                    fraction,
                    ..Statistics::NONE
                };
                self.carried = true;
            }
            _ => {
                self.stats = Statistics::NONE;
                self.carried = false;
            }
        }
    }

    /// A window of pulses scored, not all of them 0.
    fn measured(&self) -> bool {
        self.stats.scored >= WINDOW_FRAMES && self.stats.square > 0.0
    }

    /// [`OUTLIER_RMS`] times the RMS of the recent pulses, arcsec.
    fn outlier_bound(&self) -> f32 {
        OUTLIER_RMS * libm::sqrtf(self.stats.square)
    }

    /// 4 RMS of the recent pulses (arcsec), once measured.
    pub fn bound(&self) -> Option<f32> {
        self.measured().then(|| self.outlier_bound())
    }

    /// The measured correlation of pulses two frames apart (0 until
    /// measured): well below 0, the loop swings (`super::pulse_weight`).
    pub fn swing(&self) -> f32 {
        if !self.measured() {
            return 0.0;
        }
        clamp(self.stats.lagged_two / self.stats.square, -1.0, 1.0)
    }

    /// The share now, 1 when none is earned.
    pub fn fraction(&self) -> f32 {
        self.stats.fraction
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::Gaussian;

    /// A loop of gain 0.7 carrying out the share it is given, on white
    /// noise of 1 arcsec and an error that walks by `walk` arcsec per
    /// frame: the mean share over frames 1000 to 3000.
    fn mean_share(walk: f64, trusted: bool) -> f64 {
        let mut d = EarnedShare::new(0.2);
        let mut noise = Gaussian::new(3);
        let (mut error, mut sum) = (0.0f64, 0.0);
        for k in 0..3_000 {
            let pulse = 0.7 * (error + noise.next());
            let share = d.frame(Some(pulse as f32), 1.0, trusted);
            error += walk * noise.next() - share.fraction as f64 * pulse;
            if k >= 1_000 {
                sum += share.fraction as f64;
            }
        }
        sum / 2_000.0
    }

    #[test]
    fn noise_alone_earns_a_small_share_and_an_error_keeps_full_pulses() {
        assert_eq!(mean_share(0.0, false), 1.0);
        let noise_only = mean_share(0.0, true);
        assert!(noise_only < 0.35, "{noise_only}");
        // An error walking by 1 arcsec a frame is no noise to ignore.
        let walking = mean_share(1.0, true);
        assert!(walking > 0.8, "{walking}");
    }

    #[test]
    fn a_swing_of_four_frames_reads_below_the_bound_and_noise_does_not() {
        use crate::mount::guiding::pulse_weight::SWING;
        // A loop reacting to noise alone, at every share it earns.
        let mut d = EarnedShare::new(0.2);
        let mut noise = Gaussian::new(7);
        let mut error = 0.0f64;
        let mut least = f32::INFINITY;
        for k in 0..3_000 {
            let pulse = 0.7 * (error + noise.next());
            let share = d.frame(Some(pulse as f32), 1.0, true);
            error -= share.fraction as f64 * pulse;
            if k >= WINDOW_FRAMES {
                least = least.min(d.swing());
            }
        }
        assert!(least > SWING, "{least}");
        // Four frames a period under the same noise.
        let mut d = EarnedShare::new(0.2);
        for k in 0..200 {
            let swing = [3.0, 3.0, -3.0, -3.0][k % 4];
            d.frame(Some((swing + noise.next()) as f32), 1.0, true);
        }
        assert!(d.swing() < -0.7, "{}", d.swing());
    }

    /// Noise alone, anti-correlated pulses, until a share is earned.
    fn earned(d: &mut EarnedShare) {
        let mut noise = Gaussian::new(5);
        for _ in 0..1_000 {
            let u = noise.next() as f32;
            d.frame(Some(u), 1.0, true);
            d.frame(Some(-u), 1.0, true);
        }
    }

    #[test]
    fn a_saved_share_comes_back_only_behind_a_trusted_model() {
        let mut d = EarnedShare::new(0.2);
        earned(&mut d);
        let saved = d.saved();
        assert!(saved.fraction < 0.5, "{saved:?}");
        let back = SavedShare::parse(&saved.to_bytes()).unwrap();
        assert_eq!(back, saved);
        // Not trusted: full pulses, and the share once trusted again.
        let mut r = EarnedShare::new(0.2);
        r.restore(back);
        assert_eq!(r.frame(Some(0.1), 1.0, false), PulseShare::FULL);
        let mut share = 1.0;
        for k in 0..60 {
            let u = if k % 2 == 0 { 0.1 } else { -0.1 };
            share = r.frame(Some(u), 1.0, true).fraction;
        }
        assert!(share < 0.5, "{share}");
        // Trusted from the start: the saved share at once.
        let mut r = EarnedShare::new(0.2);
        r.restore(back);
        let share = r.frame(Some(0.1), 1.0, true).fraction;
        assert!((share - saved.fraction).abs() < 0.05, "{share}");
        // Nothing measured, nothing saved: earned again.
        let fresh = EarnedShare::new(0.2).saved();
        r.restore(fresh);
        assert_eq!(r.frame(Some(0.1), 1.0, true), PulseShare::FULL);
    }

    #[test]
    fn a_cut_or_garbled_saved_share_is_refused() {
        let mut d = EarnedShare::new(0.2);
        earned(&mut d);
        let bytes = d.saved().to_bytes();
        assert_eq!(
            SavedShare::parse(&bytes[..SAVED_LEN - 1]),
            Err(SnapshotError::Length {
                expected: SAVED_LEN,
                found: SAVED_LEN - 1
            })
        );
        for i in 0..SAVED_LEN {
            let mut garbled = bytes;
            garbled[i] ^= 0x10;
            assert_eq!(SavedShare::parse(&garbled), Err(SnapshotError::Checksum));
        }
        // A share or a weight out of range with a matching checksum: a
        // writer's bug.
        for fraction in [0.0, 1.5, f32::NAN] {
            let bad = SavedShare {
                fraction,
                ..d.saved()
            };
            assert_eq!(
                SavedShare::parse(&bad.to_bytes()),
                Err(SnapshotError::Invalid(Field::PulseShare))
            );
        }
        for weight in [0.0, LEAST - 0.01, 1.01, f32::NAN] {
            assert_eq!(
                SavedShare::parse(&d.saved().with_weight(weight).to_bytes()),
                Err(SnapshotError::Invalid(Field::PulseShare))
            );
        }
    }

    #[test]
    fn a_calibrations_first_steps_leave_the_share_earned_before_it() {
        let calibrated = |interval_after: f32, longer: LongerFrames| {
            let mut d = EarnedShare::new(0.2);
            earned(&mut d);
            let share = d.frame(Some(0.1), 1.0, true);
            assert!(share.fraction < 0.5, "{share:?}");
            // Two equal steps beyond the bound, taken for guide pulses
            // until the third makes them a calibration: full pulses.
            d.frame(Some(20.0), 1.0, true);
            assert_eq!(d.frame(Some(20.0), 1.0, true), PulseShare::FULL);
            d.calibrating(longer);
            assert_eq!(d.frame(None, 1.0, true), PulseShare::FULL);
            d.calibrating(longer);
            (share, d.frame(Some(0.1), interval_after, true))
        };
        // Guiding goes on at the cadence before: the share earned before,
        // as one more plain pulse leaves it.
        let (share, after) = calibrated(1.0, LongerFrames::Scale);
        assert!(
            (after.fraction - share.fraction).abs() < 0.01,
            "{share:?} {after:?}"
        );
        assert!((after.up_to_arcsec / share.up_to_arcsec - 1.0).abs() < 0.01);
        // Frames further apart: earned again.
        let (_, after) = calibrated(CARRY_INTERVAL * 1.1, LongerFrames::EarnAgain);
        assert_eq!(after, PulseShare::FULL);
        // Or scaled by the square root of the intervals' ratio, the
        // statistics started again from the new frame (its bound 4 times
        // its pulse).
        let (share, after) = calibrated(4.0, LongerFrames::Scale);
        assert!(
            (after.fraction - 2.0 * share.fraction).abs() < 1e-6,
            "{share:?} {after:?}"
        );
        assert!((after.up_to_arcsec - 0.4).abs() < 1e-6, "{after:?}");
        // Earned on from there: anti-correlated pulses lower it at once.
        let mut d = EarnedShare::new(0.2);
        earned(&mut d);
        d.calibrating(LongerFrames::Scale);
        let first = d.frame(Some(0.1), 4.0, true).fraction;
        let mut next = first;
        for k in 0..10 {
            next = d
                .frame(Some(if k % 2 == 0 { -0.1 } else { 0.1 }), 4.0, true)
                .fraction;
        }
        assert!(first < 1.0 && next < first, "{first} {next}");
        // A plain pulse between the steps and the calibration: they were
        // guide pulses, and stay.
        let mut d = EarnedShare::new(0.2);
        earned(&mut d);
        d.frame(Some(20.0), 1.0, true);
        d.frame(Some(20.0), 1.0, true);
        d.frame(Some(0.1), 1.0, true);
        d.calibrating(LongerFrames::EarnAgain);
        assert_eq!(d.frame(Some(0.1), 1.0, true), PulseShare::FULL);
    }

    #[test]
    fn pulses_beyond_the_recent_ones_bring_full_pulses_only_twice_the_same_way() {
        let mut d = EarnedShare::new(0.2);
        let mut noise = Gaussian::new(4);
        for _ in 0..1_000 {
            // Anti-correlated pulses: a loop reacting to noise.
            let u = noise.next() as f32;
            d.frame(Some(u), 1.0, true);
            d.frame(Some(-u), 1.0, true);
        }
        let share = d.frame(Some(0.1), 1.0, true);
        assert!(share.fraction < 0.5, "{share:?}");
        assert!(share.up_to_arcsec > 0.0);
        // One alone, or answered the other way (an overcorrection): the
        // fast part carries it out in full, the share stays.
        let beyond = d.frame(Some(10.0), 1.0, true);
        assert!(10.0 > beyond.up_to_arcsec, "{beyond:?}");
        assert_eq!(beyond.fraction, share.fraction);
        let answered = d.frame(Some(-12.0), 1.0, true);
        assert!(12.0 > answered.up_to_arcsec, "{answered:?}");
        assert_eq!(answered.fraction, share.fraction);
        // Twice the same way, frames without a pulse between: an error to
        // follow, full pulses.
        d.frame(Some(0.0), 1.0, true);
        assert_eq!(d.frame(Some(-14.0), 1.0, true), PulseShare::FULL);
        // A dither's frame and a non-finite pulse: full pulses.
        d.frame(Some(0.1), 1.0, true);
        assert_eq!(d.frame(None, 1.0, true), PulseShare::FULL);
        assert_eq!(d.frame(Some(f32::NAN), 1.0, true), PulseShare::FULL);
        // Switched off.
        let mut off = EarnedShare::new(1.0);
        for k in 0..500 {
            let u = if k % 2 == 0 { 1.0 } else { -1.0 };
            assert_eq!(off.frame(Some(u), 1.0, true), PulseShare::FULL);
        }
    }
}
