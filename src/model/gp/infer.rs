//! Gaussian-process inference on a subset of the grid (paper sec. 2).
//!
//! For each frame the [`SUBSET`] cells most correlated with the prediction
//! point (full kernel) are chosen, their Gram matrix `K + diag(variance)` is
//! factored, and the posterior mean with an explicit linear trend
//! `h(t) = [1, t]` is reduced to one weight vector:
//!
//! mean(x) = k(x)ᵀ w + β₀ + β₁ t'(x),   w = K⁻¹ (y - H β),
//! β = (H K⁻¹ Hᵀ)⁻¹ H K⁻¹ y,
//!
//! so that predicting needs only kernel values. The trend's time is centred
//! on the prediction point and scaled (t' = (t - t_pred) / 1000 s): the
//! fitted mean does not depend on that choice, but `f32` does.

use core::cmp::Ordering;

use crate::model::gp::grid::{Grid, CELL_S, GRID_CELLS};
use crate::model::gp::kernel::Kernel;
use crate::model::ldlt::{FactorError, Ldlt};
use crate::model::numeric::dot::dot;
use crate::model::numeric::scalar::Scalar;

/// Cells used for one inference.
pub const SUBSET: usize = 100;
const TRIANGLE: usize = SUBSET * (SUBSET + 1) / 2;
/// Time scale of the trend basis, seconds.
const TREND_TIME_S: f64 = 1000.0;

/// Why an inference could not be made.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InferError {
    /// Fewer than two cells.
    TooLittleData,
    Factor(FactorError),
    /// The trend system was singular or a result was not finite.
    Degenerate,
}

/// Inference state. RAM: the packed Gram factor (5,050 scalars, 20,200 bytes
/// in `f32`), four vectors of [`SUBSET`] scalars and the subset's cell
/// indices (about 22.5 KiB in `f32` all told).
pub struct Gp<S: Scalar> {
    chol: Ldlt<S, SUBSET, TRIANGLE>,
    /// Held-cell index of each subset member, ascending.
    cells: [u16; SUBSET],
    /// The posterior weights `w`.
    weights: [S; SUBSET],
    /// Scratch: `K⁻¹ 1` and `K⁻¹ t'`.
    s0: [S; SUBSET],
    s1: [S; SUBSET],
    n: usize,
    /// β₁, per unit of t'.
    slope: S,
    valid: bool,
}

impl<S: Scalar> Gp<S> {
    pub fn new() -> Self {
        Self {
            chol: Ldlt::new(),
            cells: [0; SUBSET],
            weights: [S::ZERO; SUBSET],
            s0: [S::ZERO; SUBSET],
            s1: [S::ZERO; SUBSET],
            n: 0,
            slope: S::ZERO,
            valid: false,
        }
    }

    /// Whether the last [`infer`](Self::infer) succeeded.
    pub fn is_valid(&self) -> bool {
        self.valid
    }

    pub fn clear(&mut self) {
        self.valid = false;
        self.n = 0;
    }

