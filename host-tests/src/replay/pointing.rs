//! Gear time from where the mount pointed. Every gear of the RA train
//! turns with the RA axis, and on one side of the pier the axis turns with
//! the hour angle: tracking turns it one hour per hour of sidereal time, a
//! slew to another target by minus the change of right ascension. So from
//! one section to the next, gear time moves by the clock plus
//! -(change of RA) in gear seconds: PHD2 resumes its predictive guider
//! with that shift.

use crate::phd2_log::Section;

/// Gear seconds per hour of RA: the axis turns once per sidereal day,
/// 86,164.09 s.
pub const GEAR_S_PER_HOUR: f64 = 86_164.090_5 / 24.0;
/// Sidereal hours per hour of the clock.
pub const SIDEREAL_PER_SOLAR: f64 = 1.002_737_909;
/// The change of RA within which two sections point at the same target,
/// hours: PHD2 writes RA and the hour angle to 0.01 h, and the clock of a
/// section's begin to the second.
pub const SAME_TARGET_HR: f64 = 0.015;
/// The sidereal rate, arcsec per second of time.
pub const SIDEREAL_ARCSEC_PER_S: f64 = 15.041;
/// The rate PHD2 gives guide speeds relative to, arcsec per second.
const PHD2_SIDEREAL_ARCSEC_PER_S: f64 = 15.0;

/// How far gear time moved beyond the clock from the begin of `a` to the
/// begin of `b`, seconds: 0 on the same target, minus the change of RA
/// after a slew; `None` where the headers do not say (no RA nor hour
/// angle in one of them), or the pier side changed (a meridian flip turns
/// the axis half a turn, in a sense the log does not give).
pub fn gear_shift_s(a: &Section, b: &Section) -> Option<f64> {
    if pier_flip(a, b) {
        return None;
    }
    let (pa, pb) = (&a.header.pointing, &b.header.pointing);
    let ra_change_hr = match (pa.ra_hr, pb.ra_hr, pa.hour_angle_hr, pb.hour_angle_hr) {
        (Some(ra_a), Some(ra_b), _, _) => ra_b - ra_a,
        (_, _, Some(ha_a), Some(ha_b)) => {
            let sidereal_hr = (b.start_s - a.start_s) / 3600.0 * SIDEREAL_PER_SOLAR;
            sidereal_hr - (ha_b - ha_a)
        }
        _ => return None,
    };
    // Across 0 h / 24 h, the shorter way.
    let ra_change_hr = (ra_change_hr + 12.0).rem_euclid(24.0) - 12.0;
    if ra_change_hr.abs() < SAME_TARGET_HR {
        Some(0.0)
    } else {
        Some(-ra_change_hr * GEAR_S_PER_HOUR)
    }
}

/// Whether the telescope changed sides of the pier from `a` to `b`.
pub fn pier_flip(a: &Section, b: &Section) -> bool {
    let sides = (a.header.pointing.pier_side, b.header.pointing.pier_side);
    sides.0.zip(sides.1).is_some_and(|(x, y)| x != y)
}

