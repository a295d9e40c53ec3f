//! Nights of several guiding sections (issue 27, item 2): each section
//! with its own header, the time step of the frames' own cadence, frames
//! without a star and pauses told, the model carried across sections.
//! Made from the real one-section logs (`common::nights`) and from the
//! public night in `data/phd2-nights`.

mod common;

use common::nights::{self, Piece};
use host_tests::data;
use host_tests::gp::{trace, Carry};
use host_tests::guide_algorithm::{GuideAlgorithm, Hysteresis, Restart};
use host_tests::models::{self, Model};
use host_tests::phd2_log::{self, GuideLog};
use host_tests::replay::{self, report, Options, TimeStep};
use mkgp_mount::model::additions::Additions;
use rayon::prelude::*;
use std::path::Path;

fn parse(name: &str, text: &str) -> GuideLog {
    phd2_log::parse(text, Path::new(name)).unwrap_or_else(|e| panic!("{e}"))
}

/// The five logs, each with the number of sections the nights below cut
/// it into (about 250-1,000 frames a section).
const CUTS: [(&str, usize); 5] = [
    ("dataset01", 3),
    ("dataset02", 3),
    ("dataset03", 3),
    ("dataset04", 4),
    ("dataset05", 3),
];

/// `name` cut into `parts` sections of its rows, `gap` rows left out
/// between them (a pause of that many frames; the star locked afresh).
fn split(name: &str, parts: usize, gap: usize) -> GuideLog {
    let lines = nights::original(name);
    let n = nights::rows(&lines).len();
    let len = n / parts;
    let pieces: Vec<Piece> = (0..parts)
        .map(|p| {
            let from = if p == 0 { 0 } else { p * len + gap };
            let to = if p + 1 == parts { n } else { (p + 1) * len };
            Piece::new(from..to)
        })
        .collect();
    parse(name, &nights::night(&lines, &pieces))
}

/// What a replay told the algorithm, call by call.
#[derive(Debug, Clone, PartialEq)]
enum Call {
    Step { t: f64, dt: f64 },
    Dark { t: f64 },
    Restart(Restart),
}

#[derive(Default)]
struct Recorder {
    calls: Vec<Call>,
}

impl GuideAlgorithm for Recorder {
    fn step(&mut self, t: f64, _measured: f64, _snr: f64, dt: f64) -> f64 {
        self.calls.push(Call::Step { t, dt });
        0.0
    }
    fn dark(&mut self, t: f64, _dt: f64) -> f64 {
        self.calls.push(Call::Dark { t });
        0.0
    }
    fn restart(&mut self, restart: &Restart) {
        self.calls.push(Call::Restart(*restart));
    }
}

fn record(log: &GuideLog) -> Vec<Call> {
    let mut r = Recorder::default();
    replay::run_with(log, &mut r, &Options::default()).unwrap();
    r.calls
}

/// Log 05 in three sections, the second written with 2 s exposures: each
/// section its own exposure and place on the night's clock, and a restart
/// between them with the pause and the hour angle's verdict (the same
/// target).
#[test]
fn sections_keep_their_headers_and_the_nights_clock() {
    let lines = nights::original("dataset05");
    let n = nights::rows(&lines).len();
    let mut pieces = vec![
        Piece::new(0..1000),
        Piece::new(1100..2000),
        Piece::new(2200..n),
    ];
    pieces[1].exposure_ms = Some(2000);
    let log = parse("split05", &nights::night(&lines, &pieces));
    let whole =
        phd2_log::load(&data::data_dir().join("phd2-logs/performance_dataset05.txt")).unwrap();
    assert_eq!(log.sections.len(), 3);
    let exposures: Vec<f64> = log.sections.iter().map(|s| s.exposure_s).collect();
    assert_eq!(exposures, vec![0.5, 2.0, 0.5]);
    // Every frame at its time of the original night (to the ms the log
    // writes).
    let original = &whole.sections[0].frames;
    for (s, from) in log.sections.iter().zip([0, 1100, 2200]) {
        let f = &s.frames[0];
        let want = original.iter().find(|o| o.frame == f.frame).unwrap();
        assert!((s.start_s + f.time_s - want.time_s).abs() < 1e-9, "{from}");
    }
    let calls = record(&log);
    let restarts: Vec<&Restart> = calls
        .iter()
        .filter_map(|c| match c {
            Call::Restart(r) => Some(r),
            _ => None,
        })
        .collect();
    assert_eq!(restarts.len(), 2);
    for r in &restarts {
        assert_eq!(r.gear_shift_s, Some(0.0), "{r:?}");
        assert!(!r.pier_flip);
        assert!(r.gap_s > 30.0, "{r:?}");
    }
    // The second section's frames get its own exposure as time step.
    let steps: Vec<f64> = calls
        .iter()
        .filter_map(|c| match c {
            Call::Step { dt, .. } => Some(*dt),
            _ => None,
        })
        .collect();
    assert_eq!(steps[0], 0.5);
    // Each section's n frames give n - 2 steps.
    assert_eq!(steps[log.sections[0].frames.len() - 2], 2.0);
}

