//! Gaussian-process inference on a subset of the grid (paper sec. 2).
//!
//! For each frame the [`SUBSET`] cells most correlated with the prediction
//! point (full kernel) are chosen (`subset`), their Gram matrix
//! `K + diag(variance)` is filled from a table of the kernel at their lags
//! (`lag_table`, `gram`) and factored, and the posterior mean with an
//! explicit linear trend `h(t) = [1, t]` is reduced to one weight vector
//! (`trend`):
//!
//! mean(x) = k(x)ᵀ w + β₀ + β₁ t'(x),
//!
//! so that predicting needs only kernel values.

use core::mem::MaybeUninit;

use crate::model::gp::grid::{Grid, CELL_S};
use crate::model::gp::kernel::Kernel;
use crate::model::gp::lag_table::Split;
use crate::model::gp::subset::Subset;
use crate::model::gp::trend::Trend;
use crate::model::gp::{gram, lag_table, InferError, SUBSET, TRIANGLE};
use crate::model::in_place::{build, fill, init_fields};
use crate::model::ldlt::Ldlt;
use crate::model::numeric::scalar::Scalar;

/// Inference state. RAM: the packed Gram factor (5,050 scalars, 20,200 bytes
/// in `f32`), four vectors of [`SUBSET`] scalars and the subset's cell
/// indices (about 22.5 KiB in `f32` all told).
pub struct Gp<S: Scalar> {
    chol: Ldlt<S, SUBSET, TRIANGLE>,
    subset: Subset,
    /// The posterior weights `w`, one per member of the subset.
    weights: [S; SUBSET],
    trend: Trend<S>,
    /// β₁, per second.
    slope: S,
    valid: bool,
}

impl<S: Scalar> Gp<S> {
    pub fn new() -> Self {
        build(Self::init)
    }

    /// [`new`](Self::new) in place (`crate::model::in_place`).
    pub fn init(slot: &mut MaybeUninit<Self>) -> &mut Self {
        init_fields!(slot, Self {
            chol in Ldlt::init,
            subset = Subset::new(),
            weights in |f| fill(f, S::ZERO),
            trend = Trend::new(),
            slope = S::ZERO,
            valid = false,
        })
    }

    /// Whether the last [`infer`](Self::infer) succeeded.
    pub fn is_valid(&self) -> bool {
        self.valid
    }

    pub fn clear(&mut self) {
        self.valid = false;
        self.subset.clear();
    }

    /// Fit the model around `centre` (seconds, relative to the grid origin).
    /// `scratch` (at least 2 x `GRID_CELLS` long, the guider's spectrum
    /// buffer) holds the selection's covariances and then the lag tables.
    /// A shorter `scratch` gives [`InferError::Degenerate`].
    /// `measured_only`: the subset leaves out cells without a measurement
    /// while there are measured ones (`Subset::select`).
    pub fn infer<const N: usize>(
        &mut self,
        grid: &Grid<S>,
        kernel: &Kernel<S, N>,
        centre: f64,
        scratch: &mut [S],
        measured_only: bool,
    ) -> Result<(), InferError> {
        self.valid = false;
        if grid.len() < 2 {
            return Err(InferError::TooLittleData);
        }
        if !self
            .subset
            .select(grid, kernel, centre, scratch, measured_only)
        {
            return Err(InferError::Degenerate);
        }
        let cells = self.subset.cells();
        let n = cells.len();
        let split = grid.dark().map(|(end, cells)| Split { end, cells });
        let Some(tables) = lag_table::build(scratch, cells, kernel, split) else {
            return Err(InferError::Degenerate);
        };
        let before = split.map_or(0, |s| cells.partition_point(|&c| (c as usize) < s.end));
        gram::fill(&mut self.chol, grid, cells, before, &tables);
        self.chol.factor().map_err(InferError::Factor)?;
        let weights = self.weights.get_mut(..n).ok_or(InferError::Degenerate)?;
        self.slope = self.trend.solve(&self.chol, grid, cells, centre, weights)?;
        self.valid = true;
        Ok(())
    }

    /// mean(x1) - mean(x0) of the projected posterior, times in seconds
    /// relative to the grid origin. Zero without a valid inference.
    pub fn predict_change<const N: usize>(
        &self,
        grid: &Grid<S>,
        kernel: &Kernel<S, N>,
        x0: f64,
        x1: f64,
    ) -> S {
        if !self.valid || grid.is_empty() {
            return S::ZERO;
        }
        // Lags from the newest cell, so that the short ones stay precise.
        let newest = grid.len() - 1;
        let t_newest = grid.cell_time(newest);
        let d0 = S::from_f64(x0 - t_newest);
        let d1 = S::from_f64(x1 - t_newest);
        let cell = S::from_f64(CELL_S);
        // x0 and x1 lie after a dark gap: the cells before it are that
        // much nearer in observed time.
        let unobserved = grid.unobserved();
        let mut change = S::ZERO;
        for (&c, &w) in self.subset.cells().iter().zip(&self.weights) {
            let back = S::from_usize(newest - c as usize) * cell;
            let (a, b) = (d0 + back, d1 + back);
            let skip = unobserved.before(c as usize);
            let dk = projection_at(kernel, b, skip) - projection_at(kernel, a, skip);
            change += dk * w;
        }
        change + self.slope * S::from_f64(x1 - x0)
    }
}

/// The projection kernel at lag `d`, `skip` of it not observed. Out of
/// line: one copy of the kernel for both ends of a prediction (a call per
/// member and end costs little beside the kernel).
#[inline(never)]
fn projection_at<S: Scalar, const N: usize>(kernel: &Kernel<S, N>, d: S, skip: S) -> S {
    kernel.projection_observed(d, d - skip)
}

impl<S: Scalar> Default for Gp<S> {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::gp::grid::{Averaging, GRID_CELLS};

    #[test]
    fn short_scratch_is_an_error_not_a_panic() {
        let mut g = Grid::new(Averaging::Reference);
        let mut t = 0.0;
        while t < 3000.0 {
            g.push(t, libm::sin(t / 50.0), 0.5);
            t += 2.0;
        }
        let k: Kernel<f64, 1> = Kernel::new(&[288.0], &[1.0]);
        let mut gp = Gp::<f64>::new();
        let mut scratch = [0.0; 2 * GRID_CELLS];
        assert_eq!(
            gp.infer(&g, &k, 3001.0, &mut scratch[..GRID_CELLS], true),
            Err(InferError::Degenerate)
        );
        assert_eq!(gp.infer(&g, &k, 3001.0, &mut scratch, true), Ok(()));
    }
}
