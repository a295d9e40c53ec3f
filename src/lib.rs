//! Hardware-free, allocation-free core of the mount firmware: the
//! multi-kernel Gaussian-process model of the gear error and the guider
//! around it, the command port (`port`: the LX200 interpreter a PC talks
//! to), and `persist`: the store that keeps the configuration, the model's
//! snapshot and the park position in flash across power cycles. Everything
//! here is `no_std` and generic over the scalar type,
//! so the same code runs in `f64` on the host (the reference) and in `f32`
//! on the Cortex-M4F.
// `no_std` everywhere but in the library's own unit tests, which use the
// standard library's collections and printing on the host.
#![cfg_attr(not(test), no_std)]

pub mod control_loop;
pub mod counters;
pub mod model;
pub mod mount;
pub mod persist;
pub mod port;
pub mod safety;
// Random numbers for the unit tests, and through the `testing` feature for
// target-tests and host-tests: one generator, not a copy per test.
#[cfg(any(test, feature = "testing"))]
pub mod testing;
