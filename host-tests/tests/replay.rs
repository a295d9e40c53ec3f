//! The PHD2 logs and the causal replay against INDIGO's reference traces
//! (`indigo_ppec_dataset0N.csv`: INDIGO's single-kernel model replayed
//! causally with control gain 0.7, prediction gain 0.5), and what becomes
//! of a log with values no guide log holds (issue 26).

mod common;

use common::bad_logs::{self, RA_GUIDE, RA_RAW, TIME};
use common::TraceRow;
use host_tests::data::{self, Error};
use host_tests::guide_algorithm::{GuideAlgorithm, Hysteresis};
use host_tests::models::Model;
use host_tests::phd2_log::{self, GuideLog};
use host_tests::replay;
use mkgp_mount::model::guider::{Guider, GuiderConfig};
use std::path::Path;

const LOGS: [&str; 5] = [
    "dataset01",
    "dataset02",
    "dataset03",
    "dataset04",
    "dataset05",
];

fn log(name: &str) -> GuideLog {
    let path = data::data_dir()
        .join("phd2-logs")
        .join(format!("performance_{name}.txt"));
    phd2_log::load(&path).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn logs_parse() {
    // (frames with RARawDistance, exposure s, dithers, first dither X)
    let want = [
        (808, 2.0, 10, -4.987),
        (952, 3.0, 0, 0.0),
        (666, 3.0, 0, 0.0),
        (4286, 2.0, 1, 0.0),
        (3520, 0.5, 3, 2.0),
    ];
    for (name, (frames, exposure, dithers, x)) in LOGS.iter().zip(want) {
        let l = log(name);
        assert_eq!(l.sections.len(), 1, "{name}");
        let s = &l.sections[0];
        assert_eq!(s.frames.len(), frames, "{name}");
        assert_eq!(s.exposure_s, exposure, "{name}");
        let d: Vec<(usize, f64, f64)> = s.dithers().collect();
        assert_eq!(d.len(), dithers, "{name}");
        if let Some(&(_, first, _)) = d.first() {
            assert_eq!(first, x, "{name}");
        }
    }
}

/// `log` replayed as INDIGO and PHD2 replay their performance test (a
/// dither's row measures the lock's move: `Options::first_lock` off).
fn performance_test(log: &GuideLog, algorithm: &mut dyn GuideAlgorithm) -> replay::ReplayResult {
    replay::run_with(log, algorithm, &replay::Options::PERFORMANCE_TEST)
        .unwrap()
        .whole
}

/// Plays back INDIGO's outputs and records what the replay showed it.
struct Scripted<'a> {
    trace: &'a [TraceRow],
    k: usize,
    worst: f64,
    exposure: f64,
}

impl GuideAlgorithm for Scripted<'_> {
    fn step(&mut self, t: f64, measured: f64, snr: f64, dt: f64) -> f64 {
        let row = self.trace[self.k];
        assert_eq!(
            (t, snr, dt),
            (row.time_s, row.snr, self.exposure),
            "frame {}",
            self.k
        );
        self.worst = self.worst.max((measured - row.input_px).abs());
        self.k += 1;
        -row.output_correction_px
    }
}

#[test]
fn replay_reproduces_indigo_traces_and_improvements() {
    // docs/reference.md: INDIGO's improvement over hysteresis 0.7, in %.
    let indigo_gain = [0.27, 0.10, 12.26, 8.31, 2.22];
    // Our hysteresis baseline RMS (px), pinned.
    let hysteresis_rms = [0.4969, 0.5302, 0.1588, 0.1471, 1.0641];
    for (i, name) in LOGS.iter().enumerate() {
        let l = log(name);
        let trace = common::trace(name);
        assert_eq!(trace.len(), l.frame_count() - 2, "{name}: n - 2 frames");
        let mut scripted = Scripted {
            trace: &trace,
            k: 0,
            worst: 0.0,
            exposure: l.sections[0].exposure_s,
        };
        let model = performance_test(&l, &mut scripted);
        assert_eq!(scripted.k, trace.len());
        assert!(
            scripted.worst < 1e-12,
            "{name}: state differs from INDIGO's input by {:e}",
            scripted.worst
        );
        let hyst = performance_test(&l, &mut Hysteresis::phd2_baseline());
        assert_eq!(hyst.frames, trace.len());
        let gain = replay::gain_pct(model.rms, hyst.rms);
        assert!(
            (gain - indigo_gain[i]).abs() < 0.005,
            "{name}: gain {gain:.3} % vs {}",
            indigo_gain[i]
        );
        assert!(
            (hyst.rms - hysteresis_rms[i]).abs() < 5e-5,
            "{name}: hysteresis {:.5}",
            hyst.rms
        );
    }
}