/// The star's motion in RA per second of gear time, px/s: what a dither of
/// X px shifts gear time by X / rate. From the guide pulse's rate and the
/// guide speed (PHD2's own way), else from the pixel scale and the
/// declination.
pub fn sidereal_px_per_s(section: &Section) -> Option<f64> {
    let h = &section.header;
    let from_pulse = h
        .x_rate
        .zip(h.ra_guide_speed)
        .filter(|&(rate, speed)| rate > 0.0 && speed > 0.0)
        .map(|(rate, speed)| rate * PHD2_SIDEREAL_ARCSEC_PER_S / speed);
    let from_scale = || {
        h.pixel_scale
            .zip(h.pointing.dec_deg)
            .and_then(|(scale, dec)| {
                let rate = SIDEREAL_ARCSEC_PER_S * dec.to_radians().cos() / scale;
                (rate > 0.0).then_some(rate)
            })
    };
    from_pulse.or_else(from_scale)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::phd2_log::header::{Header, PierSide, Pointing};

    fn section(start_s: f64, pointing: Pointing) -> Section {
        Section {
            line: 1,
            rows_line: 1,
            start_s,
            exposure_s: 2.0,
            header: Header {
                pointing,
                ..Header::default()
            },
            frames: Vec::new(),
            events: Vec::new(),
        }
    }

    fn at(ra: Option<f64>, ha: Option<f64>, pier: PierSide) -> Pointing {
        Pointing {
            ra_hr: ra,
            dec_deg: Some(10.0),
            hour_angle_hr: ha,
            pier_side: Some(pier),
        }
    }

    #[test]
    fn the_same_target_keeps_the_clock() {
        // An hour later, the hour angle an hour and ten seconds on.
        let a = section(0.0, at(None, Some(-1.0), PierSide::West));
        let b = section(3600.0, at(None, Some(0.0027), PierSide::West));
        assert_eq!(gear_shift_s(&a, &b), Some(0.0));
        let a = section(0.0, at(Some(5.51), Some(-2.46), PierSide::West));
        let b = section(7200.0, at(Some(5.51), Some(-0.40), PierSide::West));
        assert_eq!(gear_shift_s(&a, &b), Some(0.0));
    }

    #[test]
    fn a_slew_shifts_gear_time_by_minus_the_change_of_ra() {
        let a = section(0.0, at(Some(5.51), Some(-2.46), PierSide::West));
        let b = section(600.0, at(Some(3.43), Some(-0.30), PierSide::West));
        let shift = gear_shift_s(&a, &b).unwrap();
        assert!((shift - 2.08 * GEAR_S_PER_HOUR).abs() < 1e-9, "{shift}");
        // From the hour angle alone: 10 min later, 2 h further west.
        let a = section(0.0, at(None, Some(-2.0), PierSide::West));
        let b = section(600.0, at(None, Some(0.1667), PierSide::West));
        let shift = gear_shift_s(&a, &b).unwrap();
        let want = (2.1667 - 600.0 / 3600.0 * SIDEREAL_PER_SOLAR) * GEAR_S_PER_HOUR;
        assert!((shift - want).abs() < 1e-6, "{shift} vs {want}");
        // Across 0 h.
        let a = section(0.0, at(Some(23.9), None, PierSide::East));
        let b = section(60.0, at(Some(0.1), None, PierSide::East));
        let shift = gear_shift_s(&a, &b).unwrap();
        assert!((shift + 0.2 * GEAR_S_PER_HOUR).abs() < 1e-6, "{shift}");
    }

    #[test]
    fn a_flip_or_no_pointing_is_unknown() {
        let a = section(0.0, at(Some(5.0), Some(-0.1), PierSide::West));
        let b = section(600.0, at(Some(5.0), Some(0.07), PierSide::East));
        assert_eq!(gear_shift_s(&a, &b), None);
        let c = section(600.0, Pointing::default());
        assert_eq!(gear_shift_s(&a, &c), None);
    }

    #[test]
    fn the_sidereal_rate_in_px() {
        let mut s = section(0.0, at(None, None, PierSide::West));
        s.header.x_rate = Some(2.378);
        s.header.ra_guide_speed = Some(7.5);
        let rate = sidereal_px_per_s(&s).unwrap();
        assert!((rate - 4.756).abs() < 1e-12, "{rate}");
        s.header.ra_guide_speed = None;
        s.header.pixel_scale = Some(3.0);
        let rate = sidereal_px_per_s(&s).unwrap();
        assert!((rate - 15.041 * 10f64.to_radians().cos() / 3.0).abs() < 1e-12);
        s.header.pixel_scale = None;
        assert_eq!(sidereal_px_per_s(&s), None);
    }
}
