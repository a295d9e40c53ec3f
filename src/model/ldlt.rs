//! Square-root-free Cholesky (LDLᵀ) factorisation on static storage.
//!
//! The Gram matrix of the inference subset is symmetric, so only its lower
//! triangle is kept, packed row by row: row `i` holds columns `0..=i` at
//! offset `i (i + 1) / 2`. For the default subset of 100 points that is 5,050
//! scalars (20,200 bytes in `f32`). After [`Ldlt::factor`] the strict lower
//! part holds `L` (unit diagonal implied) and the diagonal holds `D`.

use core::mem::MaybeUninit;
use core::ops::Range;

use crate::model::in_place::{build, fill, init_fields};
use crate::model::numeric::dot::{dot, BLOCK};
use crate::model::numeric::scalar::Scalar;

/// Why a factorisation was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FactorError {
    /// A pivot was zero, negative or not finite: the matrix is not
    /// (numerically) positive definite. The caller falls back to reactive
    /// guiding for this frame.
    NotPositiveDefinite { row: usize },
    /// A row lay outside the packed storage. Cannot happen (`n <= CAP` and
    /// `TRI` is checked against `CAP`); an error instead of a bounds-check
    /// panic, so that the firmware holds none.
    Storage,
}

/// Packed lower triangle of an `n x n` symmetric matrix, `n <= CAP`.
/// `TRI` must be `CAP (CAP + 1) / 2` (checked at compile time in `new`).
pub struct Ldlt<S: Scalar, const CAP: usize, const TRI: usize> {
    a: [S; TRI],
    n: usize,
}

const fn row_start(i: usize) -> usize {
    i * (i + 1) / 2
}

impl<S: Scalar, const CAP: usize, const TRI: usize> Ldlt<S, CAP, TRI> {
    const TRI_MATCHES_CAP: () = assert!(TRI == CAP * (CAP + 1) / 2);

    pub fn new() -> Self {
        build(Self::init)
    }

    /// [`new`](Self::new) in place (`crate::model::in_place`).
    pub fn init(slot: &mut MaybeUninit<Self>) -> &mut Self {
        #[allow(clippy::let_unit_value)]
        let _ = Self::TRI_MATCHES_CAP;
        init_fields!(slot, Self {
            a in |f| fill(f, S::ZERO),
            n = 0,
        })
    }

    /// Current dimension.
    pub fn dim(&self) -> usize {
        self.n
    }

    /// Start filling an `n x n` matrix (`n` is clamped to the capacity).
    pub fn set_dim(&mut self, n: usize) {
        self.n = n.min(CAP);
    }

    /// Row `i`, columns `0..=i`, for filling the matrix before factoring;
    /// empty for `i >= CAP`.
    pub fn row_mut(&mut self, i: usize) -> &mut [S] {
        let s = row_start(i);
        self.a.get_mut(s..s + i + 1).unwrap_or_default()
    }

    /// Factor in place: afterwards row `i` holds `L[i][0..i]` and `D[i]`.
    ///
    /// Row by row: first `w_j = L_ij D_j = A_ij - Σ_{k<j} w_k L_jk` for
    /// `j < i`, then `L_ij = w_j / D_j` and `D_i = A_ii - Σ_j w_j L_ij`.
    /// Rows are taken in blocks of [`BLOCK`]: each row `j` of `L` above the
    /// block is then read once for all of its rows. The dot products are
    /// nearly all of the cost, and this takes their loads from two per
    /// multiply-add towards one.
    ///
    /// Rows are reached through checked splits (a failed one is
    /// [`FactorError::Storage`]), so that no bounds check can panic.
    pub fn factor(&mut self) -> Result<(), FactorError> {
        let n = self.n.min(CAP);
        let mut i = 0;
        while i < n {
            let rows = BLOCK.min(n - i);
            let (head, tail) = self
                .a
                .split_at_mut_checked(row_start(i))
                .ok_or(FactorError::Storage)?;
            if rows == BLOCK {
                let (r0, rest) = tail
                    .split_at_mut_checked(i + 1)
                    .ok_or(FactorError::Storage)?;
                let (r1, rest) = rest
                    .split_at_mut_checked(i + 2)
                    .ok_or(FactorError::Storage)?;
                let (r2, rest) = rest
                    .split_at_mut_checked(i + 3)
                    .ok_or(FactorError::Storage)?;
                let r3 = rest.get_mut(..i + 4).ok_or(FactorError::Storage)?;
                // Row j of L (columns 0..j), then its diagonal, in order.
                let mut above: &[S] = head;
                for j in 0..i {
                    let (lj, rest) = above.split_at_checked(j + 1).ok_or(FactorError::Storage)?;
                    above = rest;
                    let lj = &lj[..j];
                    let d = S::dot_rows([&r0[..j], &r1[..j], &r2[..j], &r3[..j]], lj);
                    r0[j] -= d[0];
                    r1[j] -= d[1];
                    r2[j] -= d[2];
                    r3[j] -= d[3];
                }
            } else {
                for r in 0..rows {
                    self.update_row(i + r, 0..i)?;
                }
            }
            // Inside the block: row i + r needs rows i..i + r finished.
            for r in 0..rows {
                self.update_row(i + r, i..i + r)?;
                self.finish_row(i + r)?;
            }
            i += rows;
        }
        Ok(())
    }

