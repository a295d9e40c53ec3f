//! What a restored snapshot must hold besides its checksum: the bounds the
//! model learns within, under the configuration it is restored into. A
//! record whose checksum is right but whose values no learning could have
//! produced (a writer's bug, a record of another mount) is refused whole
//! before anything is used, and the model learns again from its prior.

use crate::model::gp::grid::CELL_S;
use crate::model::guider::GuiderConfig;
use crate::model::numeric::scalar::Scalar;
use crate::model::snapshot::{Field, Snapshot, SnapshotError};
use crate::model::spectral::spectrum::MAX_PERIOD_S;

/// The shortest period a stage is learned at: two cells (the spectrum's
/// Nyquist period).
const MIN_PERIOD_S: f64 = 2.0 * CELL_S;

/// Checks `snapshot` against what a model configured by `config` learns:
/// every stage's period between the prior and the spectrum's range (a
/// tracker starts at the prior and moves towards the spectrum's peaks),
/// neighbouring cells no further apart than two observations at
/// `max_input` and a cell of correction at `max_gear_rate`, and the cells'
/// trend no steeper than `max_gear_rate`.
pub fn check<S: Scalar>(
    config: &GuiderConfig<S>,
    snapshot: &Snapshot<'_>,
) -> Result<(), SnapshotError> {
    let prior = config.prior_period_s;
    let periods = MIN_PERIOD_S.min(prior)..=MAX_PERIOD_S.max(prior);
    let stages = (0..snapshot.stages()).filter_map(|s| snapshot.stage(s));
    if stages.into_iter().any(|s| !periods.contains(&s.period_s)) {
        return Err(SnapshotError::Invalid(Field::Period));
    }
    let max_input = config.max_input.to_f64();
    let largest_step = 2.0 * max_input + config.max_gear_rate * CELL_S;
    let mut previous = None;
    for (gear, _) in snapshot.cells() {
        let gear = f64::from(gear);
        if previous.is_some_and(|p: f64| !((gear - p).abs() <= largest_step)) {
            return Err(SnapshotError::Invalid(Field::CellGear));
        }
        previous = Some(gear);
    }
    if !(trend(snapshot).abs() <= config.max_gear_rate) {
        return Err(SnapshotError::Invalid(Field::Trend));
    }
    Ok(())
}

/// The least-squares slope of the cells against their time, per second (0
/// for fewer than two cells).
fn trend(snapshot: &Snapshot<'_>) -> f64 {
    let n = snapshot.cell_count() as f64;
    if n < 2.0 {
        return 0.0;
    }
    let t_mean = 0.5 * (n - 1.0) * CELL_S;
    let g_mean = snapshot.cells().map(|(g, _)| f64::from(g)).sum::<f64>() / n;
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (i, (g, _)) in snapshot.cells().enumerate() {
        let dt = i as f64 * CELL_S - t_mean;
        sxy += dt * (f64::from(g) - g_mean);
        sxx += dt * dt;
    }
    sxy / sxx
}
