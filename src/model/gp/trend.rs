//! The explicit linear trend `h(t) = [1, t']` of the posterior mean, folded
//! into the weights:
//!
//! w = K⁻¹ (y - H β),   β = (H K⁻¹ Hᵀ)⁻¹ H K⁻¹ y.
//!
//! The trend's time is centred on the prediction point and scaled
//! (t' = (t - t_pred) / 1000 s): the fitted mean does not depend on that
//! choice, but `f32` does.

use crate::model::gp::grid::{Grid, CELL_S};
use crate::model::gp::{InferError, SUBSET, TRIANGLE};
use crate::model::ldlt::Ldlt;
use crate::model::numeric::dot::dot;
use crate::model::numeric::scalar::Scalar;

/// Time scale of the trend basis, seconds.
const TREND_TIME_S: f64 = 1000.0;

/// Scratch of the solve: `K⁻¹ 1` and `K⁻¹ t'`.
pub(super) struct Trend<S: Scalar> {
    s0: [S; SUBSET],
    s1: [S; SUBSET],
}

impl<S: Scalar> Trend<S> {
    pub(super) fn new() -> Self {
        Self {
            s0: [S::ZERO; SUBSET],
            s1: [S::ZERO; SUBSET],
        }
    }

    /// With `chol` the factored Gram matrix of `cells`, leave `w` in
    /// `weights` (as long as `cells`) and return β₁ per second. `centre`:
    /// the prediction point, seconds relative to the grid origin.
    pub(super) fn solve(
        &mut self,
        chol: &Ldlt<S, SUBSET, TRIANGLE>,
        grid: &Grid<S>,
        cells: &[u16],
        centre: f64,
        weights: &mut [S],
    ) -> Result<S, InferError> {
        let n = cells.len();
        let (Some(s0), Some(s1), Some(&first)) =
            (self.s0.get_mut(..n), self.s1.get_mut(..n), cells.first())
        else {
            return Err(InferError::Degenerate);
        };
        // Right-hand sides: y (less a constant, which the trend absorbs),
        // the constant and the time of the trend basis.
        let y_ref = grid.cell(first as usize).0;
        let inv_tau = S::from_f64(1.0 / TREND_TIME_S);
        let centre_s = S::from_f64(centre);
        // Cell times as in the selection: the oldest's plus a multiple of
        // 5 s, exact in S (no f64 per member).
        let cell = S::from_f64(CELL_S);
        let t_oldest = S::from_f64(grid.cell_time(0));
        for (((&c, w), one), t) in cells.iter().zip(&mut *weights).zip(&mut *s0).zip(&mut *s1) {
            let c = c as usize;
            *w = grid.cell(c).0 - y_ref;
            *one = S::ONE;
            let t_c = t_oldest + S::from_usize(c) * cell;
            *t = (t_c - centre_s) * inv_tau;
        }
        // t' of each member is needed again after the solves.
        let mut t = [S::ZERO; SUBSET];
        let t = &mut t[..n];
        t.copy_from_slice(s1);
        chol.solve3(weights, s0, s1).map_err(InferError::Factor)?;

        let mut f00 = S::ZERO;
        for &x in s0.iter() {
            f00 += x;
        }
        let f01 = dot(t, s0);
        let f11 = dot(t, s1);
        let mut b0 = S::ZERO;
        for &x in weights.iter() {
            b0 += x;
        }
        let b1 = dot(t, weights);
        let det = f00 * f11 - f01 * f01;
        if !(det > S::ZERO) {
            return Err(InferError::Degenerate);
        }
        let beta0 = (f11 * b0 - f01 * b1) / det;
        let beta1 = (f00 * b1 - f01 * b0) / det;
        if !(beta0.is_finite() && beta1.is_finite()) {
            return Err(InferError::Degenerate);
        }
        for ((w, &k0), &k1) in weights.iter_mut().zip(&*s0).zip(&*s1) {
            *w -= beta0 * k0 + beta1 * k1;
            if !w.is_finite() {
                return Err(InferError::Degenerate);
            }
        }
        Ok(beta1 * inv_tau)
    }
}