/// Frames that come three exposures apart (log 03 with two frames of three
/// left out, corrections kept): the time step is their cadence, not the
/// exposure.
#[test]
fn the_time_step_is_the_frames_cadence_when_they_come_slower() {
    let whole =
        phd2_log::load(&data::data_dir().join("phd2-logs/performance_dataset03.txt")).unwrap();
    let log = one_in(&whole, 3);
    let s = &log.sections[0];
    let cadence = replay::time_step_s(s, &Options::default());
    assert!(cadence > 9.0 && cadence < 10.5, "{cadence}");
    assert!(record(&log)
        .iter()
        .all(|c| !matches!(c, Call::Step { dt, .. } if *dt != cadence)));
    // The five logs' frames come at their exposure plus PHD2's overhead:
    // the exposure stays the step.
    for name in ["01", "02", "03", "04", "05"] {
        let path = data::data_dir().join(format!("phd2-logs/performance_dataset{name}.txt"));
        let log = phd2_log::load(&path).unwrap();
        let s = &log.sections[0];
        assert_eq!(replay::time_step_s(s, &Options::default()), s.exposure_s);
    }
}

/// Log 01's DROP row and log 04's pause of 173 s (PAUSE/RESUME) reach the
/// model as frames without a star: the DROP at its time, the pause one
/// frame per cadence.
#[test]
fn drops_and_pauses_are_frames_without_a_star() {
    let log = |n: &str| {
        phd2_log::load(&data::data_dir().join(format!("phd2-logs/performance_dataset{n}.txt")))
            .unwrap()
    };
    let darks = |log: &GuideLog| -> Vec<f64> {
        record(log)
            .into_iter()
            .filter_map(|c| match c {
                Call::Dark { t } => Some(t),
                _ => None,
            })
            .collect()
    };
    let drops: Vec<f64> = log("01").sections[0].drops().map(|(_, t)| t).collect();
    assert_eq!(darks(&log("01")), drops);
    let pause = darks(&log("04"));
    assert!(pause.len() > 70 && pause.len() < 90, "{}", pause.len());
    let cadence = pause[1] - pause[0];
    assert!((cadence - 2.05).abs() < 0.01, "{cadence}");
    assert!(pause
        .windows(2)
        .all(|w| (w[1] - w[0] - cadence).abs() < 1e-9));
}

