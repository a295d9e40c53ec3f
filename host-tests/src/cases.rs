//! The paper's synthetic gear-error cases (`synthetic_cases.csv`).
//!
//! Columns `case,component,period_s,amplitude_px,phase_rad,drift_px_per_s`;
//! one row per sinusoid and one `drift` row per case. The gear error is
//! g(t) = sum A sin(2 pi t / P + phase) + drift t, in pixels. A file's
//! sinusoids are steady; a drawn mount's (`crate::population`) can also
//! change amplitude over the run ([`Envelope`]).

use crate::data::{parse_f64, read_text, Error};
use std::f64::consts::PI;
use std::path::Path;

pub const HEADER: &str = "case,component,period_s,amplitude_px,phase_rad,drift_px_per_s";

#[derive(Debug, Clone, PartialEq)]
pub struct Sinusoid {
    pub component: String,
    pub period_s: f64,
    pub amplitude_px: f64,
    pub phase_rad: f64,
    pub envelope: Envelope,
}

/// How a sinusoid's amplitude changes over the run: its amplitude at `t` is
/// `amplitude_px` times [`Envelope::factor`].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Envelope {
    /// The same amplitude all along (every sinusoid of a cases file).
    #[default]
    Steady,
    /// Times 1 + depth sin(2 pi t / period + phase).
    Modulated {
        depth: f64,
        period_s: f64,
        phase_rad: f64,
    },
    /// Times 1 until `from_s`, then linearly to `to` over `over_s`, and `to`
    /// after.
    Fade { from_s: f64, over_s: f64, to: f64 },
}

