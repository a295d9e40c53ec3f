//! The scalar type the model computes in.
//!
//! `f64` on the host is the reference and uses libm throughout. `f32` is
//! what runs on the target (single-precision FPU only).

use core::fmt::Debug;

use super::dot::{self, BLOCK};
use core::ops::{Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Sub, SubAssign};

/// Arithmetic and the few transcendental functions the model needs.
pub trait Scalar:
    Copy
    + Debug
    + Default
    + PartialOrd
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
    + MulAssign
    + DivAssign
{
    const ZERO: Self;
    const ONE: Self;
    const PI: Self;

    fn from_f64(x: f64) -> Self;
    fn to_f64(self) -> f64;
    fn from_usize(x: usize) -> Self {
        Self::from_f64(x as f64)
    }
    fn sin(self) -> Self;
    fn cos(self) -> Self;
    fn exp(self) -> Self;
    fn sqrt(self) -> Self;
    /// `e^self` for the kernel's exponents, which are `<= 0`. `f64`: exactly
    /// [`exp`](Self::exp). `f32`: [`super::approx::exp_nonpositive`], a
    /// lean version for `[-87, 0]` (relative error < 5e-7) that returns `0`
    /// below `-87`; positive arguments and NaN take the general `exp`.
    fn exp_nonpositive(self) -> Self;
    /// What [`sin2_scaled`](Self::sin2_scaled) multiplies the lag by for the
    /// period `period` (s): `π / P` for `f64`, `1 / P` for `f32` (whose
    /// reduction works in periods).
    fn sin2_factor(period: f64) -> Self;
    /// `coeff * sin²(π self / P)` with `factor = Self::sin2_factor(P)`: the
    /// periodic part of the kernel's exponent. `f64`: `s = sin(factor *
    /// self)`, then `coeff * s * s`, in that order. `f32`:
    /// [`super::approx::sin2_scaled`] (absolute error of `sin²` < 3e-7 for
    /// `|self / P| < 2^22`).
    fn sin2_scaled(self, factor: Self, coeff: Self) -> Self;
    fn abs(self) -> Self {
        if self < Self::ZERO {
            -self
        } else {
            self
        }
    }
    fn is_finite(self) -> bool;
    /// Four dot products against a shared vector (the factorisation's
    /// inner loop): `rows[r] · c` over the shortest slice.
    fn dot_rows(rows: [&[Self]; BLOCK], c: &[Self]) -> [Self; BLOCK] {
        dot::dot_rows_portable(rows, c)
    }
    /// The forward substitution's inner loop for three right-hand sides:
    /// `[l · x, l · y, l · z]` over the shortest slice.
    fn dot3(l: &[Self], x: &[Self], y: &[Self], z: &[Self]) -> [Self; 3] {
        dot::dot3_portable(l, x, y, z)
    }
    /// The back substitution's inner loop for three right-hand sides:
    /// `v[r][k] -= l[k] * f[r]` over the shortest slice.
    fn sub_scaled3(l: &[Self], v: [&mut [Self]; 3], f: [Self; 3]) {
        dot::sub_scaled3_portable(l, v, f)
    }
    fn min(self, other: Self) -> Self {
        if other < self {
            other
        } else {
            self
        }
    }
    fn max(self, other: Self) -> Self {
        if other > self {
            other
        } else {
            self
        }
    }
    /// `self` limited to `[lo, hi]`; NaN maps to `lo`.
    fn clamp_to(self, lo: Self, hi: Self) -> Self {
        if self >= lo {
            if self > hi {
                hi
            } else {
                self
            }
        } else {
            lo
        }
    }
}

impl Scalar for f64 {
    const ZERO: Self = 0.0;
    const ONE: Self = 1.0;
    const PI: Self = core::f64::consts::PI;

    fn from_f64(x: f64) -> Self {
        x
    }
    fn to_f64(self) -> f64 {
        self
    }
    fn sin(self) -> Self {
        libm::sin(self)
    }
    fn cos(self) -> Self {
        libm::cos(self)
    }
    fn exp(self) -> Self {
        libm::exp(self)
    }
    fn sqrt(self) -> Self {
        libm::sqrt(self)
    }
    fn exp_nonpositive(self) -> Self {
        libm::exp(self)
    }
    fn sin2_factor(period: f64) -> Self {
        core::f64::consts::PI / period
    }
    fn sin2_scaled(self, factor: Self, coeff: Self) -> Self {
        let s = libm::sin(factor * self);
        coeff * s * s
    }
    fn is_finite(self) -> bool {
        f64::is_finite(self)
    }
}

impl Scalar for f32 {
    const ZERO: Self = 0.0;
    const ONE: Self = 1.0;
    const PI: Self = core::f32::consts::PI;

    fn from_f64(x: f64) -> Self {
        x as f32
    }
    fn to_f64(self) -> f64 {
        self as f64
    }
    fn sin(self) -> Self {
        super::approx::sin(self)
    }
    fn cos(self) -> Self {
        super::approx::cos(self)
    }
    fn exp(self) -> Self {
        super::approx::exp(self)
    }
    fn sqrt(self) -> Self {
        super::approx::sqrt(self)
    }
    #[inline(always)]
    fn exp_nonpositive(self) -> Self {
        super::approx::exp_nonpositive(self)
    }
    fn sin2_factor(period: f64) -> Self {
        (1.0 / period) as f32
    }
    #[inline(always)]
    fn sin2_scaled(self, factor: Self, coeff: Self) -> Self {
        super::approx::sin2_scaled(self, factor, coeff)
    }
    fn is_finite(self) -> bool {
        f32::is_finite(self)
    }
    #[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
    fn dot_rows(rows: [&[Self]; BLOCK], c: &[Self]) -> [Self; BLOCK] {
        super::vfp::dot_rows(rows, c)
    }
    #[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
    fn dot3(l: &[Self], x: &[Self], y: &[Self], z: &[Self]) -> [Self; 3] {
        super::vfp::dot3(l, x, y, z)
    }
    #[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
    fn sub_scaled3(l: &[Self], v: [&mut [Self]; 3], f: [Self; 3]) {
        super::vfp::sub_scaled3(l, v, f)
    }
}
