//! The kernel at the lags between the subset's cells, each lag evaluated
//! once: lags are exact multiples of 5 s, m = 0 ..= span cells, and a
//! subset's few hundred distinct lags would otherwise be evaluated once per
//! Gram entry.

use crate::model::gp::grid::{CELL_S, GRID_CELLS};
use crate::model::gp::kernel::Kernel;
use crate::model::gp::SUBSET;
use crate::model::numeric::scalar::Scalar;

/// Fill `scratch[m]` with the full kernel at `m` cells for every lag `m`
/// between two of `cells` (ascending, not empty); the other entries up to
/// the span hold -1. Returns the table, `GRID_CELLS` long so that an index
/// masked to the grid needs no bounds check, or None if `scratch` is shorter.
// Inline in `Gp::infer`, its one caller, as before the split: out of line
// the Cortex-M4 bench (guide-sim bench) measured more instructions a frame.
#[inline(always)]
pub(super) fn build<'a, S: Scalar, const N: usize>(
    scratch: &'a mut [S],
    cells: &[u16],
    kernel: &Kernel<S, N>,
) -> Option<&'a [S; GRID_CELLS]> {
    let (&first, &last) = (cells.first()?, cells.last()?);
    let span = (last - first) as usize;
    let lags = scratch.get_mut(..=span)?;
    // The members form runs of consecutive cells, and the lags between two
    // runs are one interval: the entries that occur are marked run pair by
    // run pair, and evaluated in one pass.
    let mut runs = [(0u16, 0u16); SUBSET];
    let mut n_runs: usize = 0;
    for &c in cells {
        match n_runs.checked_sub(1).and_then(|last| runs.get_mut(last)) {
            Some(run) if run.1 + 1 == c => run.1 = c,
            _ => {
                *runs.get_mut(n_runs)? = (c, c);
                n_runs += 1;
            }
        }
    }
    let runs = runs.get(..n_runs)?;
    // Used entries are marked zero, then evaluated; unused ones stay -1.
    lags.fill(-S::ONE);
    for (a, &(a0, a1)) in runs.iter().enumerate() {
        for &(b0, b1) in runs.iter().take(a) {
            if let Some(used) = lags.get_mut((a0 - b1) as usize..=(a1 - b0) as usize) {
                used.fill(S::ZERO);
            }
        }
        if let Some(used) = lags.get_mut(..=(a1 - a0) as usize) {
            used.fill(S::ZERO);
        }
    }
    let cell = S::from_f64(CELL_S);
    for (m, k) in lags.iter_mut().enumerate() {
        if *k == S::ZERO {
            *k = kernel.full(S::from_usize(m) * cell);
        }
    }
    <&[S; GRID_CELLS]>::try_from(scratch.get(..GRID_CELLS)?).ok()
}
