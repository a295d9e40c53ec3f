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
//! reference traces carry it) and dt = 2 s. A drawn mount's runs
//! (`crate::population`) take their own frame interval and a random walk
//! ([`Conditions`], [`run_in`]).

use crate::cases::Case;
use crate::guide_algorithm::{GuideAlgorithm, OpenLoop};
use crate::noise::{self, Gaussian};
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

/// What besides the gear a run has: the paper's loop has frames every 2 s
/// and nothing else moves the star; a drawn mount (`crate::population`)
/// has its own exposure and a random walk.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Conditions {
    /// Time between frames, s.
    pub dt_s: f64,
    /// A random walk of the star (flexure, seeing's slow part), px per
    /// square root of a minute, drawn at each frame from its own generator
    /// ([`noise::for_run`] of the run's seed + 1000, as `st4_sim`'s); 0:
    /// none.
    pub walk_px_per_sqrt_min: f64,
    /// The noise of seed s: the paper's protocol takes the generator at s
    /// (its seeds 1 and 3 share all but two normals; INDIGO's figures
    /// were measured so); `false`: [`noise::for_run`], a stream of its own.
    pub paper_seeds: bool,
}

impl Conditions {
    /// The paper's: [`DT`], no walk, its seeds.
    pub const PAPER: Conditions = Conditions {
        dt_s: DT,
        walk_px_per_sqrt_min: 0.0,
        paper_seeds: true,
    };
}

/// Run the loop; returns the residual RMS over t >= 3600 s.
pub fn run(case: &Case, algorithm: &mut dyn GuideAlgorithm, noise: Noise) -> f64 {
    let (sigma_px, seed) = match noise {
        Noise::None => (0.0, NOISY_SEEDS[0]),
        Noise::Gaussian { sigma_px, seed } => (sigma_px, seed),
    };
    run_in(case, algorithm, sigma_px, seed, &Conditions::PAPER)
}

/// [`run`] in `conditions`: frames every `dt_s` over the same 3 h, N(0,
/// `sigma_px`^2) noise from `seed` (none at 0); the walk is part of the
/// residual, as the star shows it.
pub fn run_in(
    case: &Case,
    algorithm: &mut dyn GuideAlgorithm,
    sigma_px: f64,
    seed: u64,
    conditions: &Conditions,
) -> f64 {
    let dt = conditions.dt_s;
    let generator = if conditions.paper_seeds {
        Gaussian::new
    } else {
        noise::for_run
    };
    let mut noise = (sigma_px > 0.0).then(|| generator(seed));
    let walk_step = conditions.walk_px_per_sqrt_min * (dt / 60.0).sqrt();
    let (mut walk, mut walk_gen) = (0.0, noise::walk(seed));
    let frames = (FRAMES as f64 * DT / dt).ceil() as usize;
    let mut applied = 0.0; // U
    let (mut sum_sq, mut count) = (0.0, 0usize);
    for t in (0..frames).map(|k| k as f64 * dt) {
        if walk_step > 0.0 {
            walk += walk_step * walk_gen.next();
        }
        let residual = case.gear_error(t) + walk - applied;
        if t >= SCORE_FROM_S {
            sum_sq += residual * residual;
            count += 1;
        }
        let n = noise.as_mut().map_or(0.0, |g| sigma_px * g.next());
        applied += algorithm.step(t, residual + n, SNR, dt);
    }
    (sum_sq / count as f64).sqrt()
}

/// The residual RMS without any correction: the RMS of g(t) over t >= 3600 s.
pub fn open_loop_rms(case: &Case) -> f64 {
    run(case, &mut OpenLoop, Noise::None)
}

/// [`open_loop_rms`] in `conditions`, the walk drawn from `seed`.
pub fn open_loop_rms_in(case: &Case, seed: u64, conditions: &Conditions) -> f64 {
    run_in(case, &mut OpenLoop, 0.0, seed, conditions)
}

/// A table's cell: one noise-free run when `sigma_px` is 0, else
/// [`mean_noisy_rms`].
pub fn rms_at<A: GuideAlgorithm>(case: &Case, sigma_px: f64, make: impl Fn() -> A + Sync) -> f64 {
    rms_in(case, sigma_px, &NOISY_SEEDS, &Conditions::PAPER, make)
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
    rms_in(case, sigma_px, &NOISY_SEEDS, &Conditions::PAPER, make)
}

/// A cell in `conditions`: one run from `seeds[0]` when `sigma_px` is 0
/// (its walk still drawn from that seed), else the mean over `seeds`, as
/// [`mean_noisy_rms`].
pub fn rms_in<A: GuideAlgorithm>(
    case: &Case,
    sigma_px: f64,
    seeds: &[u64],
    conditions: &Conditions,
    make: impl Fn() -> A + Sync,
) -> f64 {
    let seeds = if sigma_px == 0.0 { &seeds[..1] } else { seeds };
    let rms: Vec<f64> = seeds
        .par_iter()
        .map(|&seed| run_in(case, &mut make(), sigma_px, seed, conditions))
        .collect();
    rms.iter().sum::<f64>() / rms.len() as f64
}
