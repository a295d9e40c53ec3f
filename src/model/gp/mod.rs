//! The Gaussian process: the regular grid the frames are averaged into, the
//! multi-kernel covariance, and the inference (`infer`: the subset
//! selection, the lag table and the Gram matrix, the trend solve, and the
//! prediction).

mod gram;
pub mod grid;
pub mod infer;
pub mod kernel;
mod lag_table;
mod subset;
mod trend;
