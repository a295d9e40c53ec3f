//! `mkgp_mount::model::numeric::scalar::Scalar` for `f32` (and `f64`, soft-float here) on
//! the Cortex-M4F.
//!
//! Tolerances: sin and cos absolute 1e-6 (a few ulp at unit scale), exp and
//! sqrt relative 1e-6 (about 8 ulp of f32); the f32/f64 sweep compares
//! against the `f64` implementation.

use crate::harness::{check, close_abs, close_rel, TestResult};
use core::f64::consts::{E, FRAC_PI_2, FRAC_PI_3, FRAC_PI_4, FRAC_PI_6, PI, SQRT_2};
use mkgp_mount::model::numeric::scalar::Scalar;

const TRIG_ABS: f64 = 1e-6;
const REL: f64 = 1e-6;

fn f(x: f64) -> f32 {
    <f32 as Scalar>::from_f64(x)
}

/// The FPU is on (CP10/CP11 full access in CPACR) and hard-float
/// arithmetic gives IEEE results.
pub fn fpu_enabled() -> TestResult {
    // SAFETY: read-only access to a System Control Block register.
    let cpacr = unsafe { core::ptr::read_volatile(0xE000_ED88 as *const u32) };
    check((cpacr >> 20) & 0xf == 0xf, "CPACR: FPU not enabled")?;
    let a = core::hint::black_box(1.5f32);
    let b = core::hint::black_box(2.25f32);
    check(
        a * b == 3.375 && a / b + 1.0 > 1.666 && a - b == -0.75,
        "f32 arithmetic",
    )
}

pub fn constants() -> TestResult {
    check(<f32 as Scalar>::ZERO == 0.0, "ZERO")?;
    check(<f32 as Scalar>::ONE == 1.0, "ONE")?;
    close_abs("PI", <f32 as Scalar>::PI.to_f64(), PI, 1e-7)?;
    check(f(2.5).to_f64() == 2.5, "from_f64/to_f64 round trip")?;
    check(<f32 as Scalar>::from_usize(4096) == 4096.0, "from_usize")?;
    check(
        f(1.0).is_finite() && !(f32::INFINITY).is_finite(),
        "is_finite",
    )?;
    check(!Scalar::is_finite(f32::NAN), "NaN is not finite")
}

pub fn sin_known_points() -> TestResult {
    let points = [
        (0.0, 0.0),
        (FRAC_PI_6, 0.5),
        (FRAC_PI_4, SQRT_2 / 2.0),
        (FRAC_PI_2, 1.0),
        (PI, 0.0),
        (-FRAC_PI_3, -0.866_025_403_784_438_6),
        (10.0, -0.544_021_110_889_369_8),
        (100.0, -0.506_365_641_109_758_8),
    ];
    for (x, want) in points {
        close_abs("sin", Scalar::sin(f(x)).to_f64(), want, TRIG_ABS)?;
    }
    Ok(())
}

pub fn cos_known_points() -> TestResult {
    let points = [
        (0.0, 1.0),
        (FRAC_PI_3, 0.5),
        (FRAC_PI_2, 0.0),
        (PI, -1.0),
        (-FRAC_PI_4, SQRT_2 / 2.0),
        (10.0, -0.839_071_529_076_452_4),
        (100.0, 0.862_318_872_287_683_9),
    ];
    for (x, want) in points {
        close_abs("cos", Scalar::cos(f(x)).to_f64(), want, TRIG_ABS)?;
    }
    Ok(())
}

pub fn exp_known_points() -> TestResult {
    let points = [
        (0.0, 1.0),
        (1.0, E),
        (-1.0, 1.0 / E),
        (0.5, 1.648_721_270_700_128_2),
        (10.0, 22_026.465_794_806_718),
        (-10.0, 4.539_992_976_248_485e-5),
        (-50.0, 1.928_749_847_963_918e-22),
    ];
    for (x, want) in points {
        close_rel("exp", Scalar::exp(f(x)).to_f64(), want, REL)?;
    }
    check(Scalar::exp(f(-200.0)) == 0.0, "exp underflows to 0")
}

pub fn sqrt_known_points() -> TestResult {
    let points = [
        (1.0, 1.0),
        (2.0, SQRT_2),
        (0.25, 0.5),
        (1e6, 1e3),
        (3.0, 1.732_050_807_568_877_2),
        (1e-6, 1e-3),
    ];
    for (x, want) in points {
        close_rel("sqrt", Scalar::sqrt(f(x)).to_f64(), want, REL)?;
    }
    check(Scalar::sqrt(f(0.0)) == 0.0, "sqrt(0)")?;
    check(!Scalar::is_finite(Scalar::sqrt(f(-1.0))), "sqrt(-1) is NaN")
}

/// f32 against the f64 implementation (software double on this core) at
/// 401 points in [-20, 20].
pub fn f32_matches_f64_sweep() -> TestResult {
    for i in 0..=400 {
        let x32 = f(-20.0 + 0.1 * i as f64);
        let x = x32.to_f64(); // the same point, exactly
        close_abs(
            "sin sweep",
            Scalar::sin(x32).to_f64(),
            Scalar::sin(x),
            TRIG_ABS,
        )?;
        close_abs(
            "cos sweep",
            Scalar::cos(x32).to_f64(),
            Scalar::cos(x),
            TRIG_ABS,
        )?;
        close_rel("exp sweep", Scalar::exp(x32).to_f64(), Scalar::exp(x), REL)?;
        let ax = Scalar::abs(x);
        close_rel(
            "sqrt sweep",
            Scalar::sqrt(Scalar::abs(x32)).to_f64(),
            Scalar::sqrt(ax),
            REL,
        )?;
    }
    Ok(())
}