    /// Fit the model around `centre` (seconds, relative to the grid origin).
    /// `scratch` (at least 2 x [`GRID_CELLS`] long, the guider's spectrum
    /// buffer) holds the selection's covariances and then the kernel at the
    /// lags between cells: they are multiples of 5 s, and the subset's few
    /// hundred distinct lags are each evaluated once instead of once per
    /// Gram entry. A shorter `scratch` gives [`InferError::Degenerate`].
    pub fn infer<const N: usize>(
        &mut self,
        grid: &Grid<S>,
        kernel: &Kernel<S, N>,
        centre: f64,
        scratch: &mut [S],
    ) -> Result<(), InferError> {
        self.valid = false;
        let total = grid.len();
        if total < 2 {
            return Err(InferError::TooLittleData);
        }
        if !self.select(grid, kernel, centre, scratch) {
            return Err(InferError::Degenerate);
        }
        let n = self.n;

        // Gram matrix from a table of the kernel at the lags between members:
        // exact multiples of 5 s, m = 0 ..= span cells. The members form runs
        // of consecutive cells, and the lags between two runs are one
        // interval: the table's entries that occur are marked run pair by
        // run pair, and evaluated in one pass.
        let cell = S::from_f64(CELL_S);
        let cells = &self.cells[..n];
        let span = (cells[n - 1] - cells[0]) as usize;
        let Some(lags) = scratch.get_mut(..=span) else {
            return Err(InferError::Degenerate);
        };
        let mut runs = [(0u16, 0u16); SUBSET];
        let mut n_runs = 0;
        for &c in cells {
            match runs[..n_runs].last_mut() {
                Some(run) if run.1 + 1 == c => run.1 = c,
                _ => {
                    runs[n_runs] = (c, c);
                    n_runs += 1;
                }
            }
        }
        let runs = &runs[..n_runs];
        // Used entries are marked zero, then evaluated; unused ones stay -1.
        lags.fill(-S::ONE);
        for (a, &(a0, a1)) in runs.iter().enumerate() {
            for &(b0, b1) in &runs[..a] {
                if let Some(used) = lags.get_mut((a0 - b1) as usize..=(a1 - b0) as usize) {
                    used.fill(S::ZERO);
                }
            }
            if let Some(used) = lags.get_mut(..=(a1 - a0) as usize) {
                used.fill(S::ZERO);
            }
        }
        for (m, k) in lags.iter_mut().enumerate() {
            if *k == S::ZERO {
                *k = kernel.full(S::from_usize(m) * cell);
            }
        }
        // Rows: lags[ci - cj], j <= i. The lag is below `span + 1 <=
        // GRID_CELLS`, so the mask changes nothing and spares the check.
        let Some(table) = scratch.get(..GRID_CELLS) else {
            return Err(InferError::Degenerate);
        };
        let Ok(table) = <&[S; GRID_CELLS]>::try_from(table) else {
            return Err(InferError::Degenerate);
        };
        self.chol.set_dim(n);
        for (i, &ci) in cells.iter().enumerate() {
            let var_i = grid.cell(ci as usize).1;
            let row = self.chol.row_mut(i);
            for (r, &cj) in row.iter_mut().zip(cells) {
                *r = table[ci.wrapping_sub(cj) as usize & (GRID_CELLS - 1)];
            }
            row[i] += var_i;
        }
        self.chol.factor().map_err(InferError::Factor)?;

        // Right-hand sides: y (less a constant, which the trend absorbs),
        // the constant and the time of the trend basis.
        let y_ref = grid.cell(self.cells[0] as usize).0;
        let inv_tau = S::from_f64(1.0 / TREND_TIME_S);
        let centre_s = S::from_f64(centre);
        // Cell times as in `select`: the oldest's plus a multiple of 5 s,
        // exact in S (no f64 per member).
        let t_oldest = S::from_f64(grid.cell_time(0));
        for i in 0..n {
            let c = self.cells[i] as usize;
            self.weights[i] = grid.cell(c).0 - y_ref;
            self.s0[i] = S::ONE;
            let t_c = t_oldest + S::from_usize(c) * cell;
            self.s1[i] = (t_c - centre_s) * inv_tau;
        }
        // t' of each member is needed again after the solves.
        let mut t = [S::ZERO; SUBSET];
        t[..n].copy_from_slice(&self.s1[..n]);
        self.chol
            .solve3(&mut self.weights[..n], &mut self.s0[..n], &mut self.s1[..n]);

        let mut f00 = S::ZERO;
        for &x in &self.s0[..n] {
            f00 += x;
        }
        let f01 = dot(&t[..n], &self.s0[..n]);
        let f11 = dot(&t[..n], &self.s1[..n]);
        let mut b0 = S::ZERO;
        for &x in &self.weights[..n] {
            b0 += x;
        }
        let b1 = dot(&t[..n], &self.weights[..n]);
        let det = f00 * f11 - f01 * f01;
        if !(det > S::ZERO) {
            return Err(InferError::Degenerate);
        }
        let beta0 = (f11 * b0 - f01 * b1) / det;
        let beta1 = (f00 * b1 - f01 * b0) / det;
        if !(beta0.is_finite() && beta1.is_finite()) {
            return Err(InferError::Degenerate);
        }
        for i in 0..n {
            self.weights[i] -= beta0 * self.s0[i] + beta1 * self.s1[i];
            if !self.weights[i].is_finite() {
                return Err(InferError::Degenerate);
            }
        }
        self.slope = beta1 * inv_tau;
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
        let mut change = S::ZERO;
        for i in 0..self.n {
            let back = S::from_usize(newest - self.cells[i] as usize) * cell;
            let dk = kernel.projection(d1 + back) - kernel.projection(d0 + back);
            change += dk * self.weights[i];
        }
        change + self.slope * S::from_f64(x1 - x0)
    }