#[test]
fn replay_needs_three_frames() {
    let mut l = log("dataset03");
    l.sections[0].frames.truncate(2);
    let e = replay::run(&l, &mut Hysteresis::phd2_baseline()).unwrap_err();
    assert!(e.to_string().contains("at least 3"), "{e}");
}

/// PHD2's own GP test (`guide_performance_test.cpp` in PHD2's
/// `contributions/MPI_IS_gaussian_process`) replays the logs as we do, but
/// its GP guider's control is proportional, 0.7 x (none below 0.2 px), plus
/// 0.5 x the prediction from the first frames on: no hysteresis term and no
/// blend. It is still scored against hysteresis 0.7 (hysteresis 0.1). That
/// law, with our model's prediction (the model learns as in `frame`; only
/// the control differs).
struct Phd2TestLaw<const N: usize> {
    guider: Box<Guider<f64, N>>,
    applied: f64,
}

impl<const N: usize> Phd2TestLaw<N> {
    fn new() -> Self {
        Phd2TestLaw {
            guider: Box::new(Guider::new(GuiderConfig::default())),
            applied: 0.0,
        }
    }
}

impl<const N: usize> GuideAlgorithm for Phd2TestLaw<N> {
    fn step(&mut self, t: f64, measured: f64, snr: f64, dt: f64) -> f64 {
        let gear = self.applied + measured;
        self.guider.observe(t, Some(gear), self.applied, snr, dt);
        let reactive = if measured.abs() < 0.2 {
            0.0
        } else {
            0.7 * measured
        };
        let control = reactive + 0.5 * self.guider.prediction();
        self.applied += control;
        control
    }
}

/// What PHD2's test measures on log 05 (it reports 3.81 %; our MKGP with
/// the hysteresis term alone 2.59 %): mostly the reactive law, which alone
/// gains more there than PHD2's GP guider; under the same law our model is
/// ahead, and on logs 01, 02 and 04 that law loses to the blend with
/// hysteresis (docs/model.md, "PHD2's own GP test on the logs").
#[test]
fn phd2_gp_test_law() {
    // (log, proportional 0.7 alone, PHD2's law with N = 1, with N = 2): gain % over hysteresis 0.7.
    let want = [
        ("dataset01", -0.49, -0.65, 0.16),
        ("dataset02", -0.50, -1.48, -1.69),
        ("dataset03", 6.18, 12.30, 12.30),
        ("dataset04", 0.88, 8.39, 8.45),
        ("dataset05", 3.97, 4.03, 4.43),
    ];
    for (name, proportional, n1, n2) in want {
        let l = log(name);
        let hyst = performance_test(&l, &mut Hysteresis::phd2_baseline()).rms;
        let gain = |a: &mut dyn GuideAlgorithm| replay::gain_pct(performance_test(&l, a).rms, hyst);
        let got = (
            gain(&mut Hysteresis::new(0.7, 0.0, 0.2)),
            gain(&mut Phd2TestLaw::<1>::new()),
            gain(&mut Phd2TestLaw::<2>::new()),
        );
        println!(
            "{name}: proportional {:.2} %, PHD2's law N = 1 {:.2} %, N = 2 {:.2} %",
            got.0, got.1, got.2
        );
        for (g, w) in [(got.0, proportional), (got.1, n1), (got.2, n2)] {
            assert!(
                (g - w).abs() < 0.005,
                "{name}: {got:?} vs {:?}",
                (proportional, n1, n2)
            );
        }
    }
}

/// Issue 10, section 6: with the reactive law chosen by measurement
/// (docs/model.md), MKGP gains more on log 05 than PHD2's own GP test
/// reports for PHD2's guider (3.81 %), and the logs where the hysteresis
/// term is better keep it.
#[test]
fn mkgp_chooses_the_reactive_law() {
    // MKGP's gain % over hysteresis 0.7 (`guide-sim replay`; with the
    // frames PHD2 lost and log 04's pause told to the model, and measured
    // from the first lock, issue 27).
    let want = [1.27, 1.07, 12.32, 9.96, 4.00];
    for (name, want) in LOGS.iter().zip(want) {
        let gain = replay::gain_over_hysteresis(&log(name), Model::Mkgp).unwrap();
        assert!(
            (gain - want).abs() < 0.005,
            "{name}: {gain:.3} % vs {want} %"
        );
    }
}

