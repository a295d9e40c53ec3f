//! What a PHD2 guide log can hold. A value beyond these limits was not
//! measured on a guiding run: the log is corrupt or hand-made, and the
//! parser refuses it (`file:line: what`) rather than let the replay turn it
//! into absurd figures.

use super::search_region::MAX_STAR_STEP_PX;
use crate::data::parse_f64;

/// The farthest a star can be from the lock position, and the largest
/// dither, px. Both lie within the guide camera's frame, which is a few
/// thousand px across at most (the five logs' cameras: 376 x 279 to
/// 1280 x 960 px; the largest guide sensors about 4,000 px).
pub const MAX_DISTANCE_PX: f64 = 10_000.0;

/// The longest guide exposure, s. PHD2's exposure menu ends at 15 s; an
/// exposure of minutes no longer guides (the gear's error changes within a
/// worm period of a few minutes).
pub const MAX_EXPOSURE_S: f64 = 300.0;

/// The latest frame time of a guiding section, s. `Time` counts from the
/// start of guiding, and guiding lasts a night at most: a week is beyond
/// any.
pub const MAX_TIME_S: f64 = 7.0 * 86_400.0;

/// A distance or dither amount (px) within [`MAX_DISTANCE_PX`] either way.
pub fn distance(field: &str, column: &str) -> Result<f64, String> {
    let px = parse_f64(field, column)?;
    if px.abs() <= MAX_DISTANCE_PX {
        Ok(px)
    } else {
        Err(format!(
            "{column}: {} px is beyond {MAX_DISTANCE_PX} px either way, more than any guide camera's frame",
            field.trim()
        ))
    }
}

/// A frame time (s) from 0 to [`MAX_TIME_S`].
pub fn time(field: &str, column: &str) -> Result<f64, String> {
    let s = parse_f64(field, column)?;
    if (0.0..=MAX_TIME_S).contains(&s) {
        Ok(s)
    } else {
        Err(format!(
            "{column}: {} s is outside 0 to {MAX_TIME_S} s (a week) since guiding began",
            field.trim()
        ))
    }
}

/// `Exposure = N ms`, with 0 < N ms <= [`MAX_EXPOSURE_S`], in seconds.
pub fn exposure_s(rest: &str) -> Result<f64, String> {
    let value = rest.trim().strip_suffix("ms").map(str::trim);
    match value.map(|v| parse_f64(v, "Exposure")) {
        Some(Ok(ms)) if ms > 0.0 && ms <= MAX_EXPOSURE_S * 1000.0 => Ok(ms / 1000.0),
        _ => Err(format!(
            "Exposure: {:?} is not `N ms` with 0 < N <= {} (a guide exposure of {MAX_EXPOSURE_S} s at most)",
            rest.trim(),
            MAX_EXPOSURE_S * 1000.0
        )),
    }
}

/// The coarsest guide-camera pixel scale, arcsec per px: a degree (the
/// widest guide cameras on a finder give about 20"/px).
pub const MAX_PIXEL_SCALE: f64 = 3600.0;
/// The fastest guide pulse, px of correction per second of pulse (the
/// header's `xRate`): ten times sidereal at 0.01"/px is about 15,000.
pub const MAX_X_RATE: f64 = 15_000.0;
/// The fastest guide speed, arcsec per second: ten times sidereal.
pub const MAX_GUIDE_SPEED: f64 = 150.0;
/// The longest guide pulse a setting can ask for, ms: an hour.
pub const MAX_PULSE_MS: f64 = 3_600_000.0;

/// `value` if within `lo..=hi` (`unit` names it in the error).
fn within(value: f64, name: &str, lo: f64, hi: f64, unit: &str) -> Result<f64, String> {
    if (lo..=hi).contains(&value) {
        Ok(value)
    } else {
        Err(format!("{name}: {value} is outside {lo} to {hi}{unit}"))
    }
}

/// A pixel scale (arcsec/px), above 0 and at most [`MAX_PIXEL_SCALE`].
pub fn pixel_scale(value: f64, name: &str) -> Result<f64, String> {
    if value <= 0.0 {
        return Err(format!("{name}: {value} arcsec/px is no pixel scale"));
    }
    within(value, name, 0.0, MAX_PIXEL_SCALE, " arcsec/px")
}

/// The mount line's `xRate` (px/s), at most [`MAX_X_RATE`].
pub fn x_rate(value: f64, name: &str) -> Result<f64, String> {
    within(value, name, 0.0, MAX_X_RATE, " px/s")
}

/// A guide speed (arcsec/s), at most [`MAX_GUIDE_SPEED`].
pub fn guide_speed(value: f64, name: &str) -> Result<f64, String> {
    within(value, name, 0.0, MAX_GUIDE_SPEED, " arcsec/s")
}

/// A pulse duration (ms), at most [`MAX_PULSE_MS`].
pub fn pulse_ms(value: f64, name: &str) -> Result<f64, String> {
    within(value, name, 0.0, MAX_PULSE_MS, " ms")
}

