//! Numerics: the scalar type the model computes in (`f64` on the host as
//! the reference, `f32` on the target), accurate `f32` approximations of the
//! few transcendental functions it needs, the `f64` cosine and sine of the
//! phases set up in `f64`, the inner products, portable and hand-scheduled
//! for the Cortex-M4F, and the frame interval that scales the counts of
//! frames a loop is judged over.

pub mod approx;
pub mod cos_sin;
pub mod dot;
pub mod frame_interval;
pub mod scalar;
#[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
pub mod vfp;

pub use scalar::Scalar;

/// `x` limited to `[lo, hi]`, as `f32::clamp`/`f64::clamp` for `lo <= hi`
/// (NaN `x` passes through), but without their `assert!(lo <= hi)`: that
/// assertion formats both bounds, which pulls core's float formatting and a
/// panic into the firmware wherever the bounds are not constants. Bounds in
/// the wrong order (or NaN) give some value in between instead of a panic.
#[inline(always)]
pub fn clamp<T: PartialOrd>(x: T, lo: T, hi: T) -> T {
    if x < lo {
        lo
    } else if x > hi {
        hi
    } else {
        x
    }
}
