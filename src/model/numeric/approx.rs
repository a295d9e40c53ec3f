//! Accurate, fast single-precision `sin`, `cos`, `exp` and `sqrt` in pure
//! `f32` arithmetic, for the Cortex-M4F (single-precision FPU only).
//!
//! libm's `sinf`/`expf` compute internally in `f64`, which is software on the
//! target (~1,500 instructions for a sin+exp pair). Everything here uses only
//! `f32` multiplies/adds (plus a little integer work), no tables beyond 32
//! bytes, no `f64`, no libm (except the `sqrt` fallback on targets without an
//! FPU square root), and cannot panic.
//!
//! # Method
//!
//! * `sin`/`cos`: `x = k*pi/2 + r`, `|r| <= pi/4`, then a minimax polynomial
//!   for `sin(r)` or `cos(r)` chosen by `k mod 4`.
//!   * `|x| < 1e5` (`|k| < 2^16`): Cody-Waite reduction with `pi/2` split into
//!     four `f32` parts, the first three with 8 significant bits so that
//!     `k * part` is exact; the split represents `pi/2` to ~5e-17, so the
//!     reduction error is about `|k| * 5e-17 + 0.5 ulp(r)`, i.e. at most
//!     ~3e-12 plus the final rounding of `r`.
//!   * `|x| >= 1e5`: Payne-Hanek reduction in integer arithmetic with 256 bits
//!     of `2/pi` (a 32-byte table), exact for every finite `f32`; only the
//!     final conversion of `r` to `f32` rounds.
//!   * Polynomials (Remez fits in `f64` by a small Python script, weighted
//!     minimax on `[0, pi/4 + 0.004]`, coefficients rounded to `f32`):
//!     `sin r = r + r^3 (S1 + S2 r^2 + S3 r^4)`, relative error 4.0e-9;
//!     `cos r = 1 - r^2/2 + r^4 (C1 + C2 r^2 + C3 r^4)`, absolute error 5.6e-10.
//!     Both are far below `f32` rounding; the measured errors below are
//!     `f32` rounding.
//! * `exp`: `x = k ln2 + r`, `|r| <= ln2/2`, Cody-Waite with `ln2` split into
//!   a 16-bit part and an `f32` rest; `exp r = 1 + r + r^2 P(r)` with a
//!   degree-4 `P` (Remez fit, relative error 3.2e-9 on `[-0.349, 0.349]`);
//!   scaling by `2^k` is done on the exponent bits (in two steps for
//!   subnormal results and for `k = 128`).
//! * `sqrt`: on ARM hard-float targets (the Cortex-M4F) the `vsqrt.f32`
//!   instruction via inline assembly (14 cycles, correctly rounded); elsewhere
//!   `libm::sqrtf` (correctly rounded; on x86-64 it uses `sqrtss`). On
//!   thumbv7em-none-eabihf `libm::sqrtf` is a software routine (not
//!   `vsqrt`), `core::intrinsics::sqrtf32` is unstable, and `f32::sqrt` is
//!   not in `core`, so the inline assembly is the cheapest correct route.
//!
//! # Measured accuracy (unit tests below, against `f64` libm)
//!
//! * `sin`, `cos` on `[-pi, pi]` (2,000,001-point grid): max absolute error
//!   8.4e-8 (sin) and 9.5e-8 (cos); bound tested: 2e-7.
//! * On `[-1e4, 1e4]` (4,000,001 points): 1.0e-7 (sin), 1.1e-7 (cos): the
//!   Cody-Waite reduction error there is below 1e-12, what remains is the
//!   rounding of `r` (half an ulp of `r`, <= 3e-8) and of the polynomial.
//!   Near multiples of `pi/2` up to `k = 7e4`: 3.0e-8.
//! * 2,000,000 random `f32` of every magnitude up to `f32::MAX`
//!   (Payne-Hanek): 1.1e-7.
//! * `exp` on `[-87, 88]` (4,000,001 points plus 1,000,001 on `[-1, 1]`):
//!   max relative error 8.0e-8 (bound tested: 5e-7).
//! * `sqrt`: bit-identical to `libm::sqrtf` (correctly rounded).
//!
//! (The numbers are also printed by the tests: `cargo test --lib --target
//! x86_64-unknown-linux-gnu approx -- --nocapture`.)
//!
//! # Cost per call (floating-point operations, estimate)
//!
//! * `sin` or `cos`, `|x| < 1e5`: reduction 1 mul + 2 add (rounding trick) +
//!   4 mul + 4 sub, polynomial 6 mul + 5 add, about 22 flops plus a few
//!   integer/bit operations and one branch. `sin_cos` shares the reduction
//!   (about 33 flops for both). The Payne-Hanek path (`|x| >= 1e5`) costs a
//!   few dozen integer instructions (64x64-bit multiplies) more.
//! * `exp`: 1 mul + 2 add (rounding) + 2 mul + 2 sub (reduction) + 7 mul +
//!   7 add (polynomial) + 1 mul (scaling), about 22 flops.
//! * `sqrt`: one `vsqrt.f32` (14 cycles) and four register moves on the
//!   target.
//!
//! On thumbv7em-none-eabihf (`opt-level = "s"`) the compiled functions are
//! about 56 (`sin`), 66 (`sin_cos`), 59 (`exp`) and 10 (`sqrt`) instructions
//! long, mostly straight-line (LLVM uses `vmla.f32`, which rounds like the
//! separate multiply and add).

