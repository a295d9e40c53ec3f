//! The covariance function of the multi-kernel model (paper eq. 3-4).
//!
//! k(d) = long SE + sum over stages of a periodic term + short SE, where the
//! stages beyond the worm (stage 0) carry a squared-exponential envelope that
//! makes them quasi-periodic. The projection kernel used for prediction drops
//! the short SE, which only absorbs transient wander while fitting.

use crate::model::numeric::cos_sin;
use crate::model::numeric::scalar::Scalar;

/// The worm's periodic length scale, natural units (s), as in the
/// single-kernel model; stages s > 0 use `P_s / STAGE_LENGTH_RATIO` instead.
pub const WORM_LENGTH_SCALE_S: f64 = 10.0;
/// κ: stage s > 0 has length scale P_s / κ (paper sec. 3.3).
pub const STAGE_LENGTH_RATIO: f64 = 13.0;
/// λ: the envelope of stage s > 0 has length scale λ P_s (paper sec. 3.4).
pub const ENVELOPE_PERIODS: f64 = 20.0;
/// Amplitude (px or arcsec) of the worm and of a fully gated-in stage.
pub const PERIODIC_AMPLITUDE: f64 = 20.0;
/// Long SE: correlation time (s) and amplitude.
pub const LONG_LENGTH_SCALE_S: f64 = 700.0;
pub const LONG_AMPLITUDE: f64 = 20.0;
/// Short SE: correlation time (s) and amplitude.
pub const SHORT_LENGTH_SCALE_S: f64 = 25.0;
pub const SHORT_AMPLITUDE: f64 = 10.0;

/// Exponent below which [`Kernel::full`] drops the short SE.
///
/// Why that is exact in `f64`: with `a_L = -d²/(2 ℓ_L²)` and
/// `a_S = -d²/(2 ℓ_S²)` (ℓ_L = 700 s, ℓ_S = 25 s), the short term over the
/// long SE term is `(σ_S²/σ_L²) e^(a_S - a_L) = 0.25 e^(a_S (1 - ℓ_S²/ℓ_L²))`,
/// below `0.25 e^-49.93 = 5e-23` when `a_S < -50`. Every other term of the
/// projection is `>= 0`, so the short term is below `2^-54` (5.6e-17) of the
/// sum, less than half an ulp: the rounded sum is the projection itself.
/// This holds while the long SE is normal, `d < 2.6e4 s`; from `d > 965 s`
/// on, libm's `exp(a_S)` is `0` anyway. (In `f32` the term is equally far
/// below rounding.)
pub const SHORT_CUTOFF: f64 = -50.0;

/// One periodic stage, pre-computed for evaluation.
#[derive(Clone, Copy, Debug)]
struct StageTerm<S> {
    /// `S::sin2_factor(P_s)`: π / P_s in `f64`, 1 / P_s in `f32`.
    phase_factor: S,
    /// Signal variance: amplitude² (times the evidence gate for s > 0).
    variance: S,
    /// -2 / ℓ², ℓ the standard-form length scale.
    sin2_coeff: S,
    /// -1 / (2 (λ P_s)²); zero for the worm, which has no envelope.
    envelope_coeff: S,
}

/// The covariance function for `N` periodic stages.
#[derive(Clone, Copy, Debug)]
pub struct Kernel<S, const N: usize> {
    long_variance: S,
    long_coeff: S,
    short_variance: S,
    short_coeff: S,
    stages: [StageTerm<S>; N],
}

/// Natural length scale -> standard form of the periodic kernel,
/// ℓ -> 4 sin(ℓ π / P), with ℓ floored at 1 s as in the single-kernel model.
fn standard_length_scale(natural: f64, period: f64) -> f64 {
    4.0 * cos_sin::sin(natural.max(1.0) * core::f64::consts::PI / period)
}

impl<S: Scalar, const N: usize> Kernel<S, N> {
    /// Build the kernel for the given stage periods (s) and evidence gates
    /// (0..=1; the worm's gate is always 1). Runs once per frame: the `f64`
    /// arithmetic here is O(N).
    pub fn new(periods: &[f64; N], gates: &[f64; N]) -> Self {
        let se = |ls: f64| S::from_f64(-0.5 / (ls * ls));
        let stages = core::array::from_fn(|s| {
            let period = periods[s];
            let (natural_ls, gate, envelope) = if s == 0 {
                (WORM_LENGTH_SCALE_S, 1.0, 0.0)
            } else {
                let env = ENVELOPE_PERIODS * period;
                (period / STAGE_LENGTH_RATIO, gates[s], -0.5 / (env * env))
            };
            let ls = standard_length_scale(natural_ls, period);
            StageTerm {
                phase_factor: S::sin2_factor(period),
                variance: S::from_f64(gate * PERIODIC_AMPLITUDE * PERIODIC_AMPLITUDE),
                sin2_coeff: S::from_f64(-2.0 / (ls * ls)),
                envelope_coeff: S::from_f64(envelope),
            }
        });
        Self {
            long_variance: S::from_f64(LONG_AMPLITUDE * LONG_AMPLITUDE),
            long_coeff: se(LONG_LENGTH_SCALE_S),
            short_variance: S::from_f64(SHORT_AMPLITUDE * SHORT_AMPLITUDE),
            short_coeff: se(SHORT_LENGTH_SCALE_S),
            stages,
        }
    }

