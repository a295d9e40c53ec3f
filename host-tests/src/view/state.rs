//! The page's data: the session and its analysis as one JSON document,
//! fetched by the page about once a second. Written by hand (numbers,
//! arrays and escaped strings are all it needs).

use super::analysis::{self, Sample, StageFit, CURVE_POINTS};
use super::client::VERSION;
use super::session::{LinkState, Session};
use super::telemetry::Telemetry;
use std::fmt::Write;

/// Frames in the time chart (about half an hour of 2 s frames).
const TIME_FRAMES: usize = 900;
/// Points sent per series at most.
const MAX_POINTS: usize = 600;
/// Frames the spectrum and the stage fit use (the newest).
const ANALYSIS_FRAMES: usize = 4096;
/// Worm periods of observations behind the phase chart's fitted curve.
const FOLD_PERIODS: f64 = 3.0;

fn num(x: f64) -> String {
    if x.is_finite() {
        let s = format!("{x:.3}");
        let s = s.trim_end_matches('0').trim_end_matches('.');
        if s == "-0" {
            "0".into()
        } else {
            s.into()
        }
    } else {
        "null".into()
    }
}

fn string(s: &str) -> String {
    let mut o = String::from("\"");
    for c in s.chars() {
        match c {
            '"' => o.push_str("\\\""),
            '\\' => o.push_str("\\\\"),
            c if (c as u32) < 0x20 => {
                let _ = write!(o, "\\u{:04x}", c as u32);
            }
            c => o.push(c),
        }
    }
    o.push('"');
    o
}

fn array(xs: impl IntoIterator<Item = f64>) -> String {
    let v: Vec<String> = xs.into_iter().map(num).collect();
    format!("[{}]", v.join(","))
}

/// Every k-th of `v` so that at most [`MAX_POINTS`] remain (the last kept).
fn thin<T>(v: &[T]) -> Vec<&T> {
    if v.is_empty() {
        return Vec::new();
    }
    let k = v.len().div_ceil(MAX_POINTS).max(1);
    let start = (v.len() - 1) % k;
    v.iter().skip(start).step_by(k).collect()
}

fn arcsec(mas: i64) -> f64 {
    mas as f64 / 1000.0
}

/// Measured and filled frames observe the gear error; the others do not.
fn observes(f: &Telemetry) -> bool {
    matches!(f.kind, b'm' | b'f')
}

fn time_chart(frames: &[&Telemetry]) -> String {
    let from = frames.len().saturating_sub(TIME_FRAMES);
    let v = thin(&frames[from..]);
    let series = |f: &dyn Fn(&Telemetry) -> f64| array(v.iter().map(|t| f(t)));
    format!(
        "{{\"t\":{},\"obs\":{},\"applied\":{},\"pointing\":{},\"pulse\":{},\"ff\":{}}}",
        series(&|t| t.t_ms as f64 / 1000.0),
        series(&|t| arcsec(t.obs_mas)),
        series(&|t| arcsec(t.applied_mas)),
        series(&|t| arcsec(t.obs_mas - t.applied_mas)),
        series(&|t| arcsec(t.pulse_mas)),
        series(&|t| arcsec(t.ff_mas_s)),
    )
}

fn learn_chart(frames: &[&Telemetry]) -> String {
    let v = thin(frames);
    format!(
        "{{\"t\":{},\"pm\":{}}}",
        array(v.iter().map(|t| t.t_ms as f64 / 1000.0)),
        array(v.iter().map(|t| f64::from(t.learn_pm)))
    )
}

fn phase_chart(samples: &[Sample], fit: &StageFit) -> String {
    let p = fit.periods[0];
    let last = samples.last().map_or(0.0, |s| s.t);
    // The newest worm cycle: the curve is what the fit says over it.
    let anchor = (last / p).floor() * p;
    let xs: Vec<f64> = (0..=CURVE_POINTS)
        .map(|i| p * i as f64 / CURVE_POINTS as f64)
        .collect();
    let stages: Vec<String> = (0..fit.periods.len())
        .map(|k| array(xs.iter().map(|&x| fit.stage_at(k, anchor + x))))
        .collect();
    let total = array(xs.iter().map(|&x| {
        (0..fit.periods.len())
            .map(|k| fit.stage_at(k, anchor + x))
            .sum()
    }));
    let recent: Vec<&Sample> = samples
        .iter()
        .filter(|s| s.t >= last - FOLD_PERIODS * p)
        .collect();
    let pts = thin(&recent);
    let line = |s: &Sample| s.y - fit.line[0] - fit.line[1] * s.t;
    format!(
        "{{\"period_s\":{},\"x\":{},\"total\":{},\"stages\":[{}],\"points_x\":{},\"points_y\":{},\
         \"rms_before\":{},\"rms_after\":{}}}",
        num(p),
        array(xs.iter().copied()),
        total,
        stages.join(","),
        array(pts.iter().map(|s| s.t.rem_euclid(p))),
        array(pts.iter().map(|s| line(s))),
        num(fit.rms_before),
        num(fit.rms_after)
    )
}