    /// `w_j -= Σ_{k<j} w_k L_jk` in row `i` for the columns `cols` (< i).
    fn update_row(&mut self, i: usize, cols: Range<usize>) -> Result<(), FactorError> {
        let (head, tail) = self
            .a
            .split_at_mut_checked(row_start(i))
            .ok_or(FactorError::Storage)?;
        for j in cols {
            let rj = row_start(j);
            let lj = head.get(rj..rj + j).ok_or(FactorError::Storage)?;
            let (w, rest) = tail.split_at_mut_checked(j).ok_or(FactorError::Storage)?;
            let wj = rest.first_mut().ok_or(FactorError::Storage)?;
            *wj -= dot(w, lj);
        }
        Ok(())
    }

    /// Turn row `i`'s `w_j` into `L_ij` and compute `D_i`.
    fn finish_row(&mut self, i: usize) -> Result<(), FactorError> {
        let (head, tail) = self
            .a
            .split_at_mut_checked(row_start(i))
            .ok_or(FactorError::Storage)?;
        let (w, rest) = tail.split_at_mut_checked(i).ok_or(FactorError::Storage)?;
        let diag = rest.first_mut().ok_or(FactorError::Storage)?;
        let mut d = *diag;
        for (j, wj) in w.iter_mut().enumerate() {
            let dj = *head.get(row_start(j) + j).ok_or(FactorError::Storage)?;
            let w = *wj;
            let l = w / dj;
            d -= l * w;
            *wj = l;
        }
        // `!(d > 0)` also catches NaN.
        if !(d > S::ZERO) || !d.is_finite() {
            return Err(FactorError::NotPositiveDefinite { row: i });
        }
        *diag = d;
        Ok(())
    }

    /// Solve `A x = b` in place, with `A` factored. `b.len()` must be
    /// `dim()`. Storage is read with checked slices
    /// ([`FactorError::Storage`]), so that no bounds check can panic.
    pub fn solve(&self, b: &mut [S]) -> Result<(), FactorError> {
        let n = self.n.min(b.len());
        let l = |i: usize| {
            let ri = row_start(i);
            self.a.get(ri..ri + i).ok_or(FactorError::Storage)
        };
        for i in 0..n {
            let (head, tail) = b.split_at_mut(i);
            tail[0] -= dot(l(i)?, head);
        }
        for (i, bi) in b.iter_mut().enumerate().take(n) {
            *bi /= *self.a.get(row_start(i) + i).ok_or(FactorError::Storage)?;
        }
        for i in (0..n).rev() {
            let (head, tail) = b.split_at_mut(i);
            let xi = tail[0];
            for (bk, &lk) in head.iter_mut().zip(l(i)?) {
                *bk -= lk * xi;
            }
        }
        Ok(())
    }

    /// Solve for three right-hand sides at once (the inference's `y`, `1`
    /// and `t`): each element of `L` is loaded once for all three.
    pub fn solve3(&self, x: &mut [S], y: &mut [S], z: &mut [S]) -> Result<(), FactorError> {
        let n = self.n.min(x.len()).min(y.len()).min(z.len());
        let l = |i: usize| {
            let ri = row_start(i);
            self.a.get(ri..ri + i).ok_or(FactorError::Storage)
        };
        // L u = b, row by row.
        for i in 0..n {
            let s = S::dot3(l(i)?, &x[..i], &y[..i], &z[..i]);
            x[i] -= s[0];
            y[i] -= s[1];
            z[i] -= s[2];
        }
        for i in 0..n {
            let d = *self.a.get(row_start(i) + i).ok_or(FactorError::Storage)?;
            x[i] /= d;
            y[i] /= d;
            z[i] /= d;
        }
        // Lᵀ u = v, column-oriented so that rows of L are read contiguously.
        for i in (0..n).rev() {
            let (xh, xt) = x.split_at_mut(i);
            let (yh, yt) = y.split_at_mut(i);
            let (zh, zt) = z.split_at_mut(i);
            S::sub_scaled3(l(i)?, [xh, yh, zh], [xt[0], yt[0], zt[0]]);
        }
        Ok(())
    }
}

