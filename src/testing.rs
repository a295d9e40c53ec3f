//! Pseudo-random numbers for tests, one generator for the library's unit
//! tests, target-tests and host-tests (feature `testing`; never in the
//! firmware): splitmix64 with the paper's seeding, uniform draws, and
//! Box-Muller normals. The normals are the closed loop's measurement noise
//! (docs/reference.md section 3) and reproduce the noise of INDIGO's
//! reference traces `indigo_ppec_C1..C8.csv` (seed 1) frame by frame
//! (host-tests/tests/noise.rs), so their sequence must not change.

use core::marker::PhantomData;

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

    /// Uniform in `0..n` (n > 0; the modulo bias is below what a test sees).
    pub fn below(&mut self, n: u64) -> u64 {
        self.next_u64() % n
    }

    /// Uniform in the open interval (0, 1): ((x >> 11) + 0.5) / 2^53.
    pub fn uniform(&mut self) -> f64 {
        ((self.next_u64() >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    /// Uniform in (lo, hi).
    pub fn f64_in(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.uniform()
    }
}

/// The functions Box-Muller needs. They are a parameter because the
/// platform's `std` and the `libm` crate differ in the last bit for about
/// one normal in ten: host-tests' figures were made with `std`, which a
/// `no_std` library cannot call.
pub trait BoxMullerMath {
    fn ln(x: f64) -> f64;
    fn sin(x: f64) -> f64;
    fn cos(x: f64) -> f64;
}

/// The `libm` crate's functions (available everywhere, the target too).
#[derive(Debug, Clone)]
pub struct Libm;

impl BoxMullerMath for Libm {
    fn ln(x: f64) -> f64 {
        libm::log(x)
    }
    fn sin(x: f64) -> f64 {
        libm::sin(x)
    }
    fn cos(x: f64) -> f64 {
        libm::cos(x)
    }
}

/// Standard normal deviates by Box-Muller: r = sqrt(-2 ln u1), theta =
/// 2 pi u2; r cos theta first, r sin theta on the next call.
#[derive(Debug, Clone)]
pub struct BoxMuller<M: BoxMullerMath> {
    rng: SplitMix64,
    spare: Option<f64>,
    math: PhantomData<M>,
}

/// Normals with `libm`'s functions, available everywhere (host-tests uses
/// `std`'s).
pub type Gaussian = BoxMuller<Libm>;

impl<M: BoxMullerMath> BoxMuller<M> {
    pub fn new(seed: u64) -> Self {
        BoxMuller {
            rng: SplitMix64::new(seed),
            spare: None,
            math: PhantomData,
        }
    }

    // The name host-tests' callers use; an endless stream, not an Iterator.
    #[allow(clippy::should_implement_trait)]
    pub fn next(&mut self) -> f64 {
        if let Some(v) = self.spare.take() {
            return v;
        }
        let u1 = self.rng.uniform();
        let u2 = self.rng.uniform();
        let r = libm::sqrt(-2.0 * M::ln(u1));
        let theta = 2.0 * core::f64::consts::PI * u2;
        self.spare = Some(r * M::sin(theta));
        r * M::cos(theta)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paper_seeding() {
        // The first frame of every INDIGO trace C1..C8 (seed 1), to the last
        // bit or two: host-tests pins it exactly with `std`'s functions.
        let first = Gaussian::new(1).next();
        assert!((first - -0.557754129058319).abs() < 1e-15, "{first}");
    }

    #[test]
    fn draws_stay_in_range() {
        let mut rng = SplitMix64::new(5);
        for _ in 0..100_000 {
            assert!(rng.below(7) < 7);
            let x = rng.f64_in(-2.0, 3.0);
            assert!(x > -2.0 && x < 3.0);
        }
    }
}
