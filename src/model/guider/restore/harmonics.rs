//! Each stage's share of the saved cells, so that a stage can be moved to
//! its own phase after a restore (docs/model.md, "Snapshot and restore").
//!
//! A worm index gives the worm's phase only: the saved cells are placed at
//! it, and every other stage turned by an unknown amount while the power
//! was off. One contiguous stretch of cells cannot put them all right, so
//! each stage's part is taken out of the saved cells and put back at the
//! phase the new data shows. That part is a sum of harmonics of the
//! stage's period, fitted to the saved cells by least squares together
//! with the worm's harmonics, a level and a slope (the newest cells
//! weighing most, `recent_shares`: [`Harmonics::fit`]): over the 83 min saved
//! (11 worm periods) the stages' harmonics are nearly orthogonal, and a
//! harmonic that falls on an earlier stage's (C3's 144 s: the worm's third
//! and the 288 s stage's second) is left to that stage.

use core::f64::consts::TAU;

use crate::model::gp::grid::CELL_S;
use crate::model::gp::kernel::ENVELOPE_PERIODS;
use crate::model::ldlt::Ldlt;
use crate::model::numeric::approx::exp_nonpositive;
use crate::model::numeric::cos_sin::cos_sin;

/// Harmonics fitted per stage (the synthetic gears have up to the worm's
/// fourth and the other stages' second).
const HARMONICS: usize = 4;
/// Stages fitted: the worm and two more. Further stages keep their share
/// where the worm's placement put it.
const MAX_STAGES: usize = 3;
/// Unknowns of the fit: a level, a slope, a cosine and a sine per harmonic
/// (on the stack while fitting: 2.8 KiB for the normal equations).
const TERMS: usize = 2 + 2 * HARMONICS * MAX_STAGES;
const TRIANGLE: usize = TERMS * (TERMS + 1) / 2;
/// Candidate phases per period in the phase search, before the parabola
/// through the best three refines it.
const PHASE_STEPS: usize = 128;
/// Harmonics shorter than this, s, are not fitted (the cells average over
/// 5 s).
const SHORTEST_HARMONIC_S: f64 = 4.0 * CELL_S;
/// Cycles over the saved span by which two harmonics must differ to be
/// told apart: 1.5 cycles apart, two sinusoids over the span correlate by
/// at most 0.21 (|sin 1.5π| / 1.5π). C2's 380 s stage and 432 s worm
/// differ by 1.6 (at 2 it was left to the placement search, whose shifts
/// of whole worm periods put it up to 26 s off its phase); C5's 155 s
/// stage and the worm's third by 2.4.
const SEPARATION: f64 = 1.5;
/// Added to the normal equations' diagonal, relative to the cell count:
/// far below the data, it only keeps a term the cells do not determine
/// from making them singular.
const RIDGE: f64 = 1e-9;

/// The contrast an F-test at 95 % asks of one parameter against the
/// residuals' degrees of freedom, 1 to 20 (few residuals estimate their
/// variance poorly); beyond, [`F_95_MANY`] (its value at 60). A phase
/// taken wrongly costs minutes and one more cell of waiting costs five
/// seconds without the stage; measured on `guide-sim nights` against 90 %
/// (docs/model.md).
const F_95: [f64; 20] = [
    161.4, 18.51, 10.13, 7.709, 6.608, 5.987, 5.591, 5.318, 5.117, 4.965, 4.844, 4.747, 4.667,
    4.600, 4.543, 4.494, 4.451, 4.414, 4.381, 4.351,
];
const F_95_MANY: f64 = 4.001;

/// A stage's phase found in new data: the shift that places it, s, and how
/// clearly the data picks it (see [`Harmonics::phase`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct StagePhase {
    pub(super) shift_s: f64,
    /// The squared residuals at every shift an eighth of a period or more
    /// away, less those at the shift, in the residuals' variance.
    pub(super) contrast: f64,
    /// The residuals' degrees of freedom (less the level and the shift).
    pub(super) dof: usize,
}

impl StagePhase {
    /// Where a placement put the stage: no shift, picked by nothing.
    pub(super) const PLACED: Self = Self {
        shift_s: 0.0,
        contrast: 0.0,
        dof: 0,
    };

