//! Randomized tests of the safety properties, from the one test RNG
//! (`mkgp_mount::testing::SplitMix64`, fixed seeds). Their size suits CI;
//! `MKGP_RANDOMIZED_SCALE=K` multiplies the iteration counts by K for a
//! longer run (host-tests/README.md).

mod common;

use host_tests::data;
use host_tests::guide_algorithm::{GuideAlgorithm, Hysteresis};
use host_tests::models::Model;
use host_tests::phd2_log::{self, limits::MAX_DISTANCE_PX};
use host_tests::replay::{self, Options};
use mkgp_mount::model::guider::{Guider, GuiderConfig};
use mkgp_mount::model::numeric::scalar::Scalar;
use mkgp_mount::mount::st4::{Axis, Line, St4, St4Counters, St4Event};
use mkgp_mount::testing::SplitMix64;
use std::f64::consts::PI;
use std::path::Path;

use host_tests::noise::randomized_scale as scale;

/// Edges of distinct lines at one instant, then a poll at that instant or
/// not.
struct Instant {
    at_us: u64,
    edges: Vec<(Line, bool)>,
    poll: bool,
}

/// A random history of ST4 edges on a coarse time grid, so that edges,
/// confirmations (`glitch_us` a multiple of the grid) and cuts at the cap
/// often fall on the same microsecond.
fn random_history(rng: &mut SplitMix64, quantum: u64) -> Vec<Instant> {
    let mut at_us = 0;
    (0..60)
        .map(|_| {
            at_us += quantum * rng.below(12);
            let mut lines = Line::ALL.to_vec();
            let n = 1 + rng.below(4) as usize;
            let edges = (0..n)
                .map(|_| {
                    let line = lines.remove(rng.below(lines.len() as u64) as usize);
                    (line, rng.below(2) == 1)
                })
                .collect();
            Instant {
                at_us,
                edges,
                poll: rng.below(2) == 1,
            }
        })
        .collect()
}

/// Runs a history, the edges of each instant in the order `order` gives,
/// and returns the events of each axis and the counters. (Events of the two
/// axes at the same microsecond may come in either order: each axis' pulses
/// are applied on their own.)
fn run(
    st4: &mut St4,
    history: &[Instant],
    mut order: impl FnMut(&mut Vec<(Line, bool)>),
) -> ([Vec<St4Event>; 2], St4Counters) {
    let mut events = Vec::new();
    let mut drain = |st4: &mut St4, now| {
        while let Some(ev) = st4.poll(now) {
            events.push(ev);
        }
    };
    for instant in history {
        let mut edges = instant.edges.clone();
        order(&mut edges);
        for (line, asserted) in edges {
            st4.edge(line, asserted, instant.at_us);
        }
        if instant.poll {
            drain(st4, instant.at_us);
        }
    }
    let end = history.last().map_or(0, |i| i.at_us);
    drain(st4, end + 100_000_000);
    let of_axis = |axis| {
        events
            .iter()
            .filter(|ev| match ev {
                St4Event::PulseStart { axis: a, .. } | St4Event::PulseEnd { axis: a, .. } => {
                    *a == axis
                }
            })
            .copied()
            .collect()
    };
    ([of_axis(Axis::Ra), of_axis(Axis::Dec)], st4.counters())
}

/// F7: each axis' events and the counters of the ST4 state machine do not depend
/// on the order in which edges of the same microsecond arrive (once cut at
/// the cap or normal end depended on it). Every history is run in its own
/// order and in four shuffled ones.
#[test]
fn st4_same_instant_edges_in_any_order() {
    let mut rng = SplitMix64::new(7);
    const QUANTUM: u64 = 1_000;
    for history_no in 0..300 * scale() {
        let glitch_us = QUANTUM * rng.below(3);
        let glitch_us = glitch_us.max(QUANTUM) as u32;
        let cap_us = (QUANTUM * (5 + rng.below(20))) as u32;
        let history = random_history(&mut rng, QUANTUM);
        let reference = run(&mut St4::new(glitch_us, cap_us), &history, |_| {});
        for _ in 0..4 {
            let shuffled = run(&mut St4::new(glitch_us, cap_us), &history, |edges| {
                for i in (1..edges.len()).rev() {
                    edges.swap(i, rng.below(i as u64 + 1) as usize);
                }
            });
            assert_eq!(shuffled, reference, "history {history_no}");
        }
    }
}

/// The gear error of the guider storms (px): one sinusoid and a drift.
fn gear(t: f64) -> f64 {
    9.0 * (2.0 * PI * t / 432.0).sin() + 0.0008 * t
}