/// `1.5 * 2^23`: adding and subtracting it rounds an `f32` of magnitude
/// `< 2^22` to the nearest integer, which then sits in the low mantissa bits.
const ROUND_MAGIC: f32 = 12_582_912.0;
/// Bit pattern of `ROUND_MAGIC`.
const ROUND_MAGIC_BITS: i32 = 0x4B40_0000;

const FRAC_2_PI: f32 = core::f32::consts::FRAC_2_PI;
/// `pi/2 = PIO2_1 + PIO2_2 + PIO2_3 + PIO2_4 (+ ~ -5.0e-17)`; the first three
/// have 8 significant bits, so `k * PIO2_i` is exact for `|k| < 2^16`.
const PIO2_1: f32 = f32::from_bits(0x3FC90000); // 1.5703125
const PIO2_2: f32 = f32::from_bits(0x39FD0000); // 4.825592041015625e-4
const PIO2_3: f32 = f32::from_bits(0x35AA0000); // 1.2665987014770508e-6
const PIO2_4: f32 = f32::from_bits(0x30885A31); // 9.92093629470503e-10
/// Arguments below this use Cody-Waite; `|k| <= 63663 < 2^16` there.
const CODY_WAITE_LIMIT: f32 = 1.0e5;

/// Bits 1..=256 of the binary expansion of `2/pi` (`2/pi = 0.A2F9836E...`).
const TWO_OVER_PI: [u32; 8] = [
    0xA2F9_836E,
    0x4E44_1529,
    0xFC27_57D1,
    0xF534_DDC0,
    0xDB62_9599,
    0x3C43_9041,
    0xFE51_63AB,
    0xDEBB_C561,
];
/// `pi/2` in unsigned fixed point with 62 fractional bits.
const PIO2_Q62: u64 = 0x6487_ED51_10B4_611A;

// sin r = r + r^3 (S1 + S2 r^2 + S3 r^4) on |r| <= pi/4 + 0.004
const S1: f32 = -0.166_666_54;
const S2: f32 = 0.008_332_137;
const S3: f32 = -1.951_196e-4;
// cos r = 1 - r^2/2 + r^4 (C1 + C2 r^2 + C3 r^4)
const C1: f32 = 0.041_666_663;
const C2: f32 = -0.001_388_811_7;
const C3: f32 = 2.451_566_7e-5;

const LOG2_E: f32 = core::f32::consts::LOG2_E;
/// `ln 2 = LN2_HI + LN2_LO (+ 5.5e-14)`, `LN2_HI` has 16 significant bits.
const LN2_HI: f32 = f32::from_bits(0x3F317200); // 0.693145751953125
const LN2_LO: f32 = 1.428_606_8e-6;
// exp r = 1 + r + r^2 (E2 + E3 r + E4 r^2 + E5 r^3 + E6 r^4) on |r| <= 0.349
const E2: f32 = 0.499_999_93;
const E3: f32 = 0.166_665_17;
const E4: f32 = 0.041_668_427;
const E5: f32 = 0.008_369_118;
const E6: f32 = 0.001_381_376_7;
/// Largest `f32` whose exponential is finite (`ln(f32::MAX) = 88.7228391`).
const EXP_OVERFLOW: f32 = 88.722_83;
/// Below `-150 ln 2` the exponential rounds to zero.
const EXP_UNDERFLOW: f32 = -103.972_08;