/// A right ascension, hours.
pub fn right_ascension(value: f64, name: &str) -> Result<f64, String> {
    within(value, name, 0.0, 24.0, " hr")
}

/// A declination, degrees.
pub fn declination(value: f64, name: &str) -> Result<f64, String> {
    within(value, name, -90.0, 90.0, " deg")
}

/// An hour angle, hours (PHD2 writes -12 to 12; 0 to 24 is the same).
pub fn hour_angle(value: f64, name: &str) -> Result<f64, String> {
    within(value, name, -24.0, 24.0, " hr")
}

/// The correction the replay takes for a frame found at `ra_raw` px: its
/// RAGuideDistance plus the dithers before it (`correction` px). A guide
/// algorithm corrects the error it measured, plus at most what it predicts
/// the gear to move over one frame, which is less than the star can move
/// between frames ([`MAX_STAR_STEP_PX`]; in the five logs it is within
/// 3 px of the error). A larger one was not what moved the mount.
pub fn correction(ra_raw: f64, correction: f64) -> Result<(), String> {
    if correction.abs() <= ra_raw.abs() + MAX_STAR_STEP_PX {
        Ok(())
    } else {
        Err(format!(
            "RAGuideDistance: a correction of {correction} px (with any dither before it) \
             for an error of {ra_raw} px: no guide algorithm corrects {MAX_STAR_STEP_PX:.1} px more than it measured"
        ))
    }
}

/// The frame times of one guiding section: each later than the one before,
/// as PHD2 writes them (a clock that runs back is no guiding run; the
/// guide algorithms would take it for the gear's time).
#[derive(Debug, Default, Clone, Copy)]
pub struct Clock {
    /// The last time and its line.
    last: Option<(f64, usize)>,
}

impl Clock {
    /// The frame at `line` is at `t` s.
    pub fn tick(&mut self, t: f64, line: usize) -> Result<(), String> {
        if let Some((last, at)) = self.last {
            if t <= last {
                return Err(format!(
                    "Time: {t} s is not after {last} s (line {at}): a section's clock runs forward"
                ));
            }
        }
        self.last = Some((t, line));
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distances_up_to_the_frame() {
        assert_eq!(distance("-10000", "d"), Ok(-MAX_DISTANCE_PX));
        assert_eq!(distance(" 10000.0 ", "d"), Ok(MAX_DISTANCE_PX));
        assert_eq!(
            distance("10000.001", "RARawDistance").unwrap_err(),
            "RARawDistance: 10000.001 px is beyond 10000 px either way, more than any guide camera's frame"
        );
        assert!(distance("-1e300", "d").is_err());
        assert!(distance("nan", "d")
            .unwrap_err()
            .contains("not a finite number"));
    }

    #[test]
    fn corrections_of_the_error_measured() {
        for (m, c) in [(0.0, MAX_STAR_STEP_PX), (-2.0, 2.0 + MAX_STAR_STEP_PX)] {
            assert_eq!(correction(m, c), Ok(()));
            assert_eq!(correction(m, -c), Ok(()));
            assert!(correction(m, c + 0.001).is_err());
        }
        assert_eq!(
            correction(0.25, -5000.0).unwrap_err(),
            "RAGuideDistance: a correction of -5000 px (with any dither before it) for an error \
             of 0.25 px: no guide algorithm corrects 70.7 px more than it measured"
        );
    }

    #[test]
    fn times_from_zero_to_a_week() {
        assert_eq!(time("0", "Time"), Ok(0.0));
        assert_eq!(time("604800", "Time"), Ok(MAX_TIME_S));
        assert_eq!(
            time("-0.001", "Time").unwrap_err(),
            "Time: -0.001 s is outside 0 to 604800 s (a week) since guiding began"
        );
        assert!(time("604800.001", "Time").is_err());
    }

    #[test]
    fn exposures_up_to_minutes() {
        assert_eq!(exposure_s(" 2000 ms"), Ok(2.0));
        assert_eq!(exposure_s("300000 ms"), Ok(MAX_EXPOSURE_S));
        for bad in [
            "300001 ms",
            "0 ms",
            "-5 ms",
            "1e300 ms",
            "2 s",
            "ms",
            "nan ms",
        ] {
            let e = exposure_s(bad).unwrap_err();
            assert!(e.starts_with("Exposure: "), "{bad}: {e}");
        }
    }

    #[test]
    fn clock_runs_forward() {
        let mut c = Clock::default();
        c.tick(2.25, 4).unwrap();
        c.tick(4.1, 5).unwrap();
        assert_eq!(
            c.tick(4.1, 7).unwrap_err(),
            "Time: 4.1 s is not after 4.1 s (line 5): a section's clock runs forward"
        );
        assert!(c.tick(3.0, 8).is_err());
        c.tick(4.2, 9).unwrap();
    }
}