/// What the replay makes of `log`, for a failure message.
fn figures(log: &GuideLog) -> String {
    let rms = |r: Result<replay::ReplayResult, Error>| r.map(|r| r.rms);
    format!(
        "{} frames, hysteresis RMS {:?} px, MKGP RMS {:?} px",
        log.frame_count(),
        rms(replay::run(log, &mut Hysteresis::phd2_baseline())),
        rms(replay::run_model(log, Model::Mkgp)),
    )
}

/// The error `bad` must get: at its first absurd line, about `what`. An
/// accepted log fails the test with the figures its replay gives.
fn assert_refused(bad: &bad_logs::BadLog, what: &str) {
    match phd2_log::parse(&bad.text, Path::new("bad.txt")) {
        Ok(log) => panic!("{what}: accepted, {}", figures(&log)),
        Err(e) => {
            assert_eq!(e.line, Some(bad.line), "{what}: {e}");
            assert!(e.message.starts_with(what), "{e}");
        }
    }
}

/// Issue 26, item 5: one value of 1e300 gave an RMS of `inf` and gains of
/// NaN. No camera frame holds such a distance, no guiding run such a time.
#[test]
fn a_value_of_1e300_is_refused_naming_its_line() {
    for (col, what) in [
        (RA_RAW, "RARawDistance"),
        (RA_GUIDE, "RAGuideDistance"),
        (TIME, "Time"),
    ] {
        assert_refused(&bad_logs::value(col, "1e300"), what);
    }
}

/// Issue 26, item 5: `DITHER by 1e300` gave an RMS of `inf`.
#[test]
fn a_dither_by_1e300_is_refused_naming_its_line() {
    assert_refused(&bad_logs::dither("1e300"), "DITHER x");
}

/// Issue 26, item 5: RARawDistance 1e6 in 12 rows gave an RMS of 172,479
/// px (163,546 px on this log).
#[test]
fn a_raw_distance_of_1e6_is_refused_naming_its_line() {
    assert_refused(&bad_logs::raw_1e6_in_12_rows(), "RARawDistance");
}

/// Issue 26, item 5: `Time` running backwards through a section gave the
/// models 15.5 px against hysteresis 0.48 px (4.3 px against 0.16 px here).
#[test]
fn time_running_backwards_is_refused_naming_its_line() {
    assert_refused(&bad_logs::time_backwards(), "Time");
}

/// Issue 26, item 5: `Exposure = 1e300 ms` was accepted.
#[test]
fn an_exposure_of_1e300_ms_is_refused_naming_its_line() {
    assert_refused(&bad_logs::exposure_1e300(), "Exposure");
}

/// A correction thousands of px larger than the error it corrects is not
/// what moved the mount (a guide algorithm corrects what it measured), yet
/// the replay would take it for the gear's own motion. Refused at its frame,
/// whether the row's RAGuideDistance or a dither before the row says so.
#[test]
fn a_correction_far_beyond_the_error_is_refused_naming_its_line() {
    assert_refused(&bad_logs::value(RA_GUIDE, "5000"), "RAGuideDistance");
    let mut dither = bad_logs::dither("5000");
    dither.line += 1; // the frame after it
    assert_refused(&dither, "RAGuideDistance");
}

/// A star measured thousands of px from where it was a frame before is
/// none PHD2 found: it looks for the star only within its search region.
/// Such a row is a frame the guider lost, exactly as the DROP row PHD2
/// writes for one.
#[test]
fn a_star_beyond_the_search_region_is_a_dropped_frame() {
    let (jumps, drops) = bad_logs::jumps_and_drops(5000.0);
    let parse =
        |text: &str| phd2_log::parse(text, Path::new("x.txt")).unwrap_or_else(|e| panic!("{e}"));
    let (jumps, drops) = (parse(&jumps), parse(&drops));
    assert_eq!(
        jumps.frame_count(),
        drops.frame_count(),
        "jumps: {}; drops: {}",
        figures(&jumps),
        figures(&drops)
    );
    assert_eq!(jumps, drops);
}