    /// Whether the data picks this phase over every other at 95 %.
    pub(super) fn is_clear(&self) -> bool {
        let needed = match self.dof {
            0 => f64::INFINITY,
            d => F_95.get(d - 1).copied().unwrap_or(F_95_MANY),
        };
        self.contrast >= needed
    }
}

/// The saved cells as a level, a slope and each stage's harmonics, on the
/// grid's time (s from the grid's origin).
#[derive(Clone, Copy, Debug)]
pub(super) struct Harmonics<const N: usize> {
    periods: [f64; N],
    /// Cosine and sine coefficients of harmonics 1..=[`HARMONICS`] of each
    /// stage; 0 for the harmonics not fitted.
    coeffs: [[[f64; 2]; HARMONICS]; N],
    level: f64,
    /// Per second from `t_ref`.
    slope: f64,
    t_ref: f64,
}

/// cos and sin of `k θ` for k = 1..=[`HARMONICS`], from those of θ.
fn harmonics(cos: f64, sin: f64) -> [[f64; 2]; HARMONICS] {
    let mut out = [[cos, sin]; HARMONICS];
    let mut prev = [cos, sin];
    for h in out.iter_mut().skip(1) {
        prev = [prev[0] * cos - prev[1] * sin, prev[1] * cos + prev[0] * sin];
        *h = prev;
    }
    out
}

/// Which harmonics of which stages the fit takes: the worm's (stage 0) and
/// those of the stages with weight (gate > 0), each as long as
/// [`SHORTEST_HARMONIC_S`], except where a harmonic lies within the fit's
/// resolution (`1 / span`) of a harmonic of an earlier stage: the two
/// could not be told apart, and the earlier stage keeps it.
fn fitted<const N: usize>(
    periods: &[f64; N],
    gates: &[f64; N],
    span: f64,
) -> [[bool; HARMONICS]; N] {
    let mut fitted = [[false; HARMONICS]; N];
    let usable = |s: usize| {
        let p = periods[s];
        s < MAX_STAGES && p.is_finite() && p > 0.0 && (s == 0 || gates[s] > 0.0)
    };
    for s in (0..N).filter(|&s| usable(s)) {
        for k in 0..HARMONICS {
            let f = (k + 1) as f64 / periods[s];
            let distinct = (0..s).filter(|&e| usable(e)).all(|e| {
                let m = libm::round(f * periods[e]);
                m < 1.0 || (f - m / periods[e]).abs() * span >= SEPARATION
            });
            fitted[s][k] = distinct && 1.0 / f >= SHORTEST_HARMONIC_S;
        }
        // A stage whose fundamental cannot be told from an earlier
        // stage's harmonic is not a stage of its own here.
        if !fitted[s][0] {
            fitted[s] = [false; HARMONICS];
        }
    }
    fitted
}

/// Each stage's cosine and sine of `2π t / P` at `t = first`, `first +
/// CELL_S`, ...: by rotation, two `libm` calls per stage in all (on the
/// target `f64` is in software, and a call costs thousands of
/// instructions); in `f64` a grid's rotations drift by about 1e-13.
fn phasors<const N: usize>(periods: &[f64; N], first: f64) -> impl Iterator<Item = [[f64; 2]; N]> {
    let turn = |angle: f64| {
        let (c, s) = cos_sin(angle);
        [c, s]
    };
    let mut now = periods.map(|p| turn(TAU * first / p));
    let step = periods.map(|p| turn(TAU * CELL_S / p));
    core::iter::from_fn(move || {
        let out = now;
        for (n, [c, s]) in now.iter_mut().zip(step) {
            *n = [n[0] * c - n[1] * s, n[1] * c + n[0] * s];
        }
        Some(out)
    })
}

