//! The kernel at the lags between the subset's cells, each lag evaluated
//! once: lags are exact multiples of 5 s, m = 0 ..= span cells, and a
//! subset's few hundred distinct lags would otherwise be evaluated once per
//! Gram entry.
//!
//! With a dark gap in the grid (`Grid::dark`), the pairs across it are
//! apart by less observed time than gear time: their lags have a table of
//! their own, in the second half of the scratch.

use crate::model::gp::grid::{CELL_S, GRID_CELLS};
use crate::model::gp::kernel::Kernel;
use crate::model::gp::SUBSET;
use crate::model::numeric::scalar::Scalar;

/// Where the subset's cells divide at a dark gap: the cells before
/// `end` (held index) are `cells` cells of gear time further from those
/// after it than in observed time.
#[derive(Clone, Copy, Debug)]
pub(super) struct Split {
    pub(super) end: usize,
    pub(super) cells: usize,
}

/// The two tables: `same[m]`, the full kernel at `m` cells for two cells
/// on the same side of the split, and `across[m]` for two on either side.
pub(super) struct Tables<'a, S> {
    pub(super) same: &'a [S; GRID_CELLS],
    pub(super) across: &'a [S; GRID_CELLS],
}

/// Fill the tables for every lag `m` between two of `cells` (ascending, not
/// empty); the other entries up to the span hold -1 (`across` is left as
/// it was without a `split`). The tables are `GRID_CELLS` long, so that an
/// index masked to the grid needs no bounds check. None if `scratch` is
/// shorter than two tables.
// Inline in `Gp::infer`, its one caller, as before the split: out of line
// the Cortex-M4 bench (guide-sim bench) measured more instructions a frame.
#[inline(always)]
pub(super) fn build<'a, S: Scalar, const N: usize>(
    scratch: &'a mut [S],
    cells: &[u16],
    kernel: &Kernel<S, N>,
    split: Option<Split>,
) -> Option<Tables<'a, S>> {
    let (&first, &last) = (cells.first()?, cells.last()?);
    let span = (last - first) as usize;
    let (same, across) = scratch.get_mut(..2 * GRID_CELLS)?.split_at_mut(GRID_CELLS);
    let end = split.map_or(0, |s| s.end);
    // The members form runs of consecutive cells, and the lags between two
    // runs are one interval: the entries that occur are marked run pair by
    // run pair, and evaluated in one pass. No run crosses the split.
    let mut runs = [(0u16, 0u16); SUBSET];
    let mut n_runs: usize = 0;
    for &c in cells {
        match n_runs.checked_sub(1).and_then(|last| runs.get_mut(last)) {
            Some(run) if run.1 + 1 == c && c as usize != end => run.1 = c,
            _ => {
                *runs.get_mut(n_runs)? = (c, c);
                n_runs += 1;
            }
        }
    }
    let runs = runs.get(..n_runs)?;
    // Used entries are marked zero, then evaluated; unused ones stay -1.
    same.get_mut(..=span)?.fill(-S::ONE);
    if split.is_some() {
        across.get_mut(..=span)?.fill(-S::ONE);
    }
    for (a, &(a0, a1)) in runs.iter().enumerate() {
        for &(b0, b1) in runs.iter().take(a) {
            let crosses = (b0 as usize) < end && a0 as usize >= end;
            let table = if crosses { &mut *across } else { &mut *same };
            if let Some(used) = table.get_mut((a0 - b1) as usize..=(a1 - b0) as usize) {
                used.fill(S::ZERO);
            }
        }
        if let Some(used) = same.get_mut(..=(a1 - a0) as usize) {
            used.fill(S::ZERO);
        }
    }
    evaluate(same, span, kernel, 0);
    if let Some(split) = split {
        evaluate(across, span, kernel, split.cells);
    }
    Some(Tables {
        same: <&[S; GRID_CELLS]>::try_from(&*same).ok()?,
        across: <&[S; GRID_CELLS]>::try_from(&*across).ok()?,
    })
}

/// The marked (zero) entries of `table` up to `span`: the full kernel at
/// `m` cells of gear time, `m - unobserved` of observed time. Out of line:
/// one copy of the kernel serves both tables.
#[inline(never)]
fn evaluate<S: Scalar, const N: usize>(
    table: &mut [S],
    span: usize,
    kernel: &Kernel<S, N>,
    unobserved: usize,
) {
    let cell = S::from_f64(CELL_S);
    let skip = S::from_usize(unobserved) * cell;
    for (m, k) in table.iter_mut().take(span + 1).enumerate() {
        if *k == S::ZERO {
            let d = S::from_usize(m) * cell;
            *k = kernel.full_observed(d, d - skip);
        }
    }
}
