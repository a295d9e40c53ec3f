//! The targets for the model, as the simulators measure them:
//! - `guide-sim table`: every MKGP cell at most the paper's MKGP figure
//!   + 2 % (on C4 noise-free, where INDIGO's own PPEC gives 0.194 with these
//!   case definitions against the paper's 0.180, at most PPEC + 2 %), and on
//!   C1 and C4 MKGP within 0.005 px of PPEC;
//! - `guide-sim replay`: the MKGP gain over hysteresis at least INDIGO's
//!   on each of the PHD2 logs 01-05.

use host_tests::cases;
use host_tests::data::{cases_file, phd2_logs};
use host_tests::guide_algorithm::Hysteresis;
use host_tests::models::{self, Model};
use host_tests::phd2_log;
use host_tests::replay;
use host_tests::table;

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
        let mut bar = 1.02 * if r.noise_px == 0.0 { free } else { noisy };
        if r.case == "C4" && r.noise_px == 0.0 {
            bar = bar.max(1.02 * r.ppec);
        }
        println!(
            "{} noise {}: mkgp {:.4} (bar {:.4}), ppec {:.4}",
            r.case, r.noise_px, r.mkgp, bar, r.ppec
        );
        if r.mkgp > bar {
            failures.push(format!(
                "{} noise {}: {:.4} > {:.4}",
                r.case, r.noise_px, r.mkgp, bar
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

#[test]
fn replay_gains_at_least_indigo() {
    let logs = phd2_logs().unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(logs.len(), INDIGO_GAIN_PCT.len());
    for (path, indigo) in logs.iter().zip(INDIGO_GAIN_PCT) {
        let log = phd2_log::load(path).unwrap_or_else(|e| panic!("{e}"));
        let hyst = replay::run(&log, &mut Hysteresis::phd2_baseline()).unwrap();
        let mkgp = replay::run(
            &log,
            &mut *models::algorithm(Model::Mkgp, Some(0.7), Some(0.5)),
        )
        .unwrap();
        let gain = replay::gain_pct(mkgp.rms, hyst.rms);
        println!("{}: MKGP gain {gain:.3} % (INDIGO {indigo} %)", log.name());
        // INDIGO's figures are rounded to 0.01 %.
        assert!(
            gain >= indigo - 0.005,
            "{}: {gain:.3} % < {indigo} %",
            log.name()
        );
    }
}