/// One bad call to the guider at frame time `t` (s), chosen at random:
/// bad inputs, bad times (not finite, back, far ahead), bad time steps, dark
/// frames, absurd dithers. Returns the control it gave.
fn bad_call<S: Scalar, const N: usize>(
    g: &mut Guider<S, N>,
    rng: &mut SplitMix64,
    t: f64,
    measured: f64,
) -> S {
    let s = S::from_f64;
    let (snr, dt) = (s(10.0), s(2.0));
    let far = 10f64.powi(2 + rng.below(10) as i32);
    match rng.below(8) {
        0 => g.frame(
            t,
            s([f64::NAN, f64::INFINITY, -1e30, 150.0][rng.below(4) as usize]),
            snr,
            dt,
        ),
        1 => g.frame(
            [f64::NAN, f64::NEG_INFINITY][rng.below(2) as usize],
            s(measured),
            snr,
            dt,
        ),
        2 => g.frame(t + far, s(measured), snr, dt),
        3 => g.frame(t - 1000.0 * rng.uniform(), s(measured), snr, dt),
        4 => g.frame(
            t,
            s(measured),
            snr,
            s([1e6, f64::NAN, -1.0][rng.below(3) as usize]),
        ),
        5 => g.dark_frame(t, s(far)),
        6 => {
            g.dithered(s(far), s(1.0 / far));
            g.frame(t, s(measured), snr, dt)
        }
        _ => g.frame(t, s(measured), snr, s(0.0)),
    }
}

/// A guider in a closed loop on [`gear`], frames every 2 s, with a bad call
/// in place of one frame in twenty from 1200 s to 3 h: every control is
/// finite and within `max_input`, and an hour of good frames afterwards
/// brings the residual back to where guiding it is.
fn guider_storm<S: Scalar, const N: usize>(seed: u64) {
    let mut rng = SplitMix64::new(seed);
    let mut g = Box::new(Guider::<S, N>::new(GuiderConfig::default()));
    let max_input = g.config().max_input.to_f64();
    let (mut t, mut applied) = (0.0, 0.0);
    let (mut sum_sq, mut n) = (0.0, 0);
    while t < 4.0 * 3600.0 {
        let measured = gear(t) - applied;
        let storm = (1200.0..3.0 * 3600.0).contains(&t) && rng.below(20) == 0;
        let c = if storm {
            bad_call(&mut g, &mut rng, t, measured)
        } else {
            g.frame(
                t,
                S::from_f64(measured),
                S::from_f64(10.0),
                S::from_f64(2.0),
            )
        };
        let c = c.to_f64();
        assert!(
            c.is_finite() && c.abs() <= max_input,
            "seed {seed}: control {c} at {t} s"
        );
        if t >= 3.5 * 3600.0 {
            sum_sq += measured * measured;
            n += 1;
        }
        applied += c;
        t += 2.0;
    }
    let rms = (sum_sq / n as f64).sqrt();
    assert!(
        rms < 0.5,
        "seed {seed}: residual RMS {rms} px after the storm"
    );
}

#[test]
fn guider_storms_f32_n2() {
    for seed in 0..2 * scale() {
        guider_storm::<f32, 2>(seed);
    }
}

#[test]
fn guider_storms_f64_n1() {
    for seed in 0..2 * scale() {
        guider_storm::<f64, 1>(seed);
    }
}

/// What a mutation may write in place of a field: absurd, negative, not a
/// number, empty, or a plausible value.
fn random_field(rng: &mut SplitMix64) -> String {
    let magnitude = 10f64.powi(rng.below(12) as i32 - 3);
    match rng.below(8) {
        0 => [
            "1e300", "-1e300", "1e6", "-1e6", "nan", "inf", "-inf", "1e-300",
        ][rng.below(8) as usize]
            .into(),
        1 => String::new(),
        2 => "x1.5".into(),
        3 => format!("{:.3}", -magnitude * rng.uniform()),
        _ => format!("{:.3}", magnitude * rng.f64_in(-1.0, 1.0)),
    }
}

/// One random change to a log's lines, of the kinds a corrupt or hand-made
/// log has: a field replaced, a line deleted, repeated, swapped with the
/// next or cut short, a DITHER or SET LOCK POSITION line inserted, the
/// exposure changed.
fn mutate(rng: &mut SplitMix64, lines: &mut Vec<String>) {
    let i = rng.below(lines.len() as u64) as usize;
    match rng.below(8) {
        0 | 1 => {
            let mut fields: Vec<String> = lines[i].split(',').map(str::to_owned).collect();
            let k = rng.below(fields.len() as u64) as usize;
            fields[k] = random_field(rng);
            lines[i] = fields.join(",");
        }
        2 => {
            lines.remove(i);
        }
        3 => lines.insert(i, lines[i].clone()),
        4 => {
            let j = (i + 1).min(lines.len() - 1);
            lines.swap(i, j);
        }
        5 => {
            let cut = rng.below(lines[i].len() as u64 + 1) as usize;
            lines[i].truncate(cut);
        }
        6 => {
            let (x, y) = (random_field(rng), random_field(rng));
            let line = if rng.below(2) == 0 {
                format!("INFO: DITHER by {x}, {y}, new lock pos = 444.003, 198.480")
            } else {
                "INFO: SET LOCK POSITION, new lock pos = 444.003, 198.480".into()
            };
            lines.insert(i, line);
        }
        _ => {
            if let Some(e) = lines.iter_mut().find(|l| l.starts_with("Exposure =")) {
                *e = format!("Exposure = {} ms", random_field(rng));
            }
        }
    }
}

