//! The rows of a guiding section: its `Frame,Time,mount,...` header names
//! the columns, then one row per frame. A frame PHD2 found its star in has
//! an RARawDistance; a `"DROP"` row (star lost) has none.

use super::limits;
use crate::data::parse_f64;

/// Column indices of the fields we use, from a section's CSV header.
#[derive(Debug, Clone, Copy)]
pub struct Columns {
    pub time: usize,
    pub ra_raw: usize,
    pub ra_guide: usize,
    pub snr: usize,
    /// RADuration: the RA pulse sent, ms (not in every log's rows).
    pub ra_pulse: Option<usize>,
}

const REQUIRED: [&str; 4] = ["Time", "RARawDistance", "RAGuideDistance", "SNR"];

impl Columns {
    pub fn from_header(fields: &[String]) -> Result<Columns, String> {
        let find = |name: &str| fields.iter().position(|f| f == name);
        let missing: Vec<&str> = REQUIRED
            .iter()
            .copied()
            .filter(|n| find(n).is_none())
            .collect();
        match (
            find("Time"),
            find("RARawDistance"),
            find("RAGuideDistance"),
            find("SNR"),
        ) {
            (Some(time), Some(ra_raw), Some(ra_guide), Some(snr)) => Ok(Columns {
                time,
                ra_raw,
                ra_guide,
                snr,
                ra_pulse: find("RADuration"),
            }),
            _ => Err(format!(
                "guide-frame header lacks column(s) {}",
                missing.join(", ")
            )),
        }
    }
}

/// Split a CSV line, honouring double quotes (PHD2 quotes the mount name and
/// error messages).
pub fn split_csv(line: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut field = String::new();
    let mut quoted = false;
    for ch in line.chars() {
        match ch {
            '"' => quoted = !quoted,
            ',' if !quoted => out.push(std::mem::take(&mut field)),
            _ => field.push(ch),
        }
    }
    out.push(field);
    out
}

/// What one row measured.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Row {
    pub time_s: f64,
    /// RARawDistance, RAGuideDistance, SNR and RADuration (if the log has
    /// it and the row gives it); `None` for a frame without a star.
    pub star: Option<Star>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Star {
    pub ra_raw: f64,
    pub ra_guide: f64,
    pub snr: f64,
    pub ra_pulse_ms: Option<f64>,
}

impl Columns {
    /// The numbers of row `fields`.
    pub fn row(&self, fields: &[String]) -> Result<Row, String> {
        let field = |idx: usize, name: &str| {
            fields
                .get(idx)
                .ok_or_else(|| format!("row has {} fields, no {name} column", fields.len()))
        };
        let time_s = limits::time(field(self.time, "Time")?, "Time")?;
        if fields.get(self.ra_raw).is_none_or(|f| f.trim().is_empty()) {
            return Ok(Row { time_s, star: None });
        }
        let ra_raw = limits::distance(field(self.ra_raw, "RARawDistance")?, "RARawDistance")?;
        let ra_guide =
            limits::distance(field(self.ra_guide, "RAGuideDistance")?, "RAGuideDistance")?;
        let snr = parse_f64(field(self.snr, "SNR")?, "SNR")?;
        let ra_pulse_ms = match self.ra_pulse.and_then(|i| fields.get(i)) {
            Some(f) if !f.trim().is_empty() => {
                Some(limits::pulse_ms(parse_f64(f, "RADuration")?, "RADuration")?)
            }
            _ => None,
        };
        Ok(Row {
            time_s,
            star: Some(Star {
                ra_raw,
                ra_guide,
                snr,
                ra_pulse_ms,
            }),
        })
    }
}

/// How much shorter than its RAGuideDistance a pulse must be to have been
/// cut, ms: RADuration is written in whole ms and xRate to three decimals
/// (in the five reference logs every uncut pulse is within 0.7 ms).
pub const PULSE_ROUNDING_MS: f64 = 2.0;

/// The RA correction the mount carried out, px: RAGuideDistance, which is
/// what the guide algorithm asked for, unless the pulse sent (RADuration x
/// xRate) fell short of it: a pulse cut at `Max RA duration`, or none sent
/// (the last frame of a section). The direction is RAGuideDistance's.
pub fn applied(star: &Star, x_rate: Option<f64>) -> f64 {
    match (star.ra_pulse_ms, x_rate) {
        (Some(ms), Some(rate)) if rate > 0.0 => {
            let asked_ms = star.ra_guide.abs() / rate * 1000.0;
            if asked_ms - ms > PULSE_ROUNDING_MS {
                (ms / 1000.0 * rate).copysign(star.ra_guide)
            } else {
                star.ra_guide
            }
        }
        _ => star.ra_guide,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn star(guide: f64, ms: Option<f64>) -> Star {
        Star {
            ra_raw: 0.0,
            ra_guide: guide,
            snr: 10.0,
            ra_pulse_ms: ms,
        }
    }

    #[test]
    fn a_pulse_cut_short_is_what_was_applied() {
        // Log 01's first row: 0.540 px at 2.378 px/s is 227 ms, as sent.
        assert_eq!(applied(&star(-0.540, Some(227.0)), Some(2.378)), -0.540);
        // A 2.44 s pulse cut at 1.5 s (0.42 px/s).
        let a = applied(&star(1.026, Some(1500.0)), Some(0.420));
        assert!((a - 0.63).abs() < 1e-12, "{a}");
        // Guiding stopped before the pulse.
        assert_eq!(applied(&star(-0.093, Some(0.0)), Some(2.378)), -0.0);
        // Without the pulse or the rate, the distance.
        assert_eq!(applied(&star(1.026, None), Some(0.420)), 1.026);
        assert_eq!(applied(&star(1.026, Some(0.0)), None), 1.026);
    }

    #[test]
    fn columns_by_name() {
        let h = split_csv("Frame,Time,mount,RARawDistance,RAGuideDistance,SNR");
        let c = Columns::from_header(&h).unwrap();
        assert_eq!(
            (c.time, c.ra_raw, c.ra_guide, c.snr, c.ra_pulse),
            (1, 3, 4, 5, None)
        );
        let row = c.row(&split_csv("1,2.5,\"Mount\",0.5,-0.25,20")).unwrap();
        assert_eq!(row.time_s, 2.5);
        assert_eq!(
            row.star,
            Some(Star {
                ra_raw: 0.5,
                ra_guide: -0.25,
                snr: 20.0,
                ra_pulse_ms: None
            })
        );
        let drop = c
            .row(&split_csv("2,3.5,\"DROP\",,,0,7,\"Star lost\""))
            .unwrap();
        assert_eq!(drop.star, None);
    }
}
