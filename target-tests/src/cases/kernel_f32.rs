//! The kernel's specialised `f32` functions (`Scalar::exp_nonpositive`,
//! `Scalar::sin2_scaled`, `mkgp_mount::model::numeric::approx`) and the `f32` kernel built on
//! them, against the `f64` implementations (software double on this core).
//!
//! Tolerances are the functions' documented bounds: `exp_nonpositive`
//! relative 5e-7 on `[-87, 0]`, `sin²` absolute 3e-7 when `d / P` is exact
//! in `f32` (`P` a power of two), plus the rounding of `d / P` otherwise.

use crate::harness::{check, close_abs, close_rel, TestResult};
use mkgp_mount::model::gp::kernel::Kernel;
use mkgp_mount::model::numeric::scalar::Scalar;

const EXP_REL: f64 = 5e-7;
const SIN2_ABS: f64 = 3e-7;

pub fn exp_nonpositive_points() -> TestResult {
    for x in [
        0.0f32, -0.0, -1e-6, -0.25, -0.346, -0.347, -0.5, -1.0, -2.5, -10.0, -23.7, -50.0, -86.9,
        -87.0,
    ] {
        let want = Scalar::exp(x.to_f64());
        close_rel(
            "exp_nonpositive",
            x.exp_nonpositive().to_f64(),
            want,
            EXP_REL,
        )?;
    }
    // a sweep over the whole range, 8,701 points
    for i in 0..=8700 {
        let x = -0.01f32 * i as f32;
        let want = Scalar::exp(x.to_f64());
        close_rel(
            "exp_nonpositive sweep",
            x.exp_nonpositive().to_f64(),
            want,
            EXP_REL,
        )?;
    }
    check((-87.01f32).exp_nonpositive() == 0.0, "below -87 gives 0")?;
    check(f32::NEG_INFINITY.exp_nonpositive() == 0.0, "-inf gives 0")?;
    check(f32::NAN.exp_nonpositive().is_nan(), "NaN gives NaN")?;
    // positive arguments take the general exp
    close_rel(
        "exp_nonpositive(1)",
        1.0f32.exp_nonpositive().to_f64(),
        core::f64::consts::E,
        EXP_REL,
    )
}

pub fn sin2_scaled_points() -> TestResult {
    // P a power of two: 1/P and d/P are exact in f32, so only the polynomial's
    // error remains.
    for period in [16.0f64, 128.0, 1024.0] {
        let f32_factor = <f32 as Scalar>::sin2_factor(period);
        let f64_factor = <f64 as Scalar>::sin2_factor(period);
        for i in -400..=400 {
            let d = 0.37f32 * i as f32 * (period / 16.0) as f32;
            let got = d.sin2_scaled(f32_factor, 1.0).to_f64();
            let want = d.to_f64().sin2_scaled(f64_factor, 1.0);
            close_abs("sin2_scaled", got, want, SIN2_ABS)?;
        }
    }
    // zeros at whole periods, 1 at half periods, and the coefficient
    let f = <f32 as Scalar>::sin2_factor(64.0);
    check(3200.0f32.sin2_scaled(f, 1.0) == 0.0, "sin² at 50 periods")?;
    close_abs(
        "sin² at half a period",
        32.0f32.sin2_scaled(f, 1.0).to_f64(),
        1.0,
        SIN2_ABS,
    )?;
    close_abs(
        "coeff sin²",
        16.0f32.sin2_scaled(f, -23.5).to_f64(),
        -11.75,
        1e-5,
    )?;
    check(f32::NAN.sin2_scaled(f, 1.0).is_nan(), "NaN lag gives NaN")
}

/// `Kernel<f32, 2>` against `Kernel<f64, 2>` at lags up to 3,000 s: within
/// 1e-4 of the kernel's value at zero lag (the `f32` rounding of `d / P`,
/// about 6e-8 relative, times the steepest exponent, not the functions).
pub fn kernel_f32_matches_f64() -> TestResult {
    let periods = [432.0, 155.0];
    let gates = [1.0, 0.6];
    let k32: Kernel<f32, 2> = Kernel::new(&periods, &gates);
    let k64: Kernel<f64, 2> = Kernel::new(&periods, &gates);
    let scale = k64.full(0.0);
    for i in -600..=600 {
        let d32 = 5.0f32 * i as f32 + 0.25;
        let d = d32.to_f64();
        close_abs(
            "full kernel",
            k32.full(d32).to_f64() / scale,
            k64.full(d) / scale,
            1e-4,
        )?;
        close_abs(
            "projection kernel",
            k32.projection(d32).to_f64() / scale,
            k64.projection(d) / scale,
            1e-4,
        )?;
    }
    Ok(())
}