impl Envelope {
    /// The amplitude's factor at `t` (s).
    pub fn factor(&self, t: f64) -> f64 {
        match *self {
            Envelope::Steady => 1.0,
            Envelope::Modulated {
                depth,
                period_s,
                phase_rad,
            } => 1.0 + depth * (2.0 * PI * t / period_s + phase_rad).sin(),
            Envelope::Fade { from_s, over_s, to } => {
                let done = ((t - from_s) / over_s).clamp(0.0, 1.0);
                1.0 + (to - 1.0) * done
            }
        }
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct Case {
    pub name: String,
    pub sinusoids: Vec<Sinusoid>,
    pub drift_px_per_s: f64,
}

impl Case {
    /// The gear error at time `t` (s), in pixels.
    pub fn gear_error(&self, t: f64) -> f64 {
        let periodic: f64 = self
            .sinusoids
            .iter()
            .map(|s| {
                s.amplitude_px
                    * s.envelope.factor(t)
                    * (2.0 * PI * t / s.period_s + s.phase_rad).sin()
            })
            .sum();
        periodic + self.drift_px_per_s * t
    }
}

/// Load the cases from a file.
pub fn load(path: &Path) -> Result<Vec<Case>, Error> {
    parse(&read_text(path)?, path)
}

/// Parse the cases; `path` only names the file in errors. Cases keep the
/// order of their first row.
pub fn parse(text: &str, path: &Path) -> Result<Vec<Case>, Error> {
    let mut lines = text.lines().enumerate().map(|(i, l)| (i + 1, l.trim()));
    let err = |line: usize, msg: String| Error::new(path, Some(line), msg);
    match lines.next() {
        Some((_, h)) if h.trim_start_matches('\u{feff}') == HEADER => {}
        Some((n, h)) => return Err(err(n, format!("expected header {HEADER:?}, found {h:?}"))),
        None => return Err(Error::new(path, None, "empty file")),
    }
    let mut cases: Vec<Case> = Vec::new();
    let mut has_drift: Vec<bool> = Vec::new();
    for (n, line) in lines {
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        if f.len() != 6 {
            return Err(err(n, format!("expected 6 fields, found {}", f.len())));
        }
        let (name, component) = (f[0], f[1]);
        if name.is_empty() || component.is_empty() {
            return Err(err(n, "empty case or component name".into()));
        }
        let idx = match cases.iter().position(|c| c.name == name) {
            Some(i) => i,
            None => {
                cases.push(Case {
                    name: name.to_string(),
                    sinusoids: Vec::new(),
                    drift_px_per_s: 0.0,
                });
                has_drift.push(false);
                cases.len() - 1
            }
        };
        if component == "drift" {
            if f[2..5].iter().any(|x| !x.is_empty()) {
                return Err(err(n, "a drift row has only drift_px_per_s".into()));
            }
            if has_drift[idx] {
                return Err(err(n, format!("second drift row for case {name}")));
            }
            cases[idx].drift_px_per_s = parse_f64(f[5], "drift_px_per_s").map_err(|m| err(n, m))?;
            has_drift[idx] = true;
        } else {
            if !f[5].is_empty() {
                return Err(err(
                    n,
                    format!("unknown row: component {component:?} with a drift value (only `drift` rows have one)"),
                ));
            }
            let num = |i: usize, col: &str| parse_f64(f[i], col).map_err(|m| err(n, m));
            let period_s = num(2, "period_s")?;
            let amplitude_px = num(3, "amplitude_px")?;
            // An empty phase is 0.
            let phase_rad = if f[4].is_empty() {
                0.0
            } else {
                num(4, "phase_rad")?
            };
            if period_s <= 0.0 {
                return Err(err(
                    n,
                    format!("period_s must be positive, found {period_s}"),
                ));
            }
            cases[idx].sinusoids.push(Sinusoid {
                component: component.to_string(),
                period_s,
                amplitude_px,
                phase_rad,
                envelope: Envelope::Steady,
            });
        }
    }
    if cases.is_empty() {
        return Err(Error::new(path, None, "no cases"));
    }
    Ok(cases)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(text: &str) -> Result<Vec<Case>, Error> {
        parse(text, Path::new("cases.csv"))
    }

    #[test]
    fn parses_and_evaluates() {
        let c = p(&format!(
            "{HEADER}\nX,primary,400,2.0,0.5,\nX,drift,,,,0.001\n"
        ))
        .unwrap();
        assert_eq!(c.len(), 1);
        let t = 123.0;
        let want = 2.0 * (2.0 * PI * t / 400.0 + 0.5).sin() + 0.001 * t;
        assert!((c[0].gear_error(t) - want).abs() < 1e-15);
    }

    #[test]
    fn envelopes() {
        let m = Envelope::Modulated {
            depth: 0.5,
            period_s: 3600.0,
            phase_rad: 0.0,
        };
        assert!((m.factor(900.0) - 1.5).abs() < 1e-12);
        assert!((m.factor(2700.0) - 0.5).abs() < 1e-12);
        let f = Envelope::Fade {
            from_s: 1000.0,
            over_s: 500.0,
            to: 0.2,
        };
        assert_eq!(f.factor(999.0), 1.0);
        assert!((f.factor(1250.0) - 0.6).abs() < 1e-12);
        assert!((f.factor(1600.0) - 0.2).abs() < 1e-12);
        assert_eq!(Envelope::Steady.factor(1e6), 1.0);
    }

    #[test]
    fn errors_name_file_and_line() {
        let e = p(&format!("{HEADER}\nX,primary,4x0,2.0,0,\n")).unwrap_err();
        assert_eq!(
            e.to_string(),
            "cases.csv:2: period_s: not a finite number: \"4x0\""
        );
        let e = p(&format!(
            "{HEADER}\nX,primary,400,2.0,0,\nX,wobble,300,1,0,0.1\n"
        ))
        .unwrap_err();
        assert_eq!(e.line, Some(3));
        assert!(e.message.contains("unknown row"), "{e}");
        let e = p(&format!("{HEADER}\nX,primary,400,2.0\n")).unwrap_err();
        assert_eq!(e.line, Some(2));
        let e = p("case,comp\n").unwrap_err();
        assert_eq!(e.line, Some(1));
        let e = p(&format!("{HEADER}\n")).unwrap_err();
        assert_eq!(e.to_string(), "cases.csv: no cases");
    }
}