/// Random mutations of a real log (its first 200 frames): the parser and
/// the replay never panic, and each mutated log is either refused with an
/// error naming its line (or what the whole file lacks) or replayed into
/// finite figures within the camera frame the parser's limits allow.
#[test]
fn phd2_log_mutations() {
    let text = common::bad_logs::dataset03();
    let lines: Vec<String> = text.lines().map(str::to_owned).collect();
    let end = lines.iter().position(|l| l.starts_with("201,")).unwrap();
    let mut rng = SplitMix64::new(26);
    for iteration in 0..150 * scale() {
        let mut log = lines[..end].to_vec();
        for _ in 0..1 + rng.below(3) {
            mutate(&mut rng, &mut log);
        }
        check_mutated(iteration, &lines, &log);
    }
}

/// One random change to a night's structure and headers, of the kinds a
/// corrupt or hand-made log has: a section's begin, end or a calibration
/// inserted (with a date that may be garbled), or a header line of random
/// value (exposure, pixel scale, the mount's rate, the pointing).
fn mutate_night(rng: &mut SplitMix64, lines: &mut Vec<String>) {
    let i = rng.below(lines.len() as u64) as usize;
    let field = random_field(rng);
    let date = match rng.below(3) {
        0 => format!("2026-01-28 {:02}:{:02}:00", rng.below(30), rng.below(70)),
        1 => format!("{field}-01-28 18:00:00"),
        _ => "2026-01-28 18:35:00".into(),
    };
    let side = ["East", "West", "Unknown", &field][rng.below(4) as usize].to_string();
    let line = match rng.below(9) {
        0 => format!("Guiding Begins at {date}"),
        1 => format!("Guiding Ends at {date}"),
        2 => format!("Calibration Begins at {date}"),
        3 => "Calibration complete, mount = M.".into(),
        4 => format!("Exposure = {field} ms"),
        5 => format!("Pixel scale = {field} arc-sec/px, Binning = 1"),
        6 => format!("Mount = M, connected, xRate = {field}, yRate = 1"),
        7 => format!(
            "RA = {field} hr, Dec = {} deg, Hour angle = {} hr, Pier side = {side}",
            random_field(rng),
            random_field(rng)
        ),
        _ => format!("X guide algorithm = {field}, Control gain = 0.6"),
    };
    lines.insert(i, line);
}

/// Random changes to a real night (the first sections of the public night
/// in data/phd2-nights: short sections, a calibration, a slew), to its rows
/// and to its structure: the parser and the replay of every section never
/// panic, and a mutated night is refused naming a line (or what the whole
/// file lacks) or replayed into finite figures within the camera frame, the
/// whole night's and each section's.
#[test]
fn phd2_night_mutations() {
    let path = data::night_logs().unwrap().remove(0);
    let text = data::read_text(&path).unwrap();
    let lines: Vec<String> = text.lines().map(str::to_owned).collect();
    let end = lines
        .iter()
        .position(|l| l.starts_with("Guiding Begins at 2026-01-28 18:50:00"))
        .unwrap();
    let mut rng = SplitMix64::new(27);
    for iteration in 0..100 * scale() {
        let mut log = lines[..end].to_vec();
        for _ in 0..1 + rng.below(4) {
            if rng.below(2) == 0 {
                mutate_night(&mut rng, &mut log);
            } else {
                mutate(&mut rng, &mut log);
            }
        }
        check_mutated(iteration, &lines, &log);
    }
}

/// A mutated log (`log`, made from `original`) is refused with an error
/// naming its line (or what the whole file lacks), or replayed by hysteresis
/// and MKGP into finite figures within the camera frame the parser's limits
/// allow: the whole log's and each section's.
fn check_mutated(iteration: u64, original: &[String], log: &[String]) {
    let changed: Vec<&String> = log.iter().filter(|l| !original.contains(l)).collect();
    let parsed = match phd2_log::parse(&log.join("\n"), Path::new("mutated.txt")) {
        Ok(parsed) => parsed,
        Err(e) => {
            assert!(
                e.line.is_some_and(|n| n <= log.len()) || e.message.starts_with("no "),
                "iteration {iteration}: {e}; changed lines {changed:?}"
            );
            return;
        }
    };
    for (name, mut algorithm) in [
        (
            "hysteresis",
            Box::new(Hysteresis::phd2_baseline()) as Box<dyn GuideAlgorithm>,
        ),
        ("MKGP", replay::model_algorithm(Model::Mkgp)),
    ] {
        match replay::run_with(&parsed, &mut *algorithm, &Options::default()) {
            Ok(r) => {
                let sections = r.sections.iter().map(|s| (s.rms, s.frames));
                for (rms, frames) in std::iter::once((r.whole.rms, r.whole.frames)).chain(sections)
                {
                    assert!(
                        rms.is_finite() && rms <= MAX_DISTANCE_PX,
                        "iteration {iteration}: {name} RMS {rms} px over {frames} frames; changed lines {changed:?}"
                    );
                }
            }
            Err(e) => assert!(
                e.message.contains("at least 3"),
                "iteration {iteration}: {e}; changed lines {changed:?}"
            ),
        }
    }
}
