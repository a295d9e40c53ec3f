//! The inner products the linear algebra is made of, in portable Rust.
//!
//! [`Scalar`](super::Scalar)'s `dot_rows`, `dot3` and `sub_scaled3` default
//! to these; `f32` on the Cortex-M4F overrides them with the hand-scheduled
//! loops of `vfp`, which give bit-identical results. They need only
//! arithmetic, so this module depends on nothing else in the crate: the
//! scalar type uses it, and the factorisation uses the scalar type.

use core::ops::{Add, AddAssign, Mul, SubAssign};

/// What the loops need of an element: zero (`Default`) and arithmetic.
pub trait Elem:
    Copy + Default + Add<Output = Self> + Mul<Output = Self> + AddAssign + SubAssign
{
}

impl<T: Copy + Default + Add<Output = T> + Mul<Output = T> + AddAssign + SubAssign> Elem for T {}

/// Rows the factorisation takes together ([`crate::model::ldlt::Ldlt::factor`]).
pub const BLOCK: usize = 4;

/// `BLOCK` dot products sharing their second operand: `rows[r] · c`, over
/// the shortest of the slices ([`Scalar::dot_rows`](super::Scalar::dot_rows): hand-scheduled for
/// `f32` on the Cortex-M4F, this elsewhere).
#[inline(always)]
pub fn dot_rows_portable<S: Elem>(rows: [&[S]; BLOCK], c: &[S]) -> [S; BLOCK] {
    let n = rows.iter().fold(c.len(), |n, r| n.min(r.len()));
    let mut acc = [S::default(); BLOCK];
    let mut k = 0;
    // One index for every operand and four steps per pass: VLDR takes only
    // immediate offsets, so each operand costs one pointer increment per
    // pass, shared by its four loads.
    while k + 4 <= n {
        for step in 0..4 {
            // SAFETY: k + step < n <= the length of every slice.
            unsafe {
                let ck = *c.get_unchecked(k + step);
                for (a, row) in acc.iter_mut().zip(&rows) {
                    *a += *row.get_unchecked(k + step) * ck;
                }
            }
        }
        k += 4;
    }
    while k < n {
        for (a, row) in acc.iter_mut().zip(&rows) {
            *a += row[k] * c[k];
        }
        k += 1;
    }
    acc
}

/// `[l · x, l · y, l · z]` over the shortest slice, each sum taken in order
/// from zero ([`Scalar::dot3`](super::Scalar::dot3): hand-scheduled for `f32` on the
/// Cortex-M4F, this elsewhere).
#[inline(always)]
pub fn dot3_portable<S: Elem>(l: &[S], x: &[S], y: &[S], z: &[S]) -> [S; 3] {
    let mut s = [S::default(); 3];
    for (((&l, &a), &b), &c) in l.iter().zip(x).zip(y).zip(z) {
        s[0] += l * a;
        s[1] += l * b;
        s[2] += l * c;
    }
    s
}

/// `v[r][k] -= l[k] * f[r]` for the three vectors, over the shortest slice
/// ([`Scalar::sub_scaled3`](super::Scalar::sub_scaled3)).
#[inline(always)]
pub fn sub_scaled3_portable<S: Elem>(l: &[S], v: [&mut [S]; 3], f: [S; 3]) {
    let [x, y, z] = v;
    for (((&l, a), b), c) in l.iter().zip(x).zip(y).zip(z) {
        *a -= l * f[0];
        *b -= l * f[1];
        *c -= l * f[2];
    }
}

/// Dot product with four partial sums: the factorisation spends most of
/// its time here, and four independent chains let the compiler keep them in
/// registers and load operands in pairs.
pub fn dot<S: Elem>(a: &[S], b: &[S]) -> S {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut acc = [S::default(); 4];
    let mut ca = a.chunks_exact(4);
    let mut cb = b.chunks_exact(4);
    for (x, y) in (&mut ca).zip(&mut cb) {
        acc[0] += x[0] * y[0];
        acc[1] += x[1] * y[1];
        acc[2] += x[2] * y[2];
        acc[3] += x[3] * y[3];
    }
    for (&x, &y) in ca.remainder().iter().zip(cb.remainder()) {
        acc[0] += x * y;
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3])
}
