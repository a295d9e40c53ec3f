//! The Gaussian process: the regular grid the frames are averaged into, the
//! multi-kernel covariance, and the inference (subset selection, Gram matrix,
//! trend and prediction).

pub mod grid;
pub mod infer;
pub mod kernel;