/// The fit's terms: 1, the slope's `slope_x` ((t - t_ref) / half the
/// span), and the cosine and sine of each fitted harmonic, from each
/// stage's `phasors` at `t`, in the order of [`Harmonics::fit`]'s unknowns.
fn basis<const N: usize>(
    slope_x: f64,
    phasors: &[[f64; 2]; N],
    fitted: &[[bool; HARMONICS]; N],
) -> [f64; TERMS] {
    let mut x = [0.0; TERMS];
    x[0] = 1.0;
    x[1] = slope_x;
    let mut slots = x.iter_mut().skip(2);
    for (&[c1, s1], fitted) in phasors.iter().zip(fitted) {
        for ([c, s], _) in harmonics(c1, s1).iter().zip(fitted).filter(|(_, &f)| f) {
            if let (Some(a), Some(b)) = (slots.next(), slots.next()) {
                *a = *c;
                *b = *s;
            }
        }
    }
    x
}

/// A stage's share from its coefficients and the cosine and sine of its
/// fundamental's phase.
fn share(coeffs: &[[f64; 2]; HARMONICS], cos: f64, sin: f64) -> f64 {
    coeffs
        .iter()
        .zip(&harmonics(cos, sin))
        .map(|([a, b], [c, s])| a * c + b * s)
        .sum()
}

impl<const N: usize> Harmonics<N> {
    /// Fit to `cells`, the gear error of consecutive cells from the one
    /// centred at grid time `first` (`None`: not measured), which span
    /// `span` s. With `recent`, each cell weighs as the envelope of the
    /// shortest stage fitted (the worm has none) weighs it for the time
    /// right after the newest: the shares are put back where the model
    /// predicts from them, and a stage that faded or grew over the saved
    /// span is put back as it was last, not at its mean. `None` if they do
    /// not determine the fit (too few measured, or the normal equations do
    /// not factor).
    pub(super) fn fit(
        cells: impl Iterator<Item = Option<f64>>,
        first: f64,
        span: f64,
        periods: &[f64; N],
        gates: &[f64; N],
        recent: bool,
    ) -> Option<Self> {
        let fitted = fitted(periods, gates, span);
        // -1 / (2 (λ P)²) of the shortest fitted stage's envelope; 0 (all
        // alike) without one.
        let envelope_coeff = if recent {
            (1..N)
                .filter(|&s| fitted[s][0])
                .map(|s| {
                    let length = ENVELOPE_PERIODS * periods[s];
                    -0.5 / (length * length)
                })
                .fold(0.0, f64::min)
        } else {
            0.0
        };
        let newest = first + span;
        let terms = 2 + 2 * fitted.iter().flatten().filter(|&&f| f).count();
        let mut h = Self {
            periods: *periods,
            coeffs: [[[0.0; 2]; HARMONICS]; N],
            level: 0.0,
            slope: 0.0,
            t_ref: first + 0.5 * span,
        };
        let half_span = (0.5 * span).max(CELL_S);
        let mut normal: Ldlt<f64, TERMS, TRIANGLE> = Ldlt::new();
        normal.set_dim(terms);
        let mut rhs = [0.0; TERMS];
        let mut count = 0usize;
        for (k, (y, phasors)) in cells.zip(phasors(periods, first)).enumerate() {
            let Some(y) = y else { continue };
            let t = first + CELL_S * k as f64;
            let x = basis((t - h.t_ref) / half_span, &phasors, &fitted);
            // A weight needs no more than f32's precision, and the target's
            // f32 exponential keeps libm's f64 one out of its flash.
            let w = f64::from(exp_nonpositive(
                (envelope_coeff * (newest - t) * (newest - t)) as f32,
            ));
            for (i, (&xi, b)) in x.iter().zip(&mut rhs).take(terms).enumerate() {
                *b += w * xi * y;
                for (a, &xj) in normal.row_mut(i).iter_mut().zip(&x) {
                    *a += w * xi * xj;
                }
            }
            count += 1;
        }
        if count < 2 * terms {
            return None;
        }
        for i in 0..terms {
            if let Some(d) = normal.row_mut(i).last_mut() {
                *d += RIDGE * count as f64;
            }
        }
        normal.factor().ok()?;
        let solution = rhs.get_mut(..terms)?;
        normal.solve(solution).ok()?;
        if !solution.iter().all(|c| c.is_finite()) {
            return None;
        }
        let mut next = solution.iter();
        h.level = *next.next()?;
        h.slope = *next.next()? / half_span;
        for (coeffs, fitted) in h.coeffs.iter_mut().zip(&fitted) {
            for (c, _) in coeffs.iter_mut().zip(fitted).filter(|(_, &f)| f) {
                *c = [*next.next()?, *next.next()?];
            }
        }
        Some(h)
    }

