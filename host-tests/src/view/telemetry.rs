//! The telemetry line (docs/port.md, "Telemetry"), read back:
//!
//! ```text
//! ~T t_ms=1234567 gear_ms=1200000 kind=m obs_mas=-1500 pulse_mas=-700 applied_mas=-480 pred_mas=-1420 ff_mas_s=35 learn_pm=423 stage=600000,4250,1000#
//! ```
//!
//! The parser is strict about what it needs (every field once, integers in
//! range) and lenient about what it does not know (an unknown key is
//! skipped), so that a newer firmware's extra fields do not blind the view
//! while a garbled line is refused rather than plotted.

use std::fmt;

/// The most stages a line may carry (the port's `:~S0#`..`:~S9#`).
pub const MAX_STAGES: usize = 10;

/// A stage the board has found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Stage {
    pub period_ms: u32,
    /// Always 0 for now: the model does not expose it (docs/port.md).
    pub amp_mas: i64,
    pub gate_pm: u16,
}

/// One telemetry line.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Telemetry {
    pub t_ms: u64,
    pub gear_ms: u64,
    /// `m` measured, `f` filled, `u` unmeasured, `d` dither.
    pub kind: u8,
    pub obs_mas: i64,
    pub pulse_mas: i64,
    pub applied_mas: i64,
    pub pred_mas: i64,
    pub ff_mas_s: i64,
    pub learn_pm: u16,
    pub stages: Vec<Stage>,
}

/// Why a line was refused.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ParseError(pub String);

impl fmt::Display for ParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

/// Values beyond this are not a board's (a day of milliarcseconds of
/// error would be 86 400 000 000): refused as garbled.
const MAX_ABS_MAS: i64 = 1_000_000_000_000;

fn int(key: &str, v: &str) -> Result<i64, ParseError> {
    match v.parse::<i64>() {
        Ok(x) if x.abs() <= MAX_ABS_MAS => Ok(x),
        _ => Err(ParseError(format!("{key}: not an integer in range: {v:?}"))),
    }
}

fn unsigned<T: TryFrom<u64>>(key: &str, v: &str, max: u64) -> Result<T, ParseError> {
    v.parse::<u64>()
        .ok()
        .filter(|&x| x <= max)
        .and_then(|x| T::try_from(x).ok())
        .ok_or_else(|| ParseError(format!("{key}: not a count up to {max}: {v:?}")))
}

fn stage(v: &str) -> Result<Stage, ParseError> {
    let mut it = v.split(',');
    let (Some(p), Some(a), Some(g), None) = (it.next(), it.next(), it.next(), it.next()) else {
        return Err(ParseError(format!(
            "stage: PERIOD_MS,AMP_MAS,GATE_PM expected: {v:?}"
        )));
    };
    Ok(Stage {
        period_ms: unsigned("stage period", p, u64::from(u32::MAX))?,
        amp_mas: int("stage amplitude", a)?,
        gate_pm: unsigned("stage gate", g, 1000)?,
    })
}

