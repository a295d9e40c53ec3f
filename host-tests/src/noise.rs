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
