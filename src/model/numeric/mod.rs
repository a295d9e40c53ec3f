//! Numerics: the scalar type the model computes in (`f64` on the host as
//! the reference, `f32` on the target), accurate `f32` approximations of the
//! few transcendental functions it needs, and the inner products, portable
//! and hand-scheduled for the Cortex-M4F.

pub mod approx;
pub mod dot;
pub mod scalar;
#[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
pub mod vfp;

pub use scalar::Scalar;
