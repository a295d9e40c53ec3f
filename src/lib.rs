//! Hardware-free, allocation-free core of the mount firmware: the
//! multi-kernel Gaussian-process model of the gear error and the guider
//! around it. Everything here is `no_std` and generic over the scalar type,
//! so the same code runs in `f64` on the host (the reference) and in `f32`
//! on the Cortex-M4F.
// `no_std` everywhere but in the library's own unit tests, which use the
// standard library's collections and printing on the host.
#![cfg_attr(not(test), no_std)]

pub mod approx;
pub mod controller;
pub mod discovery;
pub mod fft;
pub mod gp;
pub mod grid;
pub mod guider;
pub mod kernel;
pub mod ldlt;
pub mod mount;
pub mod period;
pub mod scalar;
pub mod spectrum;
pub mod st4;
pub mod stepgen;
#[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
pub mod vfp;
