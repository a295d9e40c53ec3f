//! INDIGO's reference traces for the tests, by name (`C1`, `dataset03`...).
//! The loader is `host_tests::data::load_trace`.

#![allow(dead_code)]

use host_tests::data;
pub use host_tests::data::TraceRow;

/// The trace `indigo_ppec_<name>.csv`; a load error fails the test with its
/// `file:line`.
pub fn trace(name: &str) -> Vec<TraceRow> {
    data::load_trace(&data::reference_trace(name)).unwrap_or_else(|e| panic!("{e}"))
}

pub mod bad_logs;
pub mod lx200;
pub mod nights;
pub mod process;
pub mod store_image;
