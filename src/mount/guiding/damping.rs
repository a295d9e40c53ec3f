//! How much of the guider's RA pulses the firmware carries out, earned by
//! measurement (docs/decisions.md, "Pulse damping").
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
//! Full pulses at once: while the model is not trusted in full, for a
//! frame that is not a plain guide frame (a dither and its settling, the
//! guider silent), and for a pulse far beyond the recent ones (the error is
//! not explained: a bump, a calibration step). The fast part carries out
//! in full any pulse longer than [`PulseShare::up_to_arcsec`] and makes up
//! what it held back (`super::share`).

use crate::model::numeric::clamp;
use crate::mount::frame::PulseShare;

/// Frames the pulse statistics average over (about two minutes at 2 s):
/// the correlation's spread is about 1 / sqrt(frames).
const WINDOW_FRAMES: u32 = 64;
/// Relative change of the share per frame and unit of correlation: from
/// full to a third in about 100 frames of noise alone.
const RATE: f32 = 0.05;
/// A pulse beyond this many times the RMS of the recent pulses is no
/// reaction to noise.
const OUTLIER_RMS: f32 = 4.0;

/// The measured share of the RA guide pulses to carry out.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Damping {
    /// The configured least share; 1 switches damping off.
    least: f32,
    fraction: f32,
    /// Running means of the pulse squared and of the product of
    /// neighbouring pulses, arcsec^2.
    square: f32,
    lagged: f32,
    /// The previous frame's pulse, if that frame was a guide frame.
    previous: Option<f32>,
    scored: u32,
}

impl Damping {
    /// `least`: the least share ([`MountConfig::least_pulse_share`]
    /// (crate::mount::config::MountConfig::least_pulse_share)).
    pub const fn new(least: f32) -> Self {
        Damping {
            least,
            fraction: 1.0,
            square: 0.0,
            lagged: 0.0,
            previous: None,
            scored: 0,
        }
    }

    /// Forget the statistics (the model was reset): full pulses.
    pub fn reset(&mut self) {
        *self = Self::new(self.least);
    }

    /// One frame: `pulse` the correction its RA pulse asked for (arcsec, 0
    /// for a frame the guider sent none), `None` for a frame that is no
    /// plain guide frame; `trusted`: the model's feed-forward is in full
    /// effect. Returns the share for the pulses to come.
    pub fn frame(&mut self, pulse: Option<f32>, trusted: bool) -> PulseShare {
        let Some(u) = pulse.filter(|u| u.is_finite()) else {
            self.previous = None;
            return PulseShare::FULL;
        };
        self.scored = self.scored.saturating_add(1);
        let w = self.scored.min(WINDOW_FRAMES) as f32;
        self.square += (u * u - self.square) / w;
        if let Some(p) = self.previous {
            self.lagged += (u * p - self.lagged) / w;
        }
        self.previous = Some(u);
        let bound = OUTLIER_RMS * libm::sqrtf(self.square);
        let measured = self.scored >= WINDOW_FRAMES && self.square > 0.0;
        if self.least >= 1.0 || !trusted || !measured || u.abs() > bound {
            self.fraction = 1.0;
        } else {
            let correlation = clamp(self.lagged / self.square, -1.0, 1.0);
            self.fraction = clamp(self.fraction * (1.0 + RATE * correlation), self.least, 1.0);
        }
        if self.fraction >= 1.0 || !self.fraction.is_finite() {
            self.fraction = 1.0;
            return PulseShare::FULL;
        }
        PulseShare {
            fraction: self.fraction,
            up_to_arcsec: bound,
        }
    }

    /// The share now, 1 when none is earned.
    pub fn fraction(&self) -> f32 {
        self.fraction
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
        let mut d = Damping::new(0.2);
        let mut noise = Gaussian::new(3);
        let (mut error, mut sum) = (0.0f64, 0.0);
        for k in 0..3_000 {
            let pulse = 0.7 * (error + noise.next());
            let share = d.frame(Some(pulse as f32), trusted);
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
    fn a_pulse_beyond_the_recent_ones_brings_full_pulses_at_once() {
        let mut d = Damping::new(0.2);
        let mut noise = Gaussian::new(4);
        for _ in 0..1_000 {
            // Anti-correlated pulses: a loop reacting to noise.
            let u = noise.next() as f32;
            d.frame(Some(u), true);
            d.frame(Some(-u), true);
        }
        let share = d.frame(Some(0.1), true);
        assert!(share.fraction < 0.5, "{share:?}");
        assert!(share.up_to_arcsec > 0.0);
        assert_eq!(d.frame(Some(10.0), true), PulseShare::FULL);
        // A dither's frame and a non-finite pulse: full pulses.
        d.frame(Some(0.1), true);
        assert_eq!(d.frame(None, true), PulseShare::FULL);
        assert_eq!(d.frame(Some(f32::NAN), true), PulseShare::FULL);
        // Switched off.
        let mut off = Damping::new(1.0);
        for k in 0..500 {
            let u = if k % 2 == 0 { 1.0 } else { -1.0 };
            assert_eq!(off.frame(Some(u), true), PulseShare::FULL);
        }
    }
}
