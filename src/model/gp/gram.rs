//! The subset's Gram matrix `K + diag(variance)`, from the lag tables.

use crate::model::gp::grid::{Grid, GRID_CELLS};
use crate::model::gp::lag_table::Tables;
use crate::model::gp::{SUBSET, TRIANGLE};
use crate::model::ldlt::Ldlt;
use crate::model::numeric::scalar::Scalar;

/// Write the lower triangle of the Gram matrix of `cells` (ascending) into
/// `chol`, row i from `tables` at `ci - cj`, j <= i (lag_table::build):
/// the first `before` cells lie before a dark gap, and their entries in
/// the rows of the cells after it come from `tables.across`.
// Inline in `Gp::infer`, its one caller, as before the split: out of line
// the Cortex-M4 bench (guide-sim bench) measured more instructions a frame.
#[inline(always)]
pub(super) fn fill<S: Scalar>(
    chol: &mut Ldlt<S, SUBSET, TRIANGLE>,
    grid: &Grid<S>,
    cells: &[u16],
    before: usize,
    tables: &Tables<'_, S>,
) {
    chol.set_dim(cells.len());
    for (i, &ci) in cells.iter().enumerate() {
        let var_i = grid.cell(ci as usize).1;
        let row = chol.row_mut(i);
        let split = if i >= before {
            before.min(row.len())
        } else {
            0
        };
        let (across, same) = row.split_at_mut(split);
        // The lag is at most the span, below GRID_CELLS: the mask changes
        // nothing and spares the bounds check.
        let lag = |cj: u16| ci.wrapping_sub(cj) as usize & (GRID_CELLS - 1);
        for (r, &cj) in across.iter_mut().zip(cells) {
            *r = tables.across[lag(cj)];
        }
        for (r, &cj) in same.iter_mut().zip(cells.get(split..).unwrap_or_default()) {
            *r = tables.same[lag(cj)];
        }
        // The diagonal: row i is i + 1 long.
        if let Some(d) = same.last_mut() {
            *d += var_i;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::gp::grid::{Averaging, CELL_S};
    use crate::model::gp::kernel::Kernel;
    use crate::model::gp::lag_table::{build, Split};

    /// Each entry is the kernel at its pair's lags, bit for bit: in gear
    /// time, and across a dark gap with the envelopes in observed time.
    #[test]
    fn each_entry_is_the_kernel_at_its_pairs_lags() {
        let mut grid: Grid<f64> = Grid::new(Averaging::Reference);
        let mut t = 0.0;
        while t < 6000.0 {
            grid.push(t, libm::sin(t / 40.0), 0.5 + 0.001 * t);
            t += 2.0;
        }
        let kernel: Kernel<f64, 2> = Kernel::new(&[288.0, 110.0], &[1.0, 0.7]);
        // Runs on both sides of the split, one ending right at it.
        let cells: std::vec::Vec<u16> = (10..40)
            .chain(300..330)
            .chain(350..360)
            .chain(600..620)
            .chain(1100..1110)
            .map(|c| c as u16)
            .collect();
        for split in [
            None,
            Some(Split {
                end: 360,
                cells: 200,
            }),
            Some(Split { end: 0, cells: 9 }),
        ] {
            let mut scratch = std::vec![0.0; 2 * GRID_CELLS];
            let tables = build(&mut scratch, &cells, &kernel, split).unwrap();
            let end = split.map_or(0, |s| s.end);
            let before = cells.partition_point(|&c| (c as usize) < end);
            let mut chol: Ldlt<f64, SUBSET, TRIANGLE> = Ldlt::new();
            fill(&mut chol, &grid, &cells, before, &tables);
            for (i, &ci) in cells.iter().enumerate() {
                let row = chol.row_mut(i).to_vec();
                for (j, &cj) in cells.iter().enumerate().take(i + 1) {
                    let d = (ci - cj) as f64 * CELL_S;
                    let crosses = (cj as usize) < end && ci as usize >= end;
                    let mut want = match split {
                        Some(s) if crosses => kernel.full_observed(d, d - s.cells as f64 * CELL_S),
                        _ => kernel.full(d),
                    };
                    if i == j {
                        want += grid.cell(ci as usize).1;
                    }
                    assert_eq!(row[j].to_bits(), want.to_bits(), "{split:?} {ci} {cj}");
                }
            }
        }
    }
}