impl<S: Scalar, const CAP: usize, const TRI: usize> Default for Ldlt<S, CAP, TRI> {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn naive_solve(m: &[[f64; 6]; 6], b: &[f64; 6]) -> [f64; 6] {
        // Gaussian elimination with partial pivoting.
        let mut a = *m;
        let mut x = *b;
        for c in 0..6 {
            let p = (c..6)
                .max_by(|&i, &j| a[i][c].abs().partial_cmp(&a[j][c].abs()).unwrap())
                .unwrap();
            a.swap(c, p);
            x.swap(c, p);
            for r in c + 1..6 {
                let f = a[r][c] / a[c][c];
                for k in c..6 {
                    a[r][k] -= f * a[c][k];
                }
                x[r] -= f * x[c];
            }
        }
        for c in (0..6).rev() {
            for k in c + 1..6 {
                x[c] -= a[c][k] * x[k];
            }
            x[c] /= a[c][c];
        }
        x
    }

    fn spd() -> [[f64; 6]; 6] {
        let mut m = [[0.0; 6]; 6];
        for i in 0..6 {
            for j in 0..6 {
                let d = (i as f64 - j as f64) * 5.0;
                m[i][j] = 400.0 * libm::exp(-d * d / (2.0 * 30.0 * 30.0));
            }
            m[i][i] += 0.5 + i as f64 * 0.1;
        }
        m
    }

    #[test]
    fn matches_naive_solve() {
        let m = spd();
        let b = [1.0, -2.0, 0.5, 3.0, -1.0, 0.25];
        let mut f: Ldlt<f64, 8, 36> = Ldlt::new();
        f.set_dim(6);
        for i in 0..6 {
            f.row_mut(i).copy_from_slice(&m[i][..=i]);
        }
        f.factor().unwrap();
        let mut x = b;
        f.solve(&mut x).unwrap();
        let r = naive_solve(&m, &b);
        for i in 0..6 {
            assert!(
                (x[i] - r[i]).abs() < 1e-9 * r[i].abs().max(1.0),
                "{x:?} {r:?}"
            );
        }
    }

    #[test]
    fn pairs_and_a_last_single_row_factor_alike() {
        // Odd and even dimensions exercise the paired rows and the single
        // last row: L D Lᵀ must give back the matrix.
        for n in [1usize, 2, 5, 6] {
            let m = spd();
            let mut f: Ldlt<f64, 8, 36> = Ldlt::new();
            f.set_dim(n);
            for i in 0..n {
                f.row_mut(i).copy_from_slice(&m[i][..=i]);
            }
            f.factor().unwrap();
            let l = |i: usize, j: usize| {
                if i == j {
                    1.0
                } else if j < i {
                    f.a[row_start(i) + j]
                } else {
                    0.0
                }
            };
            let d = |k: usize| f.a[row_start(k) + k];
            for i in 0..n {
                for j in 0..=i {
                    let back: f64 = (0..n).map(|k| l(i, k) * d(k) * l(j, k)).sum();
                    assert!(
                        (back - m[i][j]).abs() < 1e-9 * m[i][j].abs().max(1.0),
                        "n {n} ({i},{j})"
                    );
                }
            }
        }
    }

    #[test]
    fn refuses_indefinite_and_nan() {
        let mut f: Ldlt<f64, 2, 3> = Ldlt::new();
        f.set_dim(2);
        f.row_mut(0).copy_from_slice(&[1.0]);
        f.row_mut(1).copy_from_slice(&[2.0, 1.0]);
        assert_eq!(f.factor(), Err(FactorError::NotPositiveDefinite { row: 1 }));
        f.row_mut(0).copy_from_slice(&[f64::NAN]);
        assert_eq!(f.factor(), Err(FactorError::NotPositiveDefinite { row: 0 }));
    }
}
