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

use crate::model::ldlt::FactorError;

/// Cells used for one inference: the size of every buffer of the subset,
/// the lag table, the Gram matrix and the trend solve.
pub const SUBSET: usize = 100;
/// Entries of a packed lower triangle of `SUBSET` x `SUBSET`.
const TRIANGLE: usize = SUBSET * (SUBSET + 1) / 2;

/// Why an inference could not be made.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InferError {
    /// Fewer than two cells.
    TooLittleData,
    Factor(FactorError),
    /// The trend system was singular or a result was not finite.
    Degenerate,
}
