//! The closed loop's measurement noise (docs/reference.md section 3): splitmix64,
//! uniforms in (0, 1), Box-Muller normals (cos first, then the spare sin).
//!
//! One generator per run, seeded with the run's seed; the stream does not
//! depend on the case. This reproduces the noise in INDIGO's reference traces
//! `indigo_ppec_C1..C8.csv` (seed 1) frame by frame (tests/noise.rs).

const GOLDEN_GAMMA: u64 = 0x9E37_79B9_7F4A_7C15;

/// splitmix64 with the paper's seeding.
#[derive(Debug, Clone)]
pub struct SplitMix64 {
    state: u64,
}

impl SplitMix64 {
    pub fn new(seed: u64) -> Self {
        SplitMix64 {
            state: 0x123_4567u64.wrapping_add(seed.wrapping_mul(GOLDEN_GAMMA)),
        }
    }

    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(GOLDEN_GAMMA);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in the open interval (0, 1): ((x >> 11) + 0.5) / 2^53.
    pub fn uniform(&mut self) -> f64 {
        ((self.next_u64() >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
}

/// Standard normal deviates by Box-Muller: r = sqrt(-2 ln u1), theta =
/// 2 pi u2; r cos theta first, r sin theta on the next call.
#[derive(Debug, Clone)]
pub struct Gaussian {
    rng: SplitMix64,
    spare: Option<f64>,
}

impl Gaussian {
    pub fn new(seed: u64) -> Self {
        Gaussian {
            rng: SplitMix64::new(seed),
            spare: None,
        }
    }

    pub fn next(&mut self) -> f64 {
        if let Some(v) = self.spare.take() {
            return v;
        }
        let u1 = self.rng.uniform();
        let u2 = self.rng.uniform();
        let r = (-2.0 * u1.ln()).sqrt();
        let theta = 2.0 * std::f64::consts::PI * u2;
        self.spare = Some(r * theta.sin());
        r * theta.cos()
    }
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