    /// How much the stages' shares, summed, change from `self` to `to`
    /// (of the same periods) at `first`, `first + CELL_S`, ... (grid
    /// times): one pass over the coefficients' difference, the stages
    /// that do not change skipped (a refine moves one stage of a thousand
    /// saved cells, in soft floating point on the target).
    pub(super) fn change_to(&self, to: &Self, first: f64) -> impl Iterator<Item = f64> {
        let mut change = to.coeffs;
        for (c, was) in change
            .iter_mut()
            .flatten()
            .zip(self.coeffs.iter().flatten())
        {
            *c = [c[0] - was[0], c[1] - was[1]];
        }
        let moves = change.map(|c| c.iter().flatten().any(|&x| x != 0.0));
        phasors(&self.periods, first).map(move |phasors| {
            (0..N)
                .filter(|&s| moves[s])
                .map(|s| share(&change[s], phasors[s][0], phasors[s][1]))
                .sum()
        })
    }

    /// Take stage `s` out (its share is 0 everywhere).
    pub(super) fn clear(&mut self, s: usize) {
        if let Some(c) = self.coeffs.get_mut(s) {
            *c = [[0.0; 2]; HARMONICS];
        }
    }

    /// Move stage `s` by `by` s: its share at `t` becomes what it was at
    /// `t + by`.
    pub(super) fn shift(&mut self, s: usize, by: f64) {
        let (Some(coeffs), Some(&period)) = (self.coeffs.get_mut(s), self.periods.get(s)) else {
            return;
        };
        let (cos_phi, sin_phi) = cos_sin(TAU * by / period);
        for ([a, b], [c, sn]) in coeffs.iter_mut().zip(harmonics(cos_phi, sin_phi)) {
            (*a, *b) = (*a * c + *b * sn, *b * c - *a * sn);
        }
    }

    /// The level and slope at grid time `t`.
    pub(super) fn trend(&self, t: f64) -> f64 {
        self.level + self.slope * (t - self.t_ref)
    }

    /// Move the level by `by` (the cells it was fitted to moved).
    pub(super) fn shift_level(&mut self, by: f64) {
        self.level += by;
    }

    /// Stage `s`'s share at grid time `t`.
    pub(super) fn stage(&self, s: usize, t: f64) -> f64 {
        let (Some(coeffs), Some(&period)) = (self.coeffs.get(s), self.periods.get(s)) else {
            return 0.0;
        };
        let theta = TAU * t / period;
        let (c, s) = cos_sin(theta);
        share(coeffs, c, s)
    }

    /// Whether any harmonic of stage `s` was fitted.
    pub(super) fn has_stage(&self, s: usize) -> bool {
        self.coeffs
            .get(s)
            .is_some_and(|c| c.iter().flatten().any(|&x| x != 0.0))
    }