#[inline(always)]
fn sin_poly(r: f32) -> f32 {
    let z = r * r;
    r + r * z * (S1 + z * (S2 + z * S3))
}

#[inline(always)]
fn cos_poly(r: f32) -> f32 {
    let z = r * r;
    1.0 - 0.5 * z + z * z * (C1 + z * (C2 + z * C3))
}

/// `x = k*pi/2 + r` with `|r| <~ pi/4`; returns `(r, k mod 4)`. Finite `x` only.
#[inline(always)]
fn reduce(x: f32) -> (f32, u32) {
    let ax = f32::from_bits(x.to_bits() & 0x7FFF_FFFF);
    if ax < CODY_WAITE_LIMIT {
        let t = x * FRAC_2_PI + ROUND_MAGIC;
        let k = t - ROUND_MAGIC;
        let r = x - k * PIO2_1;
        let r = r - k * PIO2_2;
        let r = r - k * PIO2_3;
        let r = r - k * PIO2_4;
        (r, t.to_bits() & 3)
    } else {
        reduce_large(x)
    }
}

/// Payne-Hanek reduction for finite `|x| >= 2^16`, exact up to the final
/// rounding of `r`.
#[inline(never)]
fn reduce_large(x: f32) -> (f32, u32) {
    let bits = x.to_bits();
    let neg = bits >> 31 != 0;
    let biased = ((bits >> 23) & 0xFF) as i32;
    // |x| = m * 2^e with a 24-bit integer m (|x| >= 1e5 is normal).
    let m = ((bits & 0x007F_FFFF) | 0x0080_0000) as u128;
    let e = biased - 150; // -7 ..= 104 for 1e5 <= |x| < 2^128
                          // Bits of 2/pi are numbered from 1 after the binary point; bit i has
                          // weight 2^(e - i) in |x| * 2/pi. Bits i <= e - 2 contribute multiples
                          // of 4 and are dropped; take the 96 bits i = e-1 ..= e+94 as an integer
                          // W, so |x| * 2/pi = m * W * 2^-94 (mod 4) up to < 2^-70.
                          // In the padded bit string (32 zero bits in front) bit i sits at t = i + 31.
    let t0 = (e + 30).clamp(0, 255 - 95) as u32;
    let w = (t0 / 32) as usize;
    let s = t0 % 32;
    let word = |j: usize| -> u128 {
        // padded word j: word 0 is the zero padding
        if j == 0 {
            0
        } else {
            match TWO_OVER_PI.get(j - 1) {
                Some(v) => *v as u128,
                None => 0,
            }
        }
    };
    let chunk = (word(w) << 96) | (word(w + 1) << 64) | (word(w + 2) << 32) | word(w + 3);
    let window = (chunk << s) >> 32; // 96 bits starting at t0
                                     // y = |x| * 2/pi mod 4, in units of 2^-126 (top two bits: quadrant).
    let y = (m * window) << 32;
    let q = (y.wrapping_add(1u128 << 125) >> 126) as u32 & 3;
    // signed remainder in [-1/2, 1/2) quadrant, units of 2^-126
    let frac = y.wrapping_sub((q as u128) << 126) as i128;
    let f64bits = (frac >> 64) as i64; // units of 2^-62
    let rq = (f64bits as i128 * PIO2_Q62 as i128) >> 64; // r in units of 2^-60
    let r = (rq as i64) as f32 * (1.0 / 1_152_921_504_606_846_976.0); // 2^-60
    if neg {
        (-r, q.wrapping_neg() & 3)
    } else {
        (r, q)
    }
}

/// Sine of `x` (radians). NaN and infinities give NaN.
#[inline]
pub fn sin(x: f32) -> f32 {
    if !x.is_finite() {
        return f32::NAN;
    }
    let (r, q) = reduce(x);
    let v = if q & 1 == 0 { sin_poly(r) } else { cos_poly(r) };
    f32::from_bits(v.to_bits() ^ ((q & 2) << 30))
}