/// Reads one line: `~T ` .. `#`, exactly (the framing is the client's).
pub fn parse(line: &str) -> Result<Telemetry, ParseError> {
    let body = line
        .strip_prefix("~T ")
        .and_then(|l| l.strip_suffix('#'))
        .ok_or_else(|| ParseError("not framed as ~T ...#".into()))?;
    // Each required field, once.
    let mut seen = [false; 9];
    let mut t = Telemetry {
        t_ms: 0,
        gear_ms: 0,
        kind: 0,
        obs_mas: 0,
        pulse_mas: 0,
        applied_mas: 0,
        pred_mas: 0,
        ff_mas_s: 0,
        learn_pm: 0,
        stages: Vec::new(),
    };
    for field in body.split(' ') {
        let (key, v) = field
            .split_once('=')
            .ok_or_else(|| ParseError(format!("field without '=': {field:?}")))?;
        let slot = match key {
            "t_ms" => {
                t.t_ms = unsigned(key, v, u64::MAX)?;
                0
            }
            "gear_ms" => {
                t.gear_ms = unsigned(key, v, u64::MAX)?;
                1
            }
            "kind" => {
                t.kind = match v {
                    "m" | "f" | "u" | "d" | "s" => v.as_bytes()[0],
                    _ => return Err(ParseError(format!("kind: m, f, u, d or s expected: {v:?}"))),
                };
                2
            }
            "obs_mas" => {
                t.obs_mas = int(key, v)?;
                3
            }
            "pulse_mas" => {
                t.pulse_mas = int(key, v)?;
                4
            }
            "applied_mas" => {
                t.applied_mas = int(key, v)?;
                5
            }
            "pred_mas" => {
                t.pred_mas = int(key, v)?;
                6
            }
            "ff_mas_s" => {
                t.ff_mas_s = int(key, v)?;
                7
            }
            "learn_pm" => {
                t.learn_pm = unsigned(key, v, 1000)?;
                8
            }
            "stage" => {
                if t.stages.len() == MAX_STAGES {
                    return Err(ParseError(format!("more than {MAX_STAGES} stages")));
                }
                t.stages.push(stage(v)?);
                continue;
            }
            // A field of a newer firmware: skipped, if it looks like one.
            _ if !key.is_empty() && key.bytes().all(|b| b.is_ascii_lowercase() || b == b'_') => {
                continue
            }
            _ => return Err(ParseError(format!("not a key: {key:?}"))),
        };
        if std::mem::replace(&mut seen[slot], true) {
            return Err(ParseError(format!("{key} twice")));
        }
    }
    if let Some(i) = seen.iter().position(|s| !s) {
        const KEYS: [&str; 9] = [
            "t_ms",
            "gear_ms",
            "kind",
            "obs_mas",
            "pulse_mas",
            "applied_mas",
            "pred_mas",
            "ff_mas_s",
            "learn_pm",
        ];
        return Err(ParseError(format!("{} missing", KEYS[i])));
    }
    Ok(t)
}

#[cfg(test)]
mod tests {
    use super::*;

    const LINE: &str = "~T t_ms=1234567 gear_ms=1200000 kind=m obs_mas=-1500 pulse_mas=-700 applied_mas=-480 pred_mas=-1420 ff_mas_s=35 learn_pm=423 stage=600000,4250,1000 stage=86400,730,412#";

    #[test]
    fn reads_the_documented_line() {
        let t = parse(LINE).unwrap();
        assert_eq!((t.t_ms, t.gear_ms, t.kind), (1_234_567, 1_200_000, b'm'));
        assert_eq!(
            (
                t.obs_mas,
                t.pulse_mas,
                t.applied_mas,
                t.pred_mas,
                t.ff_mas_s
            ),
            (-1500, -700, -480, -1420, 35)
        );
        assert_eq!(t.learn_pm, 423);
        assert_eq!(
            t.stages,
            [
                Stage {
                    period_ms: 600_000,
                    amp_mas: 4250,
                    gate_pm: 1000
                },
                Stage {
                    period_ms: 86_400,
                    amp_mas: 730,
                    gate_pm: 412
                }
            ]
        );
    }

    #[test]
    fn refuses_what_is_garbled() {
        for bad in [
            &LINE[..LINE.len() - 1],                        // truncated: no '#'
            &LINE[..60],                                    // truncated mid-line
            &LINE.replace("learn_pm=423", "learn_pm=1001"), // out of range
            &LINE.replace("kind=m", "kind=x"),
            &LINE.replace("obs_mas=-1500", "obs_mas=-15x0"),
            &LINE.replace(" t_ms=1234567", ""),         // missing
            &LINE.replace("gear_ms=1200000", "t_ms=5"), // twice
            &LINE.replace("stage=86400,730,412", "stage=86400,730"),
        ] {
            assert!(parse(bad).is_err(), "accepted {bad:?}");
        }
        // A newer firmware's extra field is skipped.
        assert!(parse(&LINE.replace("learn_pm", "new_field=7 learn_pm")).is_ok());
    }
}
