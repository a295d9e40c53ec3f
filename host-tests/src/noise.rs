//! The closed loop's measurement noise (docs/reference.md section 3): the
//! library's test generator (`mkgp_mount::testing`: splitmix64, uniforms in
//! (0, 1), Box-Muller normals, cos first, then the spare sin) with the
//! host's `std` functions, which made the figures.
//!
//! One generator per run, seeded with the run's seed; the stream does not
//! depend on the case. This reproduces the noise in INDIGO's reference traces
//! `indigo_ppec_C1..C8.csv` (seed 1) frame by frame (tests/noise.rs).

pub use mkgp_mount::testing::SplitMix64;
use mkgp_mount::testing::{BoxMuller, BoxMullerMath};

/// Standard normal deviates (Box-Muller) with `std`'s ln, sin and cos.
pub type Gaussian = BoxMuller<Std>;

/// The normals of run `seed` (a camera's noise, a walk): each seed its own
/// stretch of the generator's stream. splitmix64 starts seed s at s x gamma
/// and steps one gamma per draw, and Box-Muller takes two draws a pair, so
/// seed s + 2's normals were seed s's from the third on: a mean over seeds
/// 1-3 measured two noises, one of them twice. Anchored at seed 1, whose
/// stream is INDIGO's (tests/noise.rs).
pub fn for_run(seed: u64) -> Gaussian {
    Gaussian::new(apart(seed, 1))
}

/// The slow random walk of run `seed`'s error, apart from its camera's
/// noise ([`for_run`] of the seed itself).
pub fn walk(seed: u64) -> Gaussian {
    for_run(seed + 1000)
}

/// The Dec axis' camera noise of run `seed`, apart from RA's and the walk.
pub fn dec(seed: u64) -> Gaussian {
    for_run(seed + 2000)
}

/// `seed` as a splitmix64 seed 2^32 steps from each neighbour, `anchor`
/// where it was: streams of nearby seeds no longer overlap (seeds that
/// differ by a multiple of 2^32 coincide).
pub fn apart(seed: u64, anchor: u64) -> u64 {
    anchor.wrapping_add(seed.wrapping_sub(anchor) << 32)
}

/// `std`'s functions: the paper's figures were made with them, and `libm`
/// differs in the last bit of about one normal in ten.
#[derive(Debug, Clone)]
pub struct Std;

impl BoxMullerMath for Std {
    fn ln(x: f64) -> f64 {
        x.ln()
    }
    fn sin(x: f64) -> f64 {
        x.sin()
    }
    fn cos(x: f64) -> f64 {
        x.cos()
    }
}

/// The iteration multiplier of the randomized tests, from
/// `MKGP_RANDOMIZED_SCALE` (default and minimum 1): a longer run on demand.
pub fn randomized_scale() -> u64 {
    std::env::var("MKGP_RANDOMIZED_SCALE")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1)
        .max(1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_normal_of_seed_1() {
        // The first frame of every INDIGO trace C1..C8: input - g(0).
        assert_eq!(Gaussian::new(1).next(), -0.557754129058319);
    }

    #[test]
    fn the_runs_of_nearby_seeds_draw_their_own_normals() {
        let first = |g: &mut Gaussian| (0..64).map(|_| g.next()).collect::<Vec<_>>();
        // Seed 1 is INDIGO's stream; the plain generator's seed 3 is seed
        // 1's from the third normal on.
        assert_eq!(first(&mut for_run(1)), first(&mut Gaussian::new(1)));
        assert_eq!(
            first(&mut Gaussian::new(3))[..62],
            first(&mut Gaussian::new(1))[2..]
        );
        let runs: Vec<Vec<f64>> = (1..=4).map(|s| first(&mut for_run(s))).collect();
        for (i, a) in runs.iter().enumerate() {
            for b in &runs[i + 1..] {
                assert!(a.iter().all(|x| !b.contains(x)));
            }
        }
    }

    #[test]
    fn moments() {
        let mut g = Gaussian::new(7);
        let n = 200_000;
        let xs: Vec<f64> = (0..n).map(|_| g.next()).collect();
        let mean = xs.iter().sum::<f64>() / n as f64;
        let var = xs.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / n as f64;
        assert!(
            mean.abs() < 0.01 && (var - 1.0).abs() < 0.01,
            "{mean} {var}"
        );
    }
}