/// Cosine of `x` (radians). NaN and infinities give NaN.
#[inline]
pub fn cos(x: f32) -> f32 {
    if !x.is_finite() {
        return f32::NAN;
    }
    let (r, q) = reduce(x);
    let q = q.wrapping_add(1);
    let v = if q & 1 == 0 { sin_poly(r) } else { cos_poly(r) };
    f32::from_bits(v.to_bits() ^ ((q & 2) << 30))
}

/// `(sin x, cos x)` sharing one argument reduction.
#[inline]
pub fn sin_cos(x: f32) -> (f32, f32) {
    if !x.is_finite() {
        return (f32::NAN, f32::NAN);
    }
    let (r, q) = reduce(x);
    let s = sin_poly(r);
    let c = cos_poly(r);
    let (sv, cv) = if q & 1 == 0 { (s, c) } else { (c, s) };
    let sin_sign = (q & 2) << 30;
    let cos_sign = (q.wrapping_add(1) & 2) << 30;
    (
        f32::from_bits(sv.to_bits() ^ sin_sign),
        f32::from_bits(cv.to_bits() ^ cos_sign),
    )
}

/// `e^x`. Returns `+0` below the underflow limit (`x < -103.97`), `+inf` above
/// the overflow limit (`x > 88.7228`), NaN for NaN.
#[inline]
pub fn exp(x: f32) -> f32 {
    if x.is_nan() {
        return x;
    }
    if x > EXP_OVERFLOW {
        return f32::INFINITY;
    }
    if x < EXP_UNDERFLOW {
        return 0.0;
    }
    let t = x * LOG2_E + ROUND_MAGIC;
    let kf = t - ROUND_MAGIC;
    let k = (t.to_bits() as i32).wrapping_sub(ROUND_MAGIC_BITS); // -150 ..= 128
    let r = (x - kf * LN2_HI) - kf * LN2_LO;
    let p = r * r * (E2 + r * (E3 + r * (E4 + r * (E5 + r * E6))));
    let er = 1.0 + (r + p);
    if k >= -126 {
        if k <= 127 {
            er * pow2(k)
        } else {
            er * pow2(127) * pow2(k - 127)
        }
    } else {
        // subnormal result: scale in two steps (double rounding is harmless)
        er * pow2(k + 64) * pow2(-64)
    }
}

/// `2^k` for `-126 <= k <= 127`.
#[inline(always)]
fn pow2(k: i32) -> f32 {
    f32::from_bits(((k + 127) as u32) << 23)
}

// Kernel-specialised functions (see `Scalar::exp_nonpositive` and
// `Scalar::sin2_scaled`): no range handling beyond what the kernel needs.

/// `exp_nonpositive` returns `0` below this (`e^-87 = 1.6e-38`, just above
/// the smallest normal `f32`), so every result is normal and the exponent can
/// be added to the bits directly.
const EXP_NP_MIN: f32 = -87.0;
/// `EXP_NP_MIN.to_bits() - 0x8000_0000`: `x.to_bits() - 0x8000_0000`
/// (wrapping) is at most this exactly for `x` in `[-87, -0]`.
const EXP_NP_RANGE: u32 = 0x42AE_0000;
// e^r = X0 + r (X1 + r (X2 + r (X3 + r (X4 + r X5)))) on |r| <= ln2/2 + 5e-4,
// relative minimax fit (Remez in mpmath, coefficients rounded to f32):
// fit error 7.6e-8.
const X0: f32 = 1.000_000_1;
const X1: f32 = 0.999_999_7;
const X2: f32 = 0.499_988_88;
const X3: f32 = 0.166_675_8;
const X4: f32 = 0.041_916_095;
const X5: f32 = 0.008_297_552;