/// Issue 27's goals for the replay, on nights made by cutting each of the
/// five logs into sections on the same target with pauses between them:
/// the whole night's MKGP gain over hysteresis at least 0, and at least
/// the mean of its sections replayed alone (carrying the model pays).
#[test]
fn carrying_the_model_across_sections_pays() {
    let mut failures = Vec::new();
    for (name, parts) in CUTS {
        let log = split(name, parts, 10);
        let goals = report::report(&log, true).unwrap().goals().unwrap();
        println!("{name} in {parts}: {goals:?}");
        if goals.whole_gain_pct < 0.0 || goals.whole_gain_pct < goals.alone_mean_pct {
            failures.push(format!("{name}: {goals:?}"));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// The public night of data/phd2-nights.
fn public_night() -> GuideLog {
    let paths = data::night_logs().unwrap();
    let night = paths
        .iter()
        .find(|p| p.to_string_lossy().contains("2026-01-28"))
        .unwrap();
    phd2_log::load(night).unwrap_or_else(|e| panic!("{e}"))
}

/// The public night (data/phd2-nights): its sections as PHD2 wrote them,
/// the calibration and the two sections on a saturated star (every row far
/// beyond the search region: frames PHD2 lost) left out, and every figure
/// of the replay finite.
#[test]
fn the_public_night_replays_section_by_section() {
    let log = public_night();
    assert_eq!(log.sections.len(), 14);
    let exposures: Vec<f64> = log.sections.iter().map(|s| s.exposure_s).collect();
    assert_eq!(&exposures[..3], &[0.35, 0.35, 0.3]);
    assert!(exposures[3..].iter().all(|&e| e == 1.5));
    assert!(log.sections.iter().all(|s| s.header.predictive()));
    // 0.35 s exposures a frame every 0.9 s: the cadence is the step.
    let step = replay::time_step_s(&log.sections[0], &Options::default());
    assert!(step > 0.8 && step < 1.0, "{step}");
    let last = log.sections.last().unwrap();
    assert_eq!(last.frames.len(), 977);
    assert_eq!(last.dithers().count(), 6);
    let rep = report::report(&log, true).unwrap();
    for f in std::iter::once(&rep.whole).chain(rep.sections.iter().map(|s| &s.night)) {
        for v in [f.hysteresis, f.ppec, f.mkgp] {
            assert!(v.is_finite() && v < 10.0, "{f:?}");
        }
    }
}

/// `replay --trace`: the traced replay is the `mkgp` column's own (the
/// same RMS to the bit), with one row per call of the model, in the log's
/// clock order, a measured error on each frame with a star.
#[test]
fn the_replays_trace_follows_the_frames() {
    let log = public_night();
    let (traced, csv) = replay::traced_mkgp(&log).unwrap();
    assert_eq!(traced, replay::run_model(&log, Model::Mkgp).unwrap());
    assert_eq!(csv.lines().next(), Some(trace::header(2).as_str()));
    let rows: Vec<Vec<&str>> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect();
    assert!(rows.iter().all(|r| r.len() == 8), "{rows:?}");
    let measured = rows.iter().filter(|r| !r[1].is_empty()).count();
    assert_eq!(measured, traced.frames);
    let times: Vec<f64> = rows.iter().map(|r| r[0].parse().unwrap()).collect();
    assert!(times.windows(2).all(|w| w[0] <= w[1]));
    // The last section begins 9,313 s into the night (its header's clock).
    assert!(times.last().unwrap() > &9313.0, "{:?}", times.last());
}

/// Issue 27's replay goals on the scripted nights `guide-sim night` wrote
/// (data/night-logs: seven sections each, dithers of up to 40 px, pauses,
/// slews and a flip): the whole night's MKGP gain at least 0 and at least
/// its sections' replayed alone, no section below -0.5 %.
#[test]
fn the_simulated_nights_meet_the_replay_goals() {
    let paths = data::simulated_night_logs().unwrap();
    assert_eq!(paths.len(), 3);
    let misses: Vec<String> = paths
        .par_iter()
        .filter_map(|p| {
            let log = phd2_log::load(p).unwrap_or_else(|e| panic!("{e}"));
            let goals = report::report(&log, true).unwrap().goals().unwrap();
            println!("{}: {goals:?}", log.name());
            (!goals.met()).then(|| format!("{}: {goals:?}", log.name()))
        })
        .collect();
    assert!(misses.is_empty(), "{misses:#?}");
}

/// A section restarts hysteresis' memory and the model's state starts at
/// the section's first error; a log of one section replays as before.
#[test]
fn a_single_section_replays_as_it_always_did() {
    let log =
        phd2_log::load(&data::data_dir().join("phd2-logs/performance_dataset03.txt")).unwrap();
    let one = replay::run(&log, &mut Hysteresis::phd2_baseline()).unwrap();
    assert_eq!(one.frames, 664);
    assert!((one.rms - 0.1588).abs() < 5e-5, "{}", one.rms);
    let r = replay::run_with(
        &log,
        &mut *replay::model_algorithm(Model::Mkgp),
        &Options::default(),
    )
    .unwrap();
    assert_eq!(r.sections.len(), 1);
    assert_eq!(r.sections[0].rms, r.whole.rms);
}

/// Log 04 in two pieces played in the other order, 10 min apart: the mount
/// slewed between them, and the hour angles the headers give (to 0.01 h,
/// as PHD2 writes them) tell the replay how far gear time moved.
#[test]
fn a_slew_shifts_gear_time_by_what_the_hour_angles_say() {
    let lines = nights::original("dataset04");
    let n = nights::rows(&lines).len();
    let mut late = Piece::new(3000..n);
    late.at_s = Some(0.0);
    let mut early = Piece::new(0..1500);
    early.at_s = Some(3000.0);
    let log = parse("slew04", &nights::night(&lines, &[late, early]));
    let (a, b) = (&log.sections[0], &log.sections[1]);
    // Gear time is the original's: a section's gear time beyond the
    // night's clock is its first frame's time there minus its time here.
    let orig =
        phd2_log::load(&data::data_dir().join("phd2-logs/performance_dataset04.txt")).unwrap();
    let beyond = |s: &phd2_log::Section| {
        let f = &s.frames[0];
        let there = orig.sections[0].frames.iter().find(|o| o.frame == f.frame);
        there.unwrap().time_s - (s.start_s + f.time_s)
    };
    let truth = beyond(b) - beyond(a);
    let restart = record(&log)
        .into_iter()
        .find_map(|c| match c {
            Call::Restart(r) => Some(r),
            _ => None,
        })
        .unwrap();
    let shift = restart.gear_shift_s.unwrap();
    // Two hour angles rounded to 36 s of gear time each.
    assert!((shift - truth).abs() < 40.0, "{shift} vs {truth}");
    assert!(truth < -3000.0, "{truth}");
}

/// MKGP's and PPEC's gains over hysteresis on `log` with `carry` and
/// `options`: the whole night's, the mean of its sections replayed alone,
/// and the worst section's within the night (MKGP), %.
fn gains(log: &GuideLog, carry: Carry, options: &Options) -> [f64; 4] {
    let run = |log: &GuideLog, m: Option<Model>| {
        let mut a: Box<dyn GuideAlgorithm> = match m {
            None => Box::new(Hysteresis::phd2_baseline()),
            Some(m) => models::carrying(
                m,
                Some(replay::CONTROL_GAIN),
                Some(replay::PREDICTION_GAIN),
                carry,
                Additions::ALL,
            ),
        };
        replay::run_with(log, &mut *a, options).unwrap()
    };
    let (h, p, m) = (
        run(log, None),
        run(log, Some(Model::Ppec)),
        run(log, Some(Model::Mkgp)),
    );
    let alone: Vec<f64> = h
        .sections
        .iter()
        .map(|s| {
            let one = replay::section_alone(log, s.section);
            replay::gain_pct(
                run(&one, Some(Model::Mkgp)).whole.rms,
                run(&one, None).whole.rms,
            )
        })
        .collect();
    let worst = h
        .sections
        .iter()
        .zip(&m.sections)
        .map(|(h, m)| replay::gain_pct(m.rms, h.rms))
        .fold(f64::INFINITY, f64::min);
    [
        replay::gain_pct(m.whole.rms, h.whole.rms),
        replay::gain_pct(p.whole.rms, h.whole.rms),
        alone.iter().sum::<f64>() / alone.len() as f64,
        worst,
    ]
}

/// The benchmark behind docs/results.md, "Nights of several sections":
/// each way of carrying the model across sections on nights cut from the
/// five logs (on the same target with pauses of 10 and 60 frames, and in
/// the reverse order, slews whose gear time the hour angles give to 36 s).
/// About two minutes; run with `--ignored --nocapture`.
#[test]
#[ignore]
fn carry_benchmark() {
    let carries = [
        Carry::Fresh,
        Carry::Continue,
        Carry::Restore,
        Carry::Search,
        Carry::Relearn,
        Carry::Pointing,
    ];
    let mut nights = Vec::new();
    for (name, parts) in CUTS.into_iter().chain([("dataset04", 8)]) {
        for gap in [10, 60] {
            nights.push((
                format!("{name} in {parts}, pauses of {gap}"),
                split(name, parts, gap),
            ));
        }
        let lines = nights::original(name);
        let n = nights::rows(&lines).len();
        let whole = split(name, parts, 10);
        let mut pieces: Vec<Piece> = Vec::new();
        let mut at = 0.0;
        for s in whole.sections.iter().rev() {
            let first = nights::rows(&lines)
                .iter()
                .position(|&i| lines[i].starts_with(&format!("{},", s.frames[0].frame)))
                .unwrap();
            let len = s.frames.len();
            let mut p = Piece::new(first..(first + len).min(n));
            p.at_s = Some(at);
            at += s.frames.last().unwrap().time_s - s.frames[0].time_s + 60.0;
            pieces.push(p);
        }
        nights.push((
            format!("{name} in {parts}, reversed (slews)"),
            parse(name, &nights::night(&lines, &pieces)),
        ));
    }
    println!("night | carry | MKGP % | PPEC % | MKGP alone, mean % | worst section %");
    let rows: Vec<String> = nights
        .par_iter()
        .flat_map(|(title, log)| {
            carries.par_iter().map(move |&c| {
                let [m, p, alone, worst] = gains(log, c, &Options::default());
                format!("{title} | {c:?} | {m:.2} | {p:.2} | {alone:.2} | {worst:.2}")
            })
        })
        .collect();
    for r in rows {
        println!("{r}");
    }
}

/// The benchmark behind docs/results.md's choice of what the replay tells
/// the model: each option alone on the five logs, and the time step on
/// logs with two frames of three (four of five) left out.
#[test]
#[ignore]
fn options_benchmark() {
    let base = Options::PERFORMANCE_TEST;
    let variants = [
        ("performance test", base),
        (
            "drops",
            Options {
                drops: true,
                ..base
            },
        ),
        (
            "pauses from 2.5 cadences",
            Options {
                pause_cadences: Some(2.5),
                ..base
            },
        ),
        (
            "pauses from 5 cadences",
            Options {
                pause_cadences: Some(5.0),
                ..base
            },
        ),
        (
            "dithers",
            Options {
                dithers: true,
                ..base
            },
        ),
        (
            "settling",
            Options {
                settling: true,
                ..base
            },
        ),
        (
            "from the first lock",
            Options {
                first_lock: true,
                ..base
            },
        ),
        (
            "cadence step",
            Options {
                time_step: TimeStep::Cadence,
                ..base
            },
        ),
        (
            "step to the next frame",
            Options {
                time_step: TimeStep::ToNext,
                ..base
            },
        ),
        ("night (default)", Options::default()),
    ];
    println!("options | MKGP % logs 01-05 | PPEC % logs 01-05");
    for (name, o) in variants {
        let (mkgp, ppec) = five_gains(|l| l.clone(), &o);
        println!("{name} | {mkgp} | {ppec}");
    }
    for keep in [3, 5] {
        for step in [
            TimeStep::Exposure,
            TimeStep::Cadence,
            TimeStep::ToNext,
            TimeStep::Frames,
        ] {
            let o = Options {
                time_step: step,
                ..base
            };
            let (mkgp, ppec) = five_gains(|l| one_in(l, keep), &o);
            println!("1 frame in {keep}, {step:?} | {mkgp} | {ppec}");
        }
    }
}

/// MKGP's and PPEC's gains % on logs 01-05, each first passed through
/// `cut`, as two comma-separated lists.
fn five_gains(cut: impl Fn(&GuideLog) -> GuideLog + Sync, o: &Options) -> (String, String) {
    let g: Vec<[f64; 4]> = ["01", "02", "03", "04", "05"]
        .par_iter()
        .map(|n| gains(&cut(&dataset(n)), Carry::default(), o))
        .collect();
    let col = |k: usize| {
        g.iter()
            .map(|x| format!("{:.2}", x[k]))
            .collect::<Vec<_>>()
            .join(", ")
    };
    (col(0), col(1))
}

/// Log `n` (01-05) as it is in data/phd2-logs.
fn dataset(n: &str) -> GuideLog {
    phd2_log::load(&data::data_dir().join(format!("phd2-logs/performance_dataset{n}.txt"))).unwrap()
}

/// `log` with only one frame in `k` kept, the corrections of those left
/// out added to the one kept before them (dithers folded in).
fn one_in(log: &GuideLog, k: usize) -> GuideLog {
    let mut out = log.clone();
    for s in &mut out.sections {
        let (_, c) = replay::measurements(s, false);
        s.frames = (0..s.frames.len())
            .step_by(k)
            .map(|i| {
                let mut f = s.frames[i].clone();
                f.ra_applied = c[i..(i + k).min(c.len())].iter().sum();
                f
            })
            .collect();
        s.events.clear();
    }
    out
}
