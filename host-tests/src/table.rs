//! The paper's table: residual RMS per case and noise level for the open
//! loop, the reactive guide algorithm (hysteresis 0.6), PPEC, MKGP (two
//! stages) and MKGP3 (three).

use crate::cases::Case;
use crate::closed_loop::{self, Conditions};
use crate::gp::trace::Traced;
use crate::gp::{Carry, GpAlgorithm};
use crate::guide_algorithm::{GuideAlgorithm, Hysteresis};
use crate::models::{self, Model};
use mkgp_mount::model::additions::Additions;
use rayon::prelude::*;

/// The noise levels of the table (px): noise-free, and 1 px (mean of seeds 1-3).
pub const NOISE_LEVELS: [f64; 2] = [0.0, 1.0];

#[derive(Debug, Clone, PartialEq)]
pub struct TableRow {
    pub case: String,
    pub noise_px: f64,
    pub open_loop: f64,
    pub reactive: f64,
    pub ppec: f64,
    pub mkgp: f64,
    pub mkgp3: f64,
}

/// What a column runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Column {
    Reactive,
    Model(Model),
}

/// A fresh algorithm for `column`, a model with its `additions` as given.
fn make(column: Column, additions: Additions) -> Box<dyn GuideAlgorithm> {
    match column {
        Column::Reactive => Box::new(Hysteresis::paper()),
        Column::Model(m) => models::carrying(m, None, None, Carry::default(), additions),
    }
}

/// Residual RMS of `column` on `case` with `sigma_px` of noise (0: one
/// noise-free run).
fn rms(case: &Case, sigma_px: f64, column: Column, additions: Additions) -> f64 {
    closed_loop::rms_at(case, sigma_px, || make(column, additions))
}

/// Residual RMS of `column` with `additions` on `case` in `conditions`,
/// over `seeds` ([`closed_loop::rms_in`]).
pub fn rms_in(
    case: &Case,
    sigma_px: f64,
    seeds: &[u64],
    conditions: &Conditions,
    column: Column,
    additions: Additions,
) -> f64 {
    closed_loop::rms_in(case, sigma_px, seeds, conditions, || {
        make(column, additions)
    })
}

/// One run of MKGP3 (the firmware's three stages) on `case` with
/// `sigma_px` of noise from `seed` (none at 0), the model's `additions` as
/// given: its residual RMS over t >= 3600 s and its trace
/// ([`crate::gp::trace`]), a row per frame.
pub fn traced_run(case: &Case, sigma_px: f64, seed: u64, additions: Additions) -> (f64, String) {
    let mut model = Traced::new(GpAlgorithm::<3>::new(None, None).with_additions(additions));
    let rms = closed_loop::run_in(case, &mut model, sigma_px, seed, &Conditions::PAPER);
    (rms, model.csv().to_string())
}

/// Compute the table, one row per case and noise level, in that order; the
/// closed-loop runs are spread over rayon's threads.
pub fn compute(cases: &[Case]) -> Vec<TableRow> {
    compute_with(cases, Additions::ALL)
}

/// One `column` of the table with the models' `additions` as given: its
/// RMS per case and noise level, in the table's order.
pub fn column_with(cases: &[Case], column: Column, additions: Additions) -> Vec<f64> {
    cells(cases)
        .into_par_iter()
        .map(|(case, noise_px)| rms(case, noise_px, column, additions))
        .collect()
}

/// The table's cells in its order: each case at each noise level.
pub fn cells(cases: &[Case]) -> Vec<(&Case, f64)> {
    cases
        .iter()
        .flat_map(|case| NOISE_LEVELS.map(|noise_px| (case, noise_px)))
        .collect()
}

/// [`compute`] with the models' `additions` as given.
pub fn compute_with(cases: &[Case], additions: Additions) -> Vec<TableRow> {
    cells(cases)
        .into_par_iter()
        .map(|(case, noise_px)| {
            let column = |c| rms(case, noise_px, c, additions);
            let ((reactive, ppec), (mkgp, mkgp3)) = rayon::join(
                || {
                    rayon::join(
                        || column(Column::Reactive),
                        || column(Column::Model(Model::Ppec)),
                    )
                },
                || {
                    rayon::join(
                        || column(Column::Model(Model::Mkgp)),
                        || column(Column::Model(Model::Mkgp3)),
                    )
                },
            );
            TableRow {
                case: case.name.clone(),
                noise_px,
                open_loop: closed_loop::open_loop_rms(case),
                reactive,
                ppec,
                mkgp,
                mkgp3,
            }
        })
        .collect()
}
