//! Host-side tools for `mkgp-mount`: the paper's synthetic gear-error cases
//! and closed loop, PHD2 guide-log parsing and PHD2's causal replay, the
//! guide algorithms they drive (PHD2's hysteresis and the library's
//! Gaussian-process guider), and the firmware's own loop in a simulated rig
//! (`st4_sim`), through a scripted night of many guiding sections (`night`).
//!
//! The test data (`synthetic_cases.csv`, `phd2-logs/`, `reference-traces/`)
//! lives in `host-tests/data`, found by [`data::data_dir`].

pub mod ablation;
pub mod bench;
pub mod cases;
pub mod closed_loop;
pub mod data;
pub mod gp;
pub mod guide_algorithm;
pub mod models;
pub mod mount_sim;
pub mod night;
pub mod nights;
pub mod noise;
pub mod phd2_log;
pub mod population;
pub mod replay;
pub mod st4_sim;
pub mod store_sim;
pub mod svg;
pub mod table;
pub mod view;

pub use data::Error;
