//! Spectral analysis of the gear error: the FFT, the de-trended power
//! spectrum of the grid and its peak search, the period tracker, and the
//! discovery of gear stages beyond the worm.

pub mod discovery;
pub mod fft;
pub mod period;
pub mod spectrum;