    /// Projection kernel: long SE + every stage.
    #[inline(always)]
    pub fn projection(&self, d: S) -> S {
        self.projection_observed(d, d)
    }

    /// [`projection`](Self::projection) between two times `d` apart in
    /// gear time and `observed` apart in observed time (gear time less the
    /// gaps in which the gears were not observed: `Grid::dark`). The
    /// periodic terms follow the gears; the envelopes count only the time
    /// the stages were seen, so a slew's gap forgets nothing.
    #[inline(always)]
    pub fn projection_observed(&self, d: S, observed: S) -> S {
        let d2 = d * d;
        let o2 = observed * observed;
        let mut k = self.long_variance * (self.long_coeff * d2).exp_nonpositive();
        for st in &self.stages {
            if st.variance > S::ZERO {
                let periodic = d.sin2_scaled(st.phase_factor, st.sin2_coeff);
                k += st.variance * (periodic + st.envelope_coeff * o2).exp_nonpositive();
            }
        }
        k
    }

    /// Full kernel used to fit and to choose the subset: projection + short SE.
    ///
    /// The short SE is skipped where its exponent is below
    /// [`SHORT_CUTOFF`]: it is then less than 100 e^-50 = 2e-20, and (its
    /// length scale being the shortest) less than 2^-54 of the long SE
    /// term alone, so adding it cannot change the sum's `f64` rounding (see
    /// the bound at [`SHORT_CUTOFF`]). NaN lags still propagate.
    #[inline(always)]
    pub fn full(&self, d: S) -> S {
        self.full_observed(d, d)
    }

    /// [`full`](Self::full) with the envelopes in observed time, as
    /// [`projection_observed`](Self::projection_observed).
    #[inline(always)]
    pub fn full_observed(&self, d: S, observed: S) -> S {
        let k = self.projection_observed(d, observed);
        let short = self.short_coeff * d * d;
        if short < S::from_f64(SHORT_CUTOFF) {
            k
        } else {
            k + self.short_variance * short.exp_nonpositive()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn symmetric_and_peaked_at_zero() {
        let k: Kernel<f64, 2> = Kernel::new(&[432.0, 155.0], &[1.0, 0.6]);
        let k0 = k.full(0.0);
        assert!((k0 - (400.0 + 400.0 + 0.6 * 400.0 + 100.0)).abs() < 1e-9);
        for i in 1..400 {
            let d = i as f64 * 3.7;
            assert_eq!(k.full(d), k.full(-d));
            assert!(k.full(d) < k0);
            assert!(k.projection(d) <= k.full(d));
        }
    }

    /// The f64 kernel is bit for bit the formula it had before the
    /// specialised `exp_nonpositive` / `sin2_scaled` and the short-SE cutoff.
    #[test]
    fn f64_is_the_reference_formula_bit_for_bit() {
        fn reference<const N: usize>(k: &Kernel<f64, N>, periods: &[f64; N], d: f64) -> f64 {
            let d2 = d * d;
            let mut v = k.long_variance * libm::exp(k.long_coeff * d2);
            for (st, p) in k.stages.iter().zip(periods) {
                if st.variance > 0.0 {
                    let s = libm::sin(core::f64::consts::PI / p * d);
                    v += st.variance * libm::exp(st.sin2_coeff * s * s + st.envelope_coeff * d2);
                }
            }
            v + k.short_variance * libm::exp(k.short_coeff * d * d)
        }
        let cases: [([f64; 2], [f64; 2]); 4] = [
            ([432.0, 155.0], [1.0, 0.6]),
            ([288.0, 110.0], [1.0, 1.0]),
            ([600.0, 37.5], [1.0, 0.0]),
            ([12.0, 1500.0], [1.0, 0.3]),
        ];
        for (periods, gates) in cases {
            let k: Kernel<f64, 2> = Kernel::new(&periods, &gates);
            // grid lags (multiples of 5 s) and fractional ones, to 3e4 s
            for i in -6000..=6000 {
                for d in [5.0 * i as f64, 5.0 * i as f64 + 0.37, 0.013 * i as f64] {
                    let want = reference(&k, &periods, d);
                    assert_eq!(k.full(d).to_bits(), want.to_bits(), "d = {d}");
                }
            }
        }
    }

    #[test]
    fn gated_out_stage_reduces_to_single_kernel() {
        let one: Kernel<f64, 1> = Kernel::new(&[432.0], &[1.0]);
        let two: Kernel<f64, 2> = Kernel::new(&[432.0, 155.0], &[1.0, 0.0]);
        for i in 0..500 {
            let d = i as f64 * 2.3;
            assert_eq!(one.full(d), two.full(d));
        }
    }

    #[test]
    fn gram_is_positive_definite() {
        use crate::model::ldlt::Ldlt;
        let k: Kernel<f64, 2> = Kernel::new(&[288.0, 110.0], &[1.0, 1.0]);
        let mut f: Ldlt<f64, 40, 820> = Ldlt::new();
        f.set_dim(40);
        for i in 0..40 {
            let row = f.row_mut(i);
            for (j, r) in row.iter_mut().enumerate() {
                *r = k.full(5.0 * (i as f64 - j as f64));
            }
            row[i] += 1e-6;
        }
        assert!(f.factor().is_ok());
    }
}