/// The whole state, as JSON.
pub fn json(s: &Session) -> String {
    let frames: Vec<&Telemetry> = s.frames.iter().collect();
    let samples: Vec<Sample> = frames[frames.len().saturating_sub(ANALYSIS_FRAMES)..]
        .iter()
        .filter(|f| observes(f))
        .map(|f| Sample {
            t: f.gear_ms as f64 / 1000.0,
            y: arcsec(f.obs_mas),
        })
        .collect();
    let periods: Vec<f64> = s
        .stages
        .iter()
        .map(|st| f64::from(st.period_ms) / 1000.0)
        .collect();
    let fit = analysis::fit_stages(&samples, &periods);
    let detrended = analysis::detrend(&samples)
        .map(|(d, _)| d)
        .unwrap_or_default();
    let spectrum = analysis::spectrum(&detrended);
    let peaks: Vec<String> = analysis::peaks(&detrended, &spectrum)
        .iter()
        .take(5)
        .map(|&(p, a)| format!("[{},{}]", num(p), num(a)))
        .collect();
    let stages: Vec<String> = s
        .stages
        .iter()
        .map(|st| {
            let p = f64::from(st.period_ms) / 1000.0;
            let amp = fit.as_ref().and_then(|f| {
                let k = f.periods.iter().position(|&q| q == p)?;
                Some(f.amplitude(k))
            });
            format!(
                "{{\"period_s\":{},\"gate_pm\":{},\"fit_amp\":{}}}",
                num(p),
                st.gate_pm,
                amp.map_or("null".into(), num)
            )
        })
        .collect();
    let counters: Vec<String> = s
        .counters
        .iter()
        .map(|(g, list)| {
            let kv: Vec<String> = list
                .iter()
                .map(|(k, v)| format!("[{},{}]", string(k), string(v)))
                .collect();
            format!("{}:[{}]", string(&g.to_string()), kv.join(","))
        })
        .collect();
    let (link, link_why) = match &s.link {
        LinkState::Connecting => ("connecting", ""),
        LinkState::Connected => ("connected", ""),
        LinkState::Down(why) => ("down", why.as_str()),
    };
    let opt = |o: &Option<String>| o.as_deref().map_or("null".into(), string);
    let problems: Vec<String> = s.problems.values().map(|p| string(p)).collect();
    let log: Vec<String> = s
        .log
        .iter()
        .map(|(t, m)| format!("[{},{}]", num(*t), string(m)))
        .collect();
    format!(
        "{{\"target\":{},\"link\":{},\"link_why\":{},\"product\":{},\"version\":{},\"reset\":{},\
         \"view_version\":{},\"problems\":[{}],\"log\":[{}],\"frames\":{},\"frames_dropped\":{},\
         \"lines_ok\":{},\"lines_bad\":{},\"last_bad\":{},\"garbage_bytes\":{},\"learn_pm\":{},\
         \"learn_first\":{},\"stages\":[{}],\"time\":{},\"learn\":{},\"phase\":{},\
         \"spectrum\":{{\"period\":{},\"amp\":{},\"peaks\":[{}]}},\"counters\":{{{}}}}}",
        string(&s.target),
        string(link),
        string(link_why),
        opt(&s.product),
        opt(&s.version),
        opt(&s.reset),
        string(VERSION),
        problems.join(","),
        log.join(","),
        s.frames.len(),
        s.frames_dropped,
        s.lines_ok,
        s.lines_bad,
        s.last_bad.as_ref().map_or("null".into(), |(l, w)| format!(
            "[{},{}]",
            string(l),
            string(w)
        )),
        s.garbage_bytes,
        frames
            .last()
            .map_or("null".into(), |f| f.learn_pm.to_string()),
        frames
            .first()
            .map_or("null".into(), |f| f.learn_pm.to_string()),
        stages.join(","),
        time_chart(&frames),
        learn_chart(&frames),
        fit.as_ref()
            .map_or("null".into(), |f| phase_chart(&samples, f)),
        array(spectrum.iter().map(|x| x.0)),
        array(spectrum.iter().map(|x| x.1)),
        peaks.join(","),
        counters.join(",")
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_and_strings_are_json() {
        assert_eq!(num(1.5), "1.5");
        assert_eq!(num(2.0), "2");
        assert_eq!(num(-0.0001), "0");
        assert_eq!(num(f64::NAN), "null");
        assert_eq!(string("a\"b\\c\n"), "\"a\\\"b\\\\c\\u000a\"");
    }
}