    /// The phase shift `δ` (s, within one period) that best explains
    /// `residuals` (grid time and gear error less everything but stage
    /// `s`) as stage `s`'s share at `t + δ` plus a level: least squares,
    /// over [`PHASE_STEPS`] candidates per period, refined by the parabola
    /// through the best and its neighbours; with the contrast to the best
    /// other local minimum. `None` with fewer than 3 residuals.
    pub(super) fn phase(
        &self,
        s: usize,
        residuals: impl Iterator<Item = (f64, f64)> + Clone,
    ) -> Option<StagePhase> {
        let (Some(coeffs), Some(&period)) = (self.coeffs.get(s), self.periods.get(s)) else {
            return None;
        };
        // Σ e and Σ e² per candidate, e = r - stage(t + δ): each residual's
        // angle once, the candidates by rotation.
        let mut sums = [[0.0f64; 2]; PHASE_STEPS];
        let step = TAU / PHASE_STEPS as f64;
        let (step_cos, step_sin) = cos_sin(step);
        let mut n = 0usize;
        for (t, r) in residuals {
            let theta = TAU * t / period;
            let (mut c, mut sn) = cos_sin(theta);
            for sum in &mut sums {
                let value: f64 = coeffs
                    .iter()
                    .zip(&harmonics(c, sn))
                    .map(|([a, b], [hc, hs])| a * hc + b * hs)
                    .sum();
                let e = r - value;
                sum[0] += e;
                sum[1] += e * e;
                (c, sn) = (c * step_cos - sn * step_sin, sn * step_cos + c * step_sin);
            }
            n += 1;
        }
        if n < 3 {
            return None;
        }
        let cost = |j: usize| {
            let [se, see] = sums[j % PHASE_STEPS];
            see - se * se / n as f64
        };
        let best = (0..PHASE_STEPS).min_by(|&a, &b| cost(a).total_cmp(&cost(b)))?;
        let (before, at, after) = (cost(best + PHASE_STEPS - 1), cost(best), cost(best + 1));
        let curvature = before - 2.0 * at + after;
        let offset = if curvature > 0.0 {
            (0.5 * (before - after) / curvature).clamp(-1.0, 1.0)
        } else {
            0.0
        };
        let shift_s = (best as f64 + offset) * period / PHASE_STEPS as f64;
        // How much better the best shift explains the residuals than every
        // shift an eighth of a period or more away, in their variance (less
        // the level and the shift fitted): a short stretch of a stage, a
        // level fitted, is nearly a line, and noise can flip the curvature
        // that tells two shifts apart.
        let dof = n.saturating_sub(2);
        let variance = at.max(0.0) / dof.max(1) as f64;
        let rival = (PHASE_STEPS / 8..=PHASE_STEPS - PHASE_STEPS / 8)
            .map(|d| cost(best + d))
            .fold(f64::INFINITY, f64::min);
        let contrast = (rival - at) / variance.max(f64::MIN_POSITIVE);
        shift_s.is_finite().then_some(StagePhase {
            shift_s,
            contrast,
            dof,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A C5-like gear with a level and a drift: the 432 s worm and a 155 s
    /// stage, each with its second harmonic.
    fn worm(t: f64) -> f64 {
        9.0 * libm::sin(TAU * t / 432.0) + 3.0 * libm::cos(TAU * t / 216.0)
    }
    fn stage(t: f64) -> f64 {
        4.5 * libm::sin(TAU * t / 155.0 + 0.3) + 1.5 * libm::sin(TAU * t / 77.5)
    }

    /// 1,000 cells of 5 s (the saved span), as `fit` takes them.
    fn cells(gear: impl Fn(f64) -> f64) -> impl Iterator<Item = Option<f64>> {
        (0..1000).map(move |i| Some(gear(5.0 * i as f64 - 2.5)))
    }

    fn fit(periods: [f64; 2]) -> Option<Harmonics<2>> {
        let gear = |t: f64| 3.0 + 1e-3 * t + worm(t) + stage(t);
        Harmonics::fit(cells(gear), -2.5, 4995.0, &periods, &[1.0, 1.0], true)
    }

    #[test]
    fn the_fit_takes_the_stages_apart() {
        let h = fit([432.0, 155.0]).unwrap();
        for i in 0..200 {
            let t = 25.0 * i as f64;
            assert!((h.stage(0, t) - worm(t)).abs() < 1e-6, "worm at {t}");
            assert!((h.stage(1, t) - stage(t)).abs() < 1e-6, "stage at {t}");
            assert!((h.trend(t) - 3.0 - 1e-3 * t).abs() < 1e-6, "trend at {t}");
        }
    }

    /// The peak of stage 1's share in `h` over one period around `t`.
    fn peak_near(h: &Harmonics<2>, t: f64) -> f64 {
        (0..155)
            .map(|j| h.stage(1, t - j as f64).abs())
            .fold(0.0, f64::max)
    }

    #[test]
    fn a_stage_that_faded_is_taken_as_the_envelope_weighs_it_and_without_recent_shares_at_its_mean()
    {
        // The 155 s stage fades to a fifth of itself over the saved span.
        let amplitude = |t: f64| 1.0 - 0.8 * (t + 2.5) / 5000.0;
        let fading = |t: f64| worm(t) + amplitude(t) * stage(t);
        let share_at_end = |recent| {
            let periods = [432.0, 155.0];
            let h = Harmonics::fit(cells(fading), -2.5, 4995.0, &periods, &[1.0, 1.0], recent);
            peak_near(&h.unwrap(), 4995.0) / peak_near(&fit(periods).unwrap(), 4995.0)
        };
        // The amplitude as the stage's envelope (20 periods) weighs the
        // cells from the newest: 0.52; their mean 0.6; the last 0.2.
        let weighed = (0..1000).map(|i| {
            let age = 5.0 * (999 - i) as f64;
            let w = libm::exp(-0.5 * age * age / (20.0 * 155.0f64).powi(2));
            (w * amplitude(5.0 * i as f64 - 2.5), w)
        });
        let (sum, weights) = weighed.fold((0.0, 0.0), |(s, n), (x, w)| (s + x, n + w));
        let (recent, mean) = (share_at_end(true), share_at_end(false));
        assert!(
            (recent - sum / weights).abs() < 0.005,
            "{recent} {}",
            sum / weights
        );
        assert!((mean - 0.6).abs() < 0.005, "{mean}");
    }

    #[test]
    fn a_shifted_stage_is_the_stage_later_and_its_phase_is_found() {
        let mut h = fit([432.0, 155.0]).unwrap();
        let moved = {
            let mut m = h;
            m.shift(1, 40.0);
            m
        };
        for i in 0..100 {
            let t = 7.0 * i as f64;
            assert!((moved.stage(1, t) - h.stage(1, t + 40.0)).abs() < 1e-9);
        }
        // Nine cells (a tenth of the worm's period) of the stage 60 s on,
        // at another level: the phase search finds the 60 s.
        let residuals = (0..9).map(|j| {
            let t = 6000.0 + 5.0 * j as f64;
            (t, stage(t + 60.0) - 2.0)
        });
        let found = h.phase(1, residuals).unwrap();
        assert!((found.shift_s - 60.0).abs() < 0.2, "{found:?}");
        assert!(found.is_clear() && found.contrast > 100.0, "{found:?}");
        h.shift(1, found.shift_s);
        assert!((h.stage(1, 6000.0) - stage(6060.0)).abs() < 0.05);
    }

    #[test]
    fn noise_that_leaves_the_phase_open_shows_as_low_contrast() {
        let h = fit([432.0, 155.0]).unwrap();
        // The stage 60 s on under 6 px of noise (uniform, from a fixed
        // linear congruential sequence).
        let mut state = 12345u64;
        let noise: Vec<f64> = (0..200)
            .map(|_| {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                12.0 * ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5)
            })
            .collect();
        let residuals = |cells: usize| {
            let noise = noise.clone();
            (0..cells).map(move |j| {
                let t = 6000.0 + 5.0 * j as f64;
                (t, stage(t + 60.0) + noise[j])
            })
        };
        // Nine cells cannot tell the phase from a level and the noise;
        // two stage periods can.
        let short = h.phase(1, residuals(9)).unwrap();
        assert!(!short.is_clear(), "{short:?}");
        let long = h.phase(1, residuals(62)).unwrap();
        assert!(long.is_clear(), "{long:?}");
        assert!((long.shift_s - 60.0).abs() < 5.0, "{long:?}");
    }

    #[test]
    fn what_the_span_cannot_tell_apart_stays_with_the_earlier_stage() {
        // C3: the 288 s stage's second harmonic is the worm's third, its
        // fourth the worm's sixth.
        let c3 = fitted_flags([432.0, 288.0]);
        assert_eq!(c3[1], [true, false, true, false]);
        // C2: 380 s and 432 s differ by 1.6 cycles over the 83 min saved,
        // 400 s and 432 s by 0.9.
        assert!(fitted_flags([432.0, 380.0])[1][0]);
        assert_eq!(fitted_flags([432.0, 400.0])[1], [false; HARMONICS]);
        // A stage at the worm's harmonic (C4's 216 s) is the worm's.
        assert_eq!(fitted_flags([432.0, 216.0])[1], [false; HARMONICS]);
        assert!(!fit([432.0, 216.0]).unwrap().has_stage(1));
    }

    fn fitted_flags(periods: [f64; 2]) -> [[bool; HARMONICS]; 2] {
        super::fitted(&periods, &[1.0, 1.0], 4995.0)
    }
}
