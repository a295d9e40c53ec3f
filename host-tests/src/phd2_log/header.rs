//! The header of a guiding section: the lines PHD2 writes after `Guiding
//! Begins at` and before the `Frame,Time,...` line, each `Name = value`
//! pairs separated by commas:
//!
//! ```text
//! Pixel scale = 3.22 arc-sec/px, Binning = 1, Focal length = 240 mm
//! Exposure = 2000 ms
//! Mount = EQMOD HEQ5/6,  connected, guiding enabled, xAngle = 174.5, xRate = 2.378, ...
//! X guide algorithm = Predictive PEC, Control gain = 0.600
//! Calibration step = ..., Max RA duration = 2500, Max DEC duration = 2500, ...
//! RA Guide Speed = 7.5 a-s/s, Dec Guide Speed = 7.5 a-s/s, ...
//! RA = 20.95 hr, Dec = 31.6 deg, Hour angle = -2.83 hr, Pier side = West, ...
//! ```
//!
//! (older PHD2 writes the pointing line without its `RA = ...`). A field
//! PHD2 could not know is written as `Unknown` or `N/A`, or left out: it is
//! `None` here. A number beyond what any mount or camera gives fails the
//! log ([`super::limits`]).

use super::limits;

/// The side of the pier the telescope is on (a German mount turns its RA
/// axis half a turn at a meridian flip).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PierSide {
    East,
    West,
}

/// Where the mount pointed when the section began.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Pointing {
    pub ra_hr: Option<f64>,
    pub dec_deg: Option<f64>,
    pub hour_angle_hr: Option<f64>,
    pub pier_side: Option<PierSide>,
}

/// What a guiding section's header says.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Header {
    /// `Exposure = N ms`, in seconds.
    pub exposure_s: Option<f64>,
    /// `Pixel scale`, arcsec per px.
    pub pixel_scale: Option<f64>,
    /// The mount line's `xRate`: px of RA correction per second of guide
    /// pulse.
    pub x_rate: Option<f64>,
    /// `Max RA duration`, ms: the longest RA pulse.
    pub max_ra_pulse_ms: Option<f64>,
    /// `RA Guide Speed`, arcsec per second.
    pub ra_guide_speed: Option<f64>,
    /// The name of `X guide algorithm` (RA), e.g. `Hysteresis` or
    /// `Predictive PEC`.
    pub ra_algorithm: Option<String>,
    pub pointing: Pointing,
}

/// PHD2's name of its predictive guide algorithm.
pub const PREDICTIVE_PEC: &str = "Predictive PEC";

impl Header {
    /// The header a section starts from: the equipment of the section
    /// before (a hand-made log may give it once), not its pointing.
    pub fn inherit(&self) -> Header {
        Header {
            pointing: Pointing::default(),
            ..self.clone()
        }
    }

    /// Read `line` if it is a header line of ours: `Ok(true)` if it was.
    pub fn read(&mut self, line: &str) -> Result<bool, String> {
        if let Some(rest) = line.strip_prefix("Exposure =") {
            self.exposure_s = Some(limits::exposure_s(rest)?);
        } else if line.starts_with("Pixel scale =") {
            self.pixel_scale = number(line, "Pixel scale", limits::pixel_scale)?;
        } else if line.starts_with("Mount =") {
            self.x_rate = number(line, "xRate", limits::x_rate)?;
        } else if let Some(rest) = line.strip_prefix("X guide algorithm =") {
            let name = rest.split(',').next().unwrap_or("").trim();
            self.ra_algorithm = (!name.is_empty()).then(|| name.to_string());
        } else if line.starts_with("RA Guide Speed =") {
            self.ra_guide_speed = number(line, "RA Guide Speed", limits::guide_speed)?;
        } else if line.starts_with("RA =") || line.starts_with("Dec =") {
            self.pointing = Pointing {
                ra_hr: number(line, "RA", limits::right_ascension)?,
                dec_deg: number(line, "Dec", limits::declination)?,
                hour_angle_hr: number(line, "Hour angle", limits::hour_angle)?,
                pier_side: match value(line, "Pier side") {
                    Some("East") => Some(PierSide::East),
                    Some("West") => Some(PierSide::West),
                    _ => None,
                },
            };
        } else {
            // Max RA duration shares a line with other settings, whose
            // start changed between PHD2 versions.
            if line.contains("Max RA duration =") {
                self.max_ra_pulse_ms = number(line, "Max RA duration", limits::pulse_ms)?;
                return Ok(true);
            }
            return Ok(false);
        }
        Ok(true)
    }

    /// Whether the section was guided on RA by PHD2's predictive guider.
    pub fn predictive(&self) -> bool {
        self.ra_algorithm.as_deref() == Some(PREDICTIVE_PEC)
    }
}

