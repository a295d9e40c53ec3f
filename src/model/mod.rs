//! The gear-error model: the multi-kernel Gaussian process of the paper,
//! generic over the scalar type so that the same code runs in `f64` (the
//! reference) and in `f32` (the target).
//!
//! Layers, each using only those above it: [`numeric`] and `in_place`
//! (building the large state where it lives), then [`ldlt`] (linear
//! algebra), [`spectral`] and [`gp`], and on top the [`guider`], which turns
//! frames into controls and predictions. [`additions`]: the switches of
//! everything added around the paper's model.

pub mod additions;
pub mod gp;
pub mod guider;
pub(crate) mod in_place;
pub mod ldlt;
pub mod numeric;
pub mod snapshot;
pub mod spectral;
