//! The paper's synthetic closed loop (docs/reference.md section 3).
//!
//! Frames at t = 0, 2, ..., 10798 s. At each frame the guide algorithm sees
//! y = g(t) - U + noise, where U is the sum of the controls already applied,
//! and its control is added to U before the next frame. The residual of a
//! frame is g(t) - U with U taken *before* that frame's correction (what the
//! star shows during the frame's exposure); the score is the RMS of the
//! residuals of the frames with t >= 3600 s.
//!
//! Why U before the correction: it reproduces the hysteresis figures of docs/reference.md
//! (e.g. C1 0.332 / 0.705); U after the correction would give 0.152 / 0.637.
//!
//! The guide algorithm gets SNR 10 (INDIGO's value when the SNR is unknown; the
//! reference traces carry it) and dt = 2 s.

use crate::cases::Case;
use crate::guide_algorithm::{GuideAlgorithm, OpenLoop};
use crate::noise::Gaussian;
use rayon::prelude::*;

/// Time between frames (s).
pub const DT: f64 = 2.0;
/// Number of frames: t = 0 .. 10798 s.
pub const FRAMES: usize = 5400;
/// Frames from this time on are scored (s).
pub const SCORE_FROM_S: f64 = 3600.0;
/// The SNR the guide algorithm is given.
pub const SNR: f64 = 10.0;
/// The noisy runs: N(0, 1 px), seeds 1, 2, 3, mean of the three residuals.
pub const NOISY_SEEDS: [u64; 3] = [1, 2, 3];

/// Measurement noise of a run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Noise {
    None,
    /// N(0, sigma^2) px from [`Gaussian`] with this seed.
    Gaussian {
        sigma_px: f64,
        seed: u64,
    },
}

/// The frame times.
pub fn frame_times() -> impl Iterator<Item = f64> {
    (0..FRAMES).map(|k| k as f64 * DT)
}

/// Run the loop; returns the residual RMS over t >= 3600 s.
pub fn run(case: &Case, algorithm: &mut dyn GuideAlgorithm, noise: Noise) -> f64 {
    let mut gauss = match noise {
        Noise::None => None,
        Noise::Gaussian { sigma_px, seed } => Some((sigma_px, Gaussian::new(seed))),
    };
    let mut applied = 0.0; // U
    let (mut sum_sq, mut count) = (0.0, 0usize);
    for t in frame_times() {
        let g = case.gear_error(t);
        let residual = g - applied;
        if t >= SCORE_FROM_S {
            sum_sq += residual * residual;
            count += 1;
        }
        let n = match gauss.as_mut() {
            Some((sigma, gen)) => *sigma * gen.next(),
            None => 0.0,
        };
        applied += algorithm.step(t, residual + n, SNR, DT);
    }
    (sum_sq / count as f64).sqrt()
}

/// The residual RMS without any correction: the RMS of g(t) over t >= 3600 s.
pub fn open_loop_rms(case: &Case) -> f64 {
    run(case, &mut OpenLoop, Noise::None)
}

/// A table's cell: one noise-free run when `sigma_px` is 0, else
/// [`mean_noisy_rms`].
pub fn rms_at<A: GuideAlgorithm>(case: &Case, sigma_px: f64, make: impl Fn() -> A + Sync) -> f64 {
    if sigma_px == 0.0 {
        run(case, &mut make(), Noise::None)
    } else {
        mean_noisy_rms(case, sigma_px, make)
    }
}

/// Mean residual RMS over [`NOISY_SEEDS`] with N(0, sigma^2) noise; `make`
/// builds a fresh guide algorithm for each seed. The seeds run in parallel;
/// their residuals are added in seed order, so the mean does not depend on
/// the scheduling.
pub fn mean_noisy_rms<A: GuideAlgorithm>(
    case: &Case,
    sigma_px: f64,
    make: impl Fn() -> A + Sync,
) -> f64 {
    let rms: Vec<f64> = NOISY_SEEDS
        .par_iter()
        .map(|&seed| run(case, &mut make(), Noise::Gaussian { sigma_px, seed }))
        .collect();
    rms.iter().sum::<f64>() / rms.len() as f64
}