/// The value of `name = value` in a comma-separated header line.
fn value<'a>(line: &'a str, name: &str) -> Option<&'a str> {
    line.split(',').find_map(|part| {
        let (key, v) = part.split_once('=')?;
        (key.trim() == name).then(|| v.trim())
    })
}

/// The number `name = N unit` of `line`, checked by `limit`: `None` if the
/// line has no such field or PHD2 did not know it (a value that is no
/// number, such as `Unknown` or `N/A`).
fn number(
    line: &str,
    name: &str,
    limit: fn(f64, &str) -> Result<f64, String>,
) -> Result<Option<f64>, String> {
    let Some(v) = value(line, name) else {
        return Ok(None);
    };
    let token = v.split_whitespace().next().unwrap_or("");
    match token.parse::<f64>() {
        Ok(x) => limit(x, name).map(Some),
        Err(_) => Ok(None),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(lines: &[&str]) -> Result<Header, String> {
        let mut h = Header::default();
        for l in lines {
            assert!(h.read(l)?, "{l}");
        }
        Ok(h)
    }

    #[test]
    fn reads_the_fields_of_phd2_headers() {
        let h = read(&[
            "Pixel scale = 3.22 arc-sec/px, Binning = 1, Focal length = 240 mm",
            "Exposure = 2000 ms",
            "Mount = EQMOD HEQ5/6,  connected, guiding enabled, xAngle = 174.5, xRate = 2.378, \
             yAngle = 90.8, yRate = 2.227, parity = +/-,",
            "X guide algorithm = Predictive PEC, Control gain = 0.600",
            "Calibration step = phdlab_placeholder, Max RA duration = 2500, Max DEC duration = 2500",
            "RA Guide Speed = 7.5 a-s/s, Dec Guide Speed = 7.5 a-s/s, Cal Dec = 9.6",
            "Dec = -8.4 deg, Hour angle = -0.43 hr, Pier side = West, Rotator pos = N/A",
        ])
        .unwrap();
        assert_eq!(
            h,
            Header {
                exposure_s: Some(2.0),
                pixel_scale: Some(3.22),
                x_rate: Some(2.378),
                max_ra_pulse_ms: Some(2500.0),
                ra_guide_speed: Some(7.5),
                ra_algorithm: Some(PREDICTIVE_PEC.into()),
                pointing: Pointing {
                    ra_hr: None,
                    dec_deg: Some(-8.4),
                    hour_angle_hr: Some(-0.43),
                    pier_side: Some(PierSide::West),
                },
            }
        );
        assert!(h.predictive());
        let p = read(&[
            "RA = 20.95 hr, Dec = 31.6 deg, Hour angle = -2.83 hr, Pier side = East, \
             Rotator pos = N/A, Alt = 52.8 deg, Az = 107.8 deg",
        ])
        .unwrap()
        .pointing;
        assert_eq!(
            (p.ra_hr, p.dec_deg, p.hour_angle_hr, p.pier_side),
            (Some(20.95), Some(31.6), Some(-2.83), Some(PierSide::East))
        );
    }

    #[test]
    fn unknown_values_are_none() {
        let h = read(&[
            "RA Guide Speed = Unknown, Dec Guide Speed = Unknown",
            "Dec = Unknown, Hour angle = N/A, Pier side = Unknown",
            "Mount = Simulator, connected",
        ])
        .unwrap();
        assert_eq!(h, Header::default());
        let mut h = Header::default();
        assert!(!h
            .read("Norm rates RA = 7.0\"/s @ dec 0, Dec = 7.3\"/s")
            .unwrap());
        assert!(!h.read("Lock position = 631.655, 509.721").unwrap());
    }

    #[test]
    fn values_no_mount_gives_are_refused() {
        for (line, what) in [
            ("Pixel scale = -3 arc-sec/px", "Pixel scale"),
            ("Mount = M, xRate = 1e300", "xRate"),
            ("Dec = 95 deg, Hour angle = 1 hr", "Dec"),
            ("Dec = 5 deg, Hour angle = 25 hr", "Hour angle"),
            ("RA = 24.5 hr, Dec = 5 deg", "RA"),
            ("Max RA duration = -1", "Max RA duration"),
        ] {
            let e = read(&[line]).unwrap_err();
            assert!(e.starts_with(what), "{line}: {e}");
        }
    }

    #[test]
    fn a_section_inherits_the_equipment_not_the_pointing() {
        let h = read(&["Exposure = 3000 ms", "Dec = 1 deg, Hour angle = 2 hr"]).unwrap();
        let next = h.inherit();
        assert_eq!(next.exposure_s, Some(3.0));
        assert_eq!(next.pointing, Pointing::default());
    }
}
