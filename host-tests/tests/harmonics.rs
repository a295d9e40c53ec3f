//! Issue 10, "Stages near a harmonic": on the cases H1-H11
//! (`data/harmonic_cases.csv`: a worm with a second gear 2-5 % off its
//! 2nd, 3rd or 4th harmonic, with and without true harmonics of the worm)
//! the two-stage model admits the near-harmonic gear once the data resolves
//! it (docs/model.md, "Stages near a harmonic") and beats the single-kernel
//! model (N = 1, which is what the model gave there before): the goal,
//! MKGP below PPEC on every resolvable case, noise-free and with 1 px
//! (mean of seeds 1-3). Where there is nothing to admit (H3 and H8: a gear
//! too close to resolve in the run; H10 and H11: true harmonics only) MKGP
//! stays at PPEC.

use host_tests::cases;
use host_tests::closed_loop;
use host_tests::data::data_dir;
use host_tests::models::{self, Model};
use rayon::prelude::*;

/// Where nothing is to be admitted: MKGP at most PPEC + this (measured
/// equal to 0.001 px).
const UNCHANGED_PX: f64 = 0.002;
/// The cases with nothing to admit within the 3 h run.
const NOTHING_TO_ADMIT: [&str; 4] = ["H3", "H8", "H10", "H11"];

fn rms(case: &cases::Case, noise_px: f64, model: Model) -> f64 {
    closed_loop::rms_at(case, noise_px, || models::algorithm(model, None, None))
}

#[test]
fn near_harmonic_stages_beat_one_stage_and_true_harmonics_cost_nothing() {
    let cases =
        cases::load(&data_dir().join("harmonic_cases.csv")).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(cases.len(), 11);
    let runs: Vec<(&cases::Case, f64)> = cases.iter().flat_map(|c| [(c, 0.0), (c, 1.0)]).collect();
    let failures: Vec<String> = runs
        .par_iter()
        .filter_map(|&(case, noise_px)| {
            let (one, two) = rayon::join(
                || rms(case, noise_px, Model::Ppec),
                || rms(case, noise_px, Model::Mkgp),
            );
            let (bound, fails) = if NOTHING_TO_ADMIT.contains(&case.name.as_str()) {
                ("at most ppec + 0.002", two > one + UNCHANGED_PX)
            } else {
                ("below ppec", two >= one)
            };
            println!(
                "{} noise {noise_px}: ppec {one:.4}, mkgp {two:.4} (ratio {:.3}, bound {bound})",
                case.name,
                two / one
            );
            fails.then(|| {
                format!(
                    "{} noise {noise_px}: mkgp {two:.4} not {bound} {one:.4}",
                    case.name
                )
            })
        })
        .collect();
    assert!(failures.is_empty(), "{failures:#?}");
}
