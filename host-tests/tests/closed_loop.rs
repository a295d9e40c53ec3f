//! The paper's closed loop reproduces the figures of docs/reference.md.

use host_tests::cases::{self, Case};
use host_tests::closed_loop::{
    mean_noisy_rms, open_loop_rms, run, Noise, DT, FRAMES, SCORE_FROM_S,
};
use host_tests::data;
use host_tests::gp::trace;
use host_tests::guide_algorithm::Hysteresis;
use host_tests::models::{self, Model};
use host_tests::table;
use mkgp_mount::model::additions::Additions;

fn cases() -> Vec<Case> {
    cases::load(&data::cases_file()).unwrap_or_else(|e| panic!("{e}"))
}

/// docs/reference.md: hysteresis 0.6, noise-free / 1 px mean of seeds 1-3.
const HYSTERESIS: [(&str, f64, f64); 8] = [
    ("C1", 0.332, 0.705),
    ("C2", 0.367, 0.723),
    ("C3", 0.410, 0.744),
    ("C4", 0.471, 0.772),
    ("C5", 0.661, 0.910),
    ("C6", 0.994, 1.178),
    ("C7", 1.049, 1.227),
    ("C8", 1.424, 1.541),
];

/// The paper's open-loop column.
const OPEN_LOOP: [(&str, f64); 8] = [
    ("C1", 8.634),
    ("C2", 9.028),
    ("C3", 9.166),
    ("C4", 9.019),
    ("C5", 9.478),
    ("C6", 10.436),
    ("C7", 9.661),
    ("C8", 10.604),
];

#[test]
fn hysteresis_figures() {
    let cases = cases();
    assert_eq!(cases.len(), HYSTERESIS.len());
    for (case, &(name, clean, noisy)) in cases.iter().zip(&HYSTERESIS) {
        assert_eq!(case.name, name);
        let c = run(case, &mut Hysteresis::paper(), Noise::None);
        let n = mean_noisy_rms(case, 1.0, Hysteresis::paper);
        // To 3 decimals: 15 of the 16 round to the published figure; C4
        // noisy is 0.77252, 0.00052 from its published 0.772 (the published
        // value was presumably truncated or computed in another order), so
        // the bound is 0.0006 rather than 0.0005.
        assert!(
            (c - clean).abs() < 0.0005,
            "{name} noise-free: {c:.5} vs {clean}"
        );
        assert!(
            (n - noisy).abs() < 0.0006,
            "{name} noisy: {n:.5} vs {noisy}"
        );
    }
}

#[test]
fn open_loop_matches_the_paper() {
    let cases = cases();
    for (case, &(name, paper)) in cases.iter().zip(&OPEN_LOOP) {
        assert_eq!(case.name, name);
        let r = open_loop_rms(case);
        // docs/reference.md: the cases match the paper's open loop within 0.4 %.
        assert!((r / paper - 1.0).abs() < 0.004, "{name}: {r:.4} vs {paper}");
    }
}

#[test]
fn open_loop_of_c1_exactly() {
    // C1 is a pure sinusoid + drift: 8.634 in the paper and here.
    assert_eq!(format!("{:.3}", open_loop_rms(&cases()[0])), "8.634");
}

/// `guide-sim table --trace`: a row per frame of the paper's loop, the run
/// itself unchanged by the tracing, the error the model was given the
/// residual the score is taken over (noise-free), and C8's 110 s stage
/// found and gated in by the end.
#[test]
fn the_models_trace_follows_the_frames() {
    let cases = cases();
    let c8 = cases.iter().find(|c| c.name == "C8").unwrap();
    let (rms, csv) = table::traced_run(c8, 0.0, 1, Additions::ALL);
    let untraced = run(
        c8,
        &mut *models::algorithm(Model::Mkgp3, None, None),
        Noise::None,
    );
    assert_eq!(rms, untraced);
    assert_eq!(csv.lines().next(), Some(trace::header(3).as_str()));
    let rows: Vec<Vec<f64>> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|f| f.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), FRAMES);
    for (k, r) in rows.iter().enumerate() {
        assert_eq!(r.len(), 10, "{r:?}");
        assert_eq!(r[0], k as f64 * DT);
        assert_eq!(r[5], 1.0, "the worm's gate: {r:?}");
    }
    let scored: Vec<f64> = rows
        .iter()
        .filter(|r| r[0] >= SCORE_FROM_S)
        .map(|r| r[1])
        .collect();
    let traced = (scored.iter().map(|x| x * x).sum::<f64>() / scored.len() as f64).sqrt();
    // The trace prints the error to 0.0001 px.
    assert!((traced - rms).abs() < 1e-4, "{traced} {rms}");
    let last = rows.last().unwrap();
    let found = [(last[6], last[7]), (last[8], last[9])]
        .iter()
        .any(|&(p, g)| (p / 110.0 - 1.0).abs() < 0.005 && g == 1.0);
    assert!(found, "{last:?}");
}