/// `e^x` for `x` in `[-87, 0]`, the kernel's arguments: relative error
/// below 5e-7 there (measured: see the tests). Below `-87` (and for `-inf`)
/// the result is `0`; for positive `x` and NaN it is [`exp`] (off the fast
/// path).
///
/// `x = k ln2 + r` with `k` rounded by the `1.5 * 2^23` trick and the
/// two-part `ln2` of [`exp`]; a degree-5 polynomial for `e^r`, `|r| <= ln2/2`;
/// `k` is added to the exponent bits (the result is normal for `x >= -87`).
#[inline(always)]
pub fn exp_nonpositive(x: f32) -> f32 {
    // One unsigned compare: -0.0 ..= -87.0 are the bit patterns
    // 0x8000_0000 ..= 0xC2AE_0000; positive numbers, NaN and x < -87 are not.
    if x.to_bits().wrapping_sub(0x8000_0000) > EXP_NP_RANGE {
        return exp_nonpositive_outside(x);
    }
    // k = round(x log2 e) in -126 ..= 0: adding 1.5 * 2^23 leaves k in the
    // low mantissa bits of t, whose bit pattern shifted left by 23 is
    // exactly k << 23 (0x4B40_0000 << 23 wraps to 0). Cheaper on the target
    // than a float-to-int conversion (which also needs a move back).
    let t = x * LOG2_E + ROUND_MAGIC;
    let kf = t - ROUND_MAGIC;
    let r = (x - kf * LN2_HI) - kf * LN2_LO;
    let p = X0 + r * (X1 + r * (X2 + r * (X3 + r * (X4 + r * X5))));
    // p is in [0.70, 1.42]; k >= -126 keeps the biased exponent >= 1.
    f32::from_bits(p.to_bits().wrapping_add(t.to_bits() << 23))
}

#[cold]
#[inline(never)]
fn exp_nonpositive_outside(x: f32) -> f32 {
    if x < EXP_NP_MIN {
        0.0
    } else {
        exp(x)
    }
}

// sin²(pi r) = z (A1 + A2 z + A3 z^2 + A4 z^3 + A5 z^4 + A6 z^5), z = r^2,
// |r| <= 1/2: minimax for the absolute error (Remez in mpmath, coefficients
// rounded to f32): fit error 5.9e-9. (Squaring an odd polynomial for
// sin(pi r) instead doubles the f32 rounding near sin² = 1.)
const A1: f32 = 9.869_603;
const A2: f32 = -32.469_58;
const A3: f32 = 42.725_384;
const A4: f32 = -30.085_953;
const A5: f32 = 12.990_729;
const A6: f32 = -3.272_943_7;

/// `coeff * sin²(π d / P)` given `inv_period = 1/P`: the periodic part of
/// the kernel's exponent. Absolute error of the `sin²` factor below 3e-7
/// (measured: see the tests) for `|d / P| < 2^22`, beyond that the argument
/// reduction is wrong; NaN or infinite `d / P` give NaN.
///
/// `sin²` has period 1 in `x = d / P`: `x` is reduced to `r = x - round(x)`
/// in `[-1/2, 1/2]` exactly (rounding by adding and subtracting
/// `1.5 * 2^23`), and `sin²(π r)` is a polynomial in `r²`. Computing `x = d/P`
/// directly rather than `(π/P) d` then reducing modulo `π` costs no accuracy:
/// both round the product once, and `r` is exact.
#[inline(always)]
pub fn sin2_scaled(d: f32, inv_period: f32, coeff: f32) -> f32 {
    let x = d * inv_period;
    let r = x - ((x + ROUND_MAGIC) - ROUND_MAGIC);
    let z = r * r;
    let q = A1 + z * (A2 + z * (A3 + z * (A4 + z * (A5 + z * A6))));
    coeff * (z * q)
}

/// Square root, correctly rounded; negative inputs give NaN.
#[inline]
pub fn sqrt(x: f32) -> f32 {
    sqrt_impl(x)
}

#[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
#[inline(always)]
fn sqrt_impl(x: f32) -> f32 {
    // The VFP `s` register class needs the unstable `vfp2` target feature
    // in `asm!`, so pass the value in a core register and borrow s15 (saved
    // and restored inside the block, so no clobber is needed).
    let y: u32;
    // SAFETY: every ARM hard-float (eabihf) target has a VFP unit with
    // `vsqrt.f32`; the block touches only s15, which it restores, and the
    // registers given to it.
    unsafe {
        core::arch::asm!(
            "vmov {save}, s15",
            "vmov s15, {x}",
            "vsqrt.f32 s15, s15",
            "vmov {y}, s15",
            "vmov s15, {save}",
            x = in(reg) x.to_bits(),
            y = lateout(reg) y,
            save = out(reg) _,
            options(pure, nomem, nostack),
        );
    }
    f32::from_bits(y)
}