    /// Choose the cells with the largest full-kernel covariance to `centre`;
    /// of equal covariances the older cell wins (NaN counts as the lowest).
    /// Leaves them in `self.cells`, ascending. `scratch` must hold two
    /// covariances per cell (`2 * grid.len()`); returns false otherwise.
    ///
    /// The members are exactly the `SUBSET` first cells in the order
    /// (covariance descending, cell ascending), found without a heap: the
    /// covariances go to `scratch`, a copy is partitioned around the
    /// `SUBSET`-th (`select_nth_unstable_by`, O(cells)), and one pass in cell
    /// order takes every cell above that threshold and, of the cells equal
    /// to it, the oldest ones, ascending as they come.
    fn select<const N: usize>(
        &mut self,
        grid: &Grid<S>,
        kernel: &Kernel<S, N>,
        centre: f64,
        scratch: &mut [S],
    ) -> bool {
        let total = grid.len();
        let k = total.min(SUBSET);
        self.n = k;
        if total <= SUBSET {
            for (i, c) in self.cells.iter_mut().enumerate().take(total) {
                *c = i as u16;
            }
            return true;
        }
        if scratch.len() < 2 * total {
            return false;
        }
        let (cov, rest) = scratch.split_at_mut(total);
        let copy = &mut rest[..total];
        let centre_s = S::from_f64(centre);
        // Cell times in S, stepping 5 s from the oldest: exact (multiples of
        // 2.5 s; in f32 up to 2^23 s), so each equals
        // `S::from_f64(grid.cell_time(j))` bit for bit without the software
        // f64 arithmetic per cell on the target.
        let step = S::from_f64(CELL_S);
        let mut t_j = S::from_f64(grid.cell_time(0));
        for c in cov.iter_mut() {
            *c = kernel.full(centre_s - t_j);
            t_j += step;
        }
        copy.copy_from_slice(cov);
        // Descending, NaN last: a total order.
        let order = |a: &S, b: &S| {
            if *a > *b {
                Ordering::Less
            } else if *a < *b {
                Ordering::Greater
            } else if *a == *b || (is_nan(*a) && is_nan(*b)) {
                Ordering::Equal
            } else if is_nan(*a) {
                Ordering::Greater
            } else {
                Ordering::Less
            }
        };
        let (above, &mut threshold, _) = copy.select_nth_unstable_by(k - 1, order);
        let mut ties = k - above
            .iter()
            .filter(|c| order(c, &threshold) == Ordering::Less)
            .count();
        let mut m = 0;
        for (j, c) in cov.iter().enumerate() {
            let take = match order(c, &threshold) {
                Ordering::Less => true,
                Ordering::Equal if ties > 0 => {
                    ties -= 1;
                    true
                }
                _ => false,
            };
            if take {
                if let Some(slot) = self.cells.get_mut(m) {
                    *slot = j as u16;
                }
                m += 1;
            }
        }
        true
    }
}

