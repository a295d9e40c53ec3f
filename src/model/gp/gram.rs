//! The subset's Gram matrix `K + diag(variance)`, from the lag table.

use crate::model::gp::grid::{Grid, GRID_CELLS};
use crate::model::gp::{SUBSET, TRIANGLE};
use crate::model::ldlt::Ldlt;
use crate::model::numeric::scalar::Scalar;

/// Write the lower triangle of the Gram matrix of `cells` (ascending) into
/// `chol`, row i from `table[ci - cj]`, j <= i (lag_table::build).
// Inline in `Gp::infer`, its one caller, as before the split: out of line
// the Cortex-M4 bench (guide-sim bench) measured more instructions a frame.
#[inline(always)]
pub(super) fn fill<S: Scalar>(
    chol: &mut Ldlt<S, SUBSET, TRIANGLE>,
    grid: &Grid<S>,
    cells: &[u16],
    table: &[S; GRID_CELLS],
) {
    chol.set_dim(cells.len());
    for (i, &ci) in cells.iter().enumerate() {
        let var_i = grid.cell(ci as usize).1;
        let row = chol.row_mut(i);
        // The lag is at most the span, below GRID_CELLS: the mask changes
        // nothing and spares the bounds check.
        for (r, &cj) in row.iter_mut().zip(cells) {
            *r = table[ci.wrapping_sub(cj) as usize & (GRID_CELLS - 1)];
        }
        // The diagonal: row i is i + 1 long.
        if let Some(d) = row.last_mut() {
            *d += var_i;
        }
    }
}
