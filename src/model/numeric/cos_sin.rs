//! The cosine and sine of an angle in `f64`, for the phases a restore's
//! harmonics and the kernel's length scales are set up in.
//!
//! libm's `f64` `sin` and `cos` reduce any finite argument exactly
//! (`rem_pio2`, with its large-argument path), and on the target that
//! reduction is most of their 5.3 KiB of flash. The angles here are
//! `2π t / P` with `t` a grid time or a lag and `P` a period: far inside
//! the range where a three-part Cody-Waite reduction is exact
//! (docs/decisions.md, "`f64` phases: our `cos_sin`, not libm's").
//!
//! # Method
//!
//! `x = k π/2 + r`, `|r| <= π/4`, with `π/2` split into two 33-bit parts
//! and a rest, so that `k` times each part is exact for `|k| < 2^20`
//! (angles up to about 1.6e6 rad; beyond, the remainder rounds by
//! about `|x| * 1e-16`, and past about 1e15 rad, where an `f64` holds no
//! phase, the result is some value within [-1, 1]); then the Taylor series
//! of `sin r` to `r^17` and of `cos r` to `r^18` (the first terms left out
//! are below 1e-19 on `|r| <= π/4`), chosen and signed by `k mod 4`.

use core::f64::consts::{FRAC_2_PI, FRAC_PI_4};

/// `π/2` in three parts: two of 33 significant bits (`k` times each is
/// exact for `|k| < 2^20`), and the rest.
const PIO2_1: f64 = 1.570_796_326_734_125_6;
const PIO2_2: f64 = 6.077_100_506_303_966e-11;
const PIO2_3: f64 = 2.022_266_248_795_950_6e-21;

/// `(cos x, sin x)`; NaN for a non-finite `x`.
pub fn cos_sin(x: f64) -> (f64, f64) {
    let (quadrant, r) = reduce(x);
    let (c, s) = (cos_reduced(r), sin_reduced(r));
    match quadrant {
        0 => (c, s),
        1 => (-s, c),
        2 => (-c, -s),
        _ => (s, -c),
    }
}

/// `sin x` alone, half the work of [`cos_sin`]: the kernel's length
/// scales, set up each frame.
pub fn sin(x: f64) -> f64 {
    let (quadrant, r) = reduce(x);
    match quadrant {
        0 => sin_reduced(r),
        1 => cos_reduced(r),
        2 => -sin_reduced(r),
        _ => -cos_reduced(r),
    }
}

/// `x = k π/2 + r`: `k mod 4` and `r` (NaN for a non-finite `x`).
fn reduce(x: f64) -> (i64, f64) {
    if !x.is_finite() {
        return (0, f64::NAN);
    }
    let k = libm::round(x * FRAC_2_PI);
    let r = ((x - k * PIO2_1) - k * PIO2_2) - k * PIO2_3;
    // Beyond about 1e15 rad an `f64` holds no phase (its ulp is above
    // 0.1 rad) and the reduction can fail: some value within [-1, 1].
    let r = super::clamp(r, -FRAC_PI_4, FRAC_PI_4);
    // `k` is whole and finite; its two lowest bits pick the quadrant (a
    // cast saturates beyond i64, where the phase means nothing anyway).
    ((k as i64) & 3, r)
}

/// The Taylor series' coefficients of `r^n` for `n = first, first + 2,
/// ..., first + 14`, highest power first: `(-1)^(n/2) / n!` (integer
/// division), the signs of `sin` for odd `first` and of `cos` for even.
const fn series(first: u32) -> [f64; 8] {
    let mut terms = [0.0; 8];
    let (mut factorial, mut n) = (1.0, 1);
    let mut k = 0;
    while k < 8 {
        let power = first + 2 * k as u32;
        while n <= power {
            factorial *= n as f64;
            n += 1;
        }
        let sign = if (power / 2).is_multiple_of(2) {
            1.0
        } else {
            -1.0
        };
        terms[7 - k] = sign / factorial;
        k += 1;
    }
    terms
}

/// `r^3 .. r^17` of `sin r`, and `r^4 .. r^18` of `cos r`.
const SIN_TERMS: [f64; 8] = series(3);
const COS_TERMS: [f64; 8] = series(4);

/// `z` in the polynomial of `terms`, by Horner's rule.
fn horner(terms: &[f64; 8], z: f64) -> f64 {
    terms.iter().fold(0.0, |p, &t| t + z * p)
}

/// `sin r` for `|r| <= π/4`: `r - r^3/3! + ... + r^17/17!`.
fn sin_reduced(r: f64) -> f64 {
    let z = r * r;
    r + r * z * horner(&SIN_TERMS, z)
}

/// `cos r` for `|r| <= π/4`: `1 - r^2/2! + ... + r^18/18!`.
fn cos_reduced(r: f64) -> f64 {
    let z = r * r;
    (1.0 - 0.5 * z) + z * z * horner(&COS_TERMS, z)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The largest difference from libm's `cos` and `sin` over `xs`.
    fn worst(xs: impl Iterator<Item = f64>) -> f64 {
        let mut worst = 0.0f64;
        for x in xs {
            let (c, s) = cos_sin(x);
            assert_eq!(sin(x), s);
            worst = worst
                .max((c - libm::cos(x)).abs())
                .max((s - libm::sin(x)).abs());
        }
        worst
    }

    #[test]
    fn within_an_ulp_or_two_of_libm_where_the_phases_are() {
        // A dense grid over a turn and a half, and grid times over
        // periods of 2-2000 s up to a week.
        let turn = worst((-3_000_000..=3_000_000).map(|i| i as f64 * 1.6e-6));
        let mut rng = crate::testing::SplitMix64::new(9);
        let phases = worst((0..1_000_000).map(|_| {
            let t = rng.f64_in(0.0, 604_800.0);
            let p = rng.f64_in(2.0, 2000.0);
            core::f64::consts::TAU * t / p
        }));
        std::println!("cos_sin against libm: a turn {turn:.1e}, phases {phases:.1e}");
        assert!(turn <= 2.3e-16, "{turn:e}");
        assert!(phases <= 2.3e-16, "{phases:e}");
    }

    #[test]
    fn exact_at_quadrants_and_nan_beyond_finite() {
        assert_eq!(cos_sin(0.0), (1.0, 0.0));
        for k in 1..2_000 {
            // Near k π/2 the result is the small remainder: relative
            // accuracy there needs the three-part reduction.
            let x = k as f64 * core::f64::consts::FRAC_PI_2;
            let (c, s) = cos_sin(x);
            let small = if k % 2 == 0 { s } else { c };
            let want = if k % 2 == 0 {
                libm::sin(x)
            } else {
                libm::cos(x)
            };
            assert!((small - want).abs() <= 1e-31 + 1e-15 * want.abs(), "{k}");
        }
        for x in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let (c, s) = cos_sin(x);
            assert!(c.is_nan() && s.is_nan() && sin(x).is_nan());
        }
        for x in [1e300, -3.7e17, 2.5e15] {
            let (c, s) = cos_sin(x);
            assert!(c.abs() <= 1.0 && s.abs() <= 1.0, "{x}");
        }
    }
}