fn is_nan<S: Scalar>(x: S) -> bool {
    x.partial_cmp(&x).is_none()
}

impl<S: Scalar> Default for Gp<S> {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec::Vec;

    /// The subset by sorting every cell: (covariance descending, cell
    /// ascending), the first `SUBSET`, ascending.
    fn reference<S: Scalar, const N: usize>(
        grid: &Grid<S>,
        kernel: &Kernel<S, N>,
        centre: f64,
    ) -> Vec<u16> {
        let centre_s = S::from_f64(centre);
        let mut all: Vec<(S, u16)> = (0..grid.len())
            .map(|j| {
                let t = S::from_f64(grid.cell_time(j));
                (kernel.full(centre_s - t), j as u16)
            })
            .collect();
        all.sort_by(|a, b| b.0.partial_cmp(&a.0).unwrap().then(a.1.cmp(&b.1)));
        let mut cells: Vec<u16> = all.iter().take(SUBSET).map(|x| x.1).collect();
        cells.sort();
        cells
    }

    fn grid<S: Scalar>(seconds: f64) -> Grid<S> {
        let mut g = Grid::new();
        let mut t = 0.0;
        while t < seconds {
            g.push(t, libm::sin(t / 50.0), 0.5);
            t += 2.0;
        }
        g
    }

    fn check<S: Scalar, const N: usize>(grid: &Grid<S>, kernel: &Kernel<S, N>, centre: f64) {
        let mut gp = Gp::<S>::new();
        let mut scratch = [S::ZERO; 2 * GRID_CELLS];
        assert!(gp.select(grid, kernel, centre, &mut scratch));
        let want = reference(grid, kernel, centre);
        assert_eq!(&gp.cells[..gp.n], &want[..], "centre {centre}");
    }

    #[test]
    fn select_is_the_sorted_top_subset() {
        let g64 = grid::<f64>(6000.0);
        let g32 = grid::<f32>(6000.0);
        let k1: Kernel<f64, 1> = Kernel::new(&[288.0], &[1.0]);
        let k2: Kernel<f64, 2> = Kernel::new(&[288.0, 110.0], &[1.0, 0.7]);
        let k1f: Kernel<f32, 1> = Kernel::new(&[288.0], &[1.0]);
        let k2f: Kernel<f32, 2> = Kernel::new(&[432.0, 155.0], &[1.0, 1.0]);
        let newest = g64.cell_time(g64.len() - 1);
        for centre in [newest + 2.5, newest + 3.7, newest + 40.0, newest - 1000.0] {
            check(&g64, &k1, centre);
            check(&g64, &k2, centre);
            check(&g32, &k1f, centre);
            check(&g32, &k2f, centre);
        }
        // Centred between two cells in the middle: every covariance comes
        // twice (k(d) = k(-d)), and of each pair the older cell must win.
        let mid = g64.cell_time(600) + 2.5;
        check(&g64, &k1, mid);
        check(&g64, &k2, mid);
        check(&g32, &k1f, mid);
        check(&g32, &k2f, mid);
        // Few cells: all of them.
        let small = grid::<f64>(300.0);
        check(&small, &k1, 310.0);
    }

    #[test]
    fn short_scratch_is_an_error_not_a_panic() {
        let g = grid::<f64>(3000.0);
        let k: Kernel<f64, 1> = Kernel::new(&[288.0], &[1.0]);
        let mut gp = Gp::<f64>::new();
        let mut scratch = [0.0; GRID_CELLS];
        assert_eq!(
            gp.infer(&g, &k, 3001.0, &mut scratch[..100]),
            Err(InferError::Degenerate)
        );
        assert_eq!(gp.infer(&g, &k, 3001.0, &mut scratch), Ok(()));
    }
}