#[cfg(not(all(target_arch = "arm", target_abi = "eabihf")))]
#[inline(always)]
fn sqrt_impl(x: f32) -> f32 {
    libm::sqrtf(x)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::SplitMix64;
    use std::println;

    /// `n + 1` evenly spaced points on `[a, b]` as f32.
    fn grid(a: f64, b: f64, n: usize) -> impl Iterator<Item = f32> {
        (0..=n).map(move |i| (a + (b - a) * i as f64 / n as f64) as f32)
    }

    fn max_abs_err(
        f: fn(f32) -> f32,
        g: fn(f64) -> f64,
        xs: impl Iterator<Item = f32>,
    ) -> (f64, f32) {
        let mut worst = (0.0f64, 0.0f32);
        for x in xs {
            let e = (f(x) as f64 - g(x as f64)).abs();
            assert!(e.is_finite(), "x = {x}");
            if e > worst.0 {
                worst = (e, x);
            }
        }
        worst
    }

    #[test]
    fn sin_cos_on_minus_pi_pi() {
        let pi = core::f64::consts::PI;
        let (es, xs) = max_abs_err(sin, libm::sin, grid(-pi, pi, 2_000_000));
        let (ec, xc) = max_abs_err(cos, libm::cos, grid(-pi, pi, 2_000_000));
        println!("[-pi, pi]: sin max abs err {es:.3e} at {xs}, cos {ec:.3e} at {xc}");
        assert!(es <= 2e-7 && ec <= 2e-7);
        // every f32 in [-pi/4, pi/4] near 0 and the small-argument behaviour
        for x in [0.0f32, -0.0, 1e-30, -1e-30, 1e-10, f32::MIN_POSITIVE, 1e-45] {
            assert_eq!(sin(x), x);
            assert_eq!(cos(x), 1.0);
        }
    }

    #[test]
    fn sin_cos_reduction_up_to_1e4_and_beyond() {
        let (es, xs) = max_abs_err(sin, libm::sin, grid(-1e4, 1e4, 4_000_000));
        let (ec, xc) = max_abs_err(cos, libm::cos, grid(-1e4, 1e4, 4_000_000));
        println!("[-1e4, 1e4]: sin max abs err {es:.3e} at {xs}, cos {ec:.3e} at {xc}");
        assert!(es <= 2e-7 && ec <= 2e-7);
        // Across the Cody-Waite / Payne-Hanek switch, and multiples of pi/2.
        let (es, _) = max_abs_err(sin, libm::sin, grid(9.9e4, 1.01e5, 1_000_000));
        let (ec, _) = max_abs_err(cos, libm::cos, grid(-1.01e5, -9.9e4, 1_000_000));
        println!("around 1e5: sin {es:.3e}, cos {ec:.3e}");
        assert!(es <= 2e-7 && ec <= 2e-7);
        let mut worst = 0.0f64;
        for k in -70_000i32..70_000 {
            let x = (k as f64 * core::f64::consts::FRAC_PI_2) as f32;
            let e1 = (sin(x) as f64 - libm::sin(x as f64)).abs();
            let e2 = (cos(x) as f64 - libm::cos(x as f64)).abs();
            worst = worst.max(e1).max(e2);
        }
        println!("near k pi/2: {worst:.3e}");
        assert!(worst <= 2e-7);
    }

    #[test]
    fn sin_cos_huge_and_special() {
        // All exponents up to f32::MAX, pseudo-random mantissas.
        let mut rng = SplitMix64::new(1);
        let mut worst = 0.0f64;
        for _ in 0..2_000_000 {
            let state = rng.next_u64();
            let bits = (state >> 32) as u32 & 0x7F7F_FFFF | ((state as u32) & 0x8000_0000);
            let x = f32::from_bits(bits);
            let e1 = (sin(x) as f64 - libm::sin(x as f64)).abs();
            let e2 = (cos(x) as f64 - libm::cos(x as f64)).abs();
            let (s, c) = sin_cos(x);
            assert_eq!(
                (s.to_bits(), c.to_bits()),
                (sin(x).to_bits(), cos(x).to_bits())
            );
            worst = worst.max(e1).max(e2);
        }
        println!("random f32 of all magnitudes: sin/cos max abs err {worst:.3e}");
        assert!(worst <= 2e-7);
        for x in [
            f32::MAX,
            -f32::MAX,
            1e5,
            65536.0,
            1e10,
            1e30,
            16_367_173.0 * 2f32.powi(72),
        ] {
            for (f, g) in [
                (sin as fn(f32) -> f32, libm::sin as fn(f64) -> f64),
                (cos, libm::cos),
            ] {
                assert!((f(x) as f64 - g(x as f64)).abs() <= 2e-7, "x = {x}");
            }
        }
        for x in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            assert!(sin(x).is_nan() && cos(x).is_nan());
            assert!(sin_cos(x).0.is_nan() && sin_cos(x).1.is_nan());
        }
    }

    #[test]
    fn exp_accuracy() {
        let mut worst = (0.0f64, 0.0f32);
        for x in grid(-87.0, 88.0, 4_000_000).chain(grid(-1.0, 1.0, 1_000_000)) {
            let want = libm::exp(x as f64);
            let e = ((exp(x) as f64 - want) / want).abs();
            if e > worst.0 {
                worst = (e, x);
            }
        }
        println!(
            "exp on [-87, 88]: max rel err {:.3e} at {}",
            worst.0, worst.1
        );
        assert!(worst.0 <= 5e-7);
    }

    #[test]
    fn exp_limits_and_special() {
        assert!(exp(f32::NAN).is_nan());
        assert_eq!(exp(f32::INFINITY), f32::INFINITY);
        assert_eq!(exp(f32::NEG_INFINITY), 0.0);
        assert_eq!(exp(89.0), f32::INFINITY);
        assert_eq!(exp(f32::MAX), f32::INFINITY);
        assert_eq!(exp(-104.0), 0.0);
        assert_eq!(exp(-1000.0), 0.0);
        assert_eq!(exp(-f32::MAX), 0.0);
        assert_eq!(exp(0.0), 1.0);
        assert_eq!(exp(-0.0), 1.0);
        // largest finite result, and the subnormal range stays close
        let top = exp(EXP_OVERFLOW);
        assert!(top.is_finite());
        let want = libm::exp(EXP_OVERFLOW as f64);
        assert!(((top as f64 - want) / want).abs() <= 5e-7);
        for x in grid(-103.9, -87.0, 100_000) {
            let want = libm::exp(x as f64);
            let got = exp(x) as f64;
            // absolute error within an ulp of the smallest normal's scale
            assert!(
                (got - want).abs() <= 2f64.powi(-149) + 5e-7 * want,
                "x = {x}"
            );
        }
    }

    #[test]
    fn exp_nonpositive_accuracy() {
        let mut worst = (0.0f64, 0.0f32);
        let mut check = |x: f32| {
            let want = libm::exp(x as f64);
            let e = ((exp_nonpositive(x) as f64 - want) / want).abs();
            if e > worst.0 {
                worst = (e, x);
            }
        };
        for x in grid(-87.0, 0.0, 8_000_000).chain(grid(-1.0, 0.0, 2_000_000)) {
            check(x);
        }
        // every f32 in [-2, -0.25] (the reduction's k = -3 ..= 0 and the
        // rounding boundaries at k ln2 + ln2/2), and around each boundary
        let mut b = (-0.25f32).to_bits();
        while b <= (-2.0f32).to_bits() {
            check(f32::from_bits(b));
            b += 1;
        }
        for k in 0..126 {
            let mid = -((k as f64 + 0.5) * core::f64::consts::LN_2) as f32;
            let mb = mid.to_bits();
            for i in 0..2000u32 {
                check(f32::from_bits(mb - 1000 + i));
            }
        }
        println!(
            "exp_nonpositive on [-87, 0]: max rel err {:.3e} at {}",
            worst.0, worst.1
        );
        assert!(worst.0 <= 5e-7);
    }

    #[test]
    fn exp_nonpositive_outside_range() {
        assert!(exp_nonpositive(f32::NAN).is_nan());
        assert!(exp_nonpositive(-f32::NAN).is_nan());
        assert_eq!(exp_nonpositive(f32::NEG_INFINITY), 0.0);
        assert_eq!(exp_nonpositive(-87.000_01), 0.0);
        assert_eq!(exp_nonpositive(-1000.0), 0.0);
        assert!(exp_nonpositive(-87.0) > 0.0);
        assert_eq!(exp_nonpositive(0.0), 1.0);
        assert!((exp_nonpositive(-0.0) - 1.0).abs() <= 2e-7);
        // positive arguments: the general `exp`
        for x in [1e-30f32, 0.5, 1.0, 10.0, 88.0, 89.0, f32::INFINITY] {
            assert_eq!(exp_nonpositive(x).to_bits(), exp(x).to_bits());
        }
    }

    /// `sin²(π x)` in `f64` for an `f32` product `x`.
    fn sin2_pi(x: f64) -> f64 {
        let s = libm::sin(core::f64::consts::PI * (x - libm::round(x)));
        s * s
    }

    #[test]
    fn sin2_scaled_polynomial() {
        // The approximation itself: x = d exactly (1/P = 1), dense in [-3, 3]
        // (every reduction r in [-1/2, 1/2] many times) and far out.
        let mut worst = (0.0f64, 0.0f32);
        let xs = grid(-3.0, 3.0, 6_000_000)
            .chain(grid(1490.0, 1500.0, 1_000_000))
            .chain(grid(-4.0e6, 4.0e6, 1_000_000));
        for x in xs {
            let e = (sin2_scaled(x, 1.0, 1.0) as f64 - sin2_pi(x as f64)).abs();
            if e > worst.0 {
                worst = (e, x);
            }
        }
        println!(
            "sin2_scaled: max abs err {:.3e} at x = {}",
            worst.0, worst.1
        );
        assert!(worst.0 <= 3e-7);
        for x in [0.0f32, 1.0, -1.0, 2.0, 1500.0, -12345.0] {
            assert_eq!(sin2_scaled(x, 1.0, 1.0), 0.0);
        }
        assert!((sin2_scaled(0.5, 1.0, 1.0) - 1.0).abs() <= 2e-7);
        assert!(sin2_scaled(f32::NAN, 1.0, 1.0).is_nan());
        assert!(sin2_scaled(f32::INFINITY, 1.0, 1.0).is_nan());
    }

    #[test]
    fn sin2_scaled_kernel_lags() {
        // End to end for the kernel's inputs, d up to 1.5e4 s and P from 10
        // to 1500 s, against f64 sin²(π d / P) with 1/P rounded to f32 once:
        // what remains beyond the polynomial is the rounding of x = d/P
        // (half an ulp of x, ~6e-8 relative), as for any f32 evaluation.
        let mut worst_rel_x = 0.0f64;
        for period in [10.0f64, 37.3, 110.0, 288.0, 432.0, 1000.0, 1500.0] {
            let inv = (1.0 / period) as f32;
            let pi_over_p = (core::f64::consts::PI / period) as f32;
            let (mut worst, mut worst_sin) = (0.0f64, 0.0f64);
            for d in grid(-1.5e4, 1.5e4, 600_000) {
                let x = d as f64 / period;
                // the general-purpose route, sin((π/P) d)², for comparison
                let s = sin(pi_over_p * d) as f64;
                worst_sin = worst_sin.max((s * s - sin2_pi(x)).abs());
                let e = (sin2_scaled(d, inv, 1.0) as f64 - sin2_pi(x)).abs();
                // the derivative of sin²(π x) is at most π
                let bound = 3e-7 + core::f64::consts::PI * 1.2e-7 * x.abs();
                assert!(e <= bound, "P = {period}, d = {d}: {e:.3e}");
                worst = worst.max(e);
                worst_rel_x = worst_rel_x.max(e / (1.0 + x.abs()));
            }
            println!(
                "sin2_scaled, P = {period}: max abs err {worst:.3e} (sin((π/P) d)²: {worst_sin:.3e})"
            );
        }
        println!("max abs err / (1 + |d/P|): {worst_rel_x:.3e}");
        // the coefficient multiplies (coeff s) s
        let c = -23.7f32;
        let s = sin2_scaled(0.3, 1.0, 1.0);
        assert!((sin2_scaled(0.3, 1.0, c) - c * s).abs() <= 1e-5);
    }

    #[test]
    fn sqrt_matches_libm() {
        let mut rng = SplitMix64::new(2);
        for _ in 0..1_000_000 {
            let x = f32::from_bits((rng.next_u64() >> 33) as u32); // non-negative
            let a = sqrt(x);
            let b = libm::sqrtf(x);
            assert!(a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()));
        }
        assert!(sqrt(-1.0).is_nan());
        assert!(sqrt(f32::NAN).is_nan());
        assert_eq!(sqrt(f32::INFINITY), f32::INFINITY);
        assert_eq!(sqrt(4.0), 2.0);
        assert_eq!(sqrt(0.0), 0.0);
    }
}
