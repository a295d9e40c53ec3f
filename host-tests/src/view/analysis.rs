//! What the page plots beyond the raw frames, computed here from the
//! observed gear error of the telemetry (`obs_mas`, measured and filled
//! frames only: an unmeasured or dither frame observes nothing):
//!
//! - the **spectrum**: the amplitude of the best-fitting sinusoid at each
//!   period of a log-spaced grid (a least-squares periodogram, which
//!   allows the uneven gear-time spacing of frames), after removing a
//!   straight line (the drift);
//! - the **stage fit**: a joint least-squares fit of the gear error as a
//!   line plus, for each stage the board reports, a periodic term at that
//!   period (fundamental and harmonics). The board does not report what
//!   its model learned for a stage (its amplitude reads 0), so this is the
//!   view's own reconstruction from the same observations, at the board's
//!   periods: what the page labels "fit at the board's stage periods".

use std::f64::consts::TAU;

/// Periods of the spectrum's grid.
pub const SPECTRUM_POINTS: usize = 240;
/// Harmonics per stage in the fit (a gear's error is rarely a pure sine).
pub const HARMONICS: usize = 3;
/// Points of the fitted curve over one worm period.
pub const CURVE_POINTS: usize = 120;

/// One observation: gear time and gear error, seconds and arcsec.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    pub t: f64,
    pub y: f64,
}

/// Solves the symmetric positive (semi-)definite system `a x = b` by
/// Gaussian elimination with partial pivoting, after a small ridge that
/// keeps collinear columns (a stage at another's harmonic) solvable.
fn solve(mut a: Vec<Vec<f64>>, mut b: Vec<f64>) -> Option<Vec<f64>> {
    let n = b.len();
    let trace: f64 = (0..n).map(|i| a[i][i]).sum();
    let ridge = 1e-9 * trace / n.max(1) as f64;
    for (i, row) in a.iter_mut().enumerate() {
        row[i] += ridge;
    }
    for c in 0..n {
        let p = (c..n).max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs()))?;
        if a[p][c].abs() < 1e-300 {
            return None;
        }
        a.swap(c, p);
        b.swap(c, p);
        let (top, below) = a.split_at_mut(c + 1);
        let pivot = &top[c];
        for (r, row) in below.iter_mut().enumerate() {
            let f = row[c] / pivot[c];
            for (x, p) in row[c..].iter_mut().zip(&pivot[c..]) {
                *x -= f * p;
            }
            b[c + 1 + r] -= f * b[c];
        }
    }
    let mut x = vec![0.0; n];
    for c in (0..n).rev() {
        let s: f64 = (c + 1..n).map(|k| a[c][k] * x[k]).sum();
        x[c] = (b[c] - s) / a[c][c];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// Least squares of `y` on the columns `f(t)`.
fn fit(samples: &[Sample], n: usize, f: impl Fn(f64, &mut [f64])) -> Option<Vec<f64>> {
    let mut a = vec![vec![0.0; n]; n];
    let mut b = vec![0.0; n];
    let mut row = vec![0.0; n];
    for s in samples {
        f(s.t, &mut row);
        for i in 0..n {
            b[i] += row[i] * s.y;
            for j in 0..n {
                a[i][j] += row[i] * row[j];
            }
        }
    }
    solve(a, b)
}

/// The first time and the span (at least 1 s): the line's column is
/// scaled to 0..1 so that it weighs like the sines in the ridge.
fn time_scale(samples: &[Sample]) -> (f64, f64) {
    let t0 = samples.first().map_or(0.0, |s| s.t);
    let t1 = samples.last().map_or(0.0, |s| s.t);
    (t0, (t1 - t0).max(1.0))
}

/// The samples less their straight-line fit (the drift), and that line.
pub fn detrend(samples: &[Sample]) -> Option<(Vec<Sample>, [f64; 2])> {
    if samples.len() < 3 {
        return None;
    }
    let (t0, span) = time_scale(samples);
    let c = fit(samples, 2, |t, r| {
        r[0] = 1.0;
        r[1] = (t - t0) / span;
    })?;
    let line = [c[0] - c[1] / span * t0, c[1] / span];
    let rest = samples
        .iter()
        .map(|s| Sample {
            t: s.t,
            y: s.y - line[0] - line[1] * s.t,
        })
        .collect();
    Some((rest, line))
}

/// The amplitude of the best-fitting sinusoid of period `p` (s).
fn amplitude_at(samples: &[Sample], p: f64) -> Option<f64> {
    let w = TAU / p;
    let c = fit(samples, 2, |t, r| {
        r[0] = (w * t).sin();
        r[1] = (w * t).cos();
    })?;
    Some(c[0].hypot(c[1]))
}

/// The periodogram: (period s, amplitude arcsec) on a log grid from four
/// frame intervals to half the span (a shorter record cannot show a
/// period), of detrended samples.
pub fn spectrum(samples: &[Sample]) -> Vec<(f64, f64)> {
    let Some((first, last)) = samples.first().zip(samples.last()) else {
        return Vec::new();
    };
    let span = last.t - first.t;
    let dt = span / (samples.len() - 1).max(1) as f64;
    let (lo, hi) = ((4.0 * dt).max(1.0), span / 2.0);
    if samples.len() < 16 || hi <= lo * 1.05 {
        return Vec::new();
    }
    (0..SPECTRUM_POINTS)
        .filter_map(|i| {
            let p = lo * (hi / lo).powf(i as f64 / (SPECTRUM_POINTS - 1) as f64);
            Some((p, amplitude_at(samples, p)?))
        })
        .collect()
}

/// Points of the fine search around each peak of the grid.
const PEAK_REFINE: usize = 24;

/// The local maxima of `spectrum` (of `samples`), highest first, each
/// refined between its grid neighbours: the grid's steps (about 2 % of the
/// period) are coarser than a peak is sharp over a long record.
pub fn peaks(samples: &[Sample], spectrum: &[(f64, f64)]) -> Vec<(f64, f64)> {
    let mut p: Vec<(f64, f64)> = spectrum
        .windows(3)
        .filter(|w| w[1].1 > w[0].1 && w[1].1 >= w[2].1)
        .map(|w| {
            let (lo, hi) = (w[0].0, w[2].0);
            (0..=PEAK_REFINE)
                .map(|i| lo + (hi - lo) * i as f64 / PEAK_REFINE as f64)
                .filter_map(|q| Some((q, amplitude_at(samples, q)?)))
                .fold(w[1], |best, x| if x.1 > best.1 { x } else { best })
        })
        .collect();
    p.sort_by(|a, b| b.1.total_cmp(&a.1));
    p
}

/// The stage fit: each stage's periodic term and the line.
#[derive(Clone, Debug, PartialEq)]
pub struct StageFit {
    /// The stages' periods, s.
    pub periods: Vec<f64>,
    /// Per stage, per harmonic h (1-based), the sine and cosine weights.
    pub terms: Vec<Vec<(f64, f64)>>,
    /// The line: offset and drift (arcsec, arcsec/s).
    pub line: [f64; 2],
    /// RMS of the detrended samples and of what the fit leaves, arcsec.
    pub rms_before: f64,
    pub rms_after: f64,
}

impl StageFit {
    /// Stage `k`'s contribution at gear time `t`.
    pub fn stage_at(&self, k: usize, t: f64) -> f64 {
        self.terms[k]
            .iter()
            .enumerate()
            .map(|(h, (s, c))| {
                let a = TAU * (h + 1) as f64 * t / self.periods[k];
                s * a.sin() + c * a.cos()
            })
            .sum()
    }

    /// Stage `k`'s amplitude: half its peak-to-peak over a period.
    pub fn amplitude(&self, k: usize) -> f64 {
        let p = self.periods[k];
        let v: Vec<f64> = (0..CURVE_POINTS)
            .map(|i| self.stage_at(k, p * i as f64 / CURVE_POINTS as f64))
            .collect();
        let (lo, hi) = v
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &x| {
                (l.min(x), h.max(x))
            });
        (hi - lo) / 2.0
    }
}

/// Fits the stages at `periods` (s) to the samples; harmonics above the
/// Nyquist rate of the frames, and stages longer than the record, are
/// left out (the record cannot tell them).
pub fn fit_stages(samples: &[Sample], periods: &[f64]) -> Option<StageFit> {
    let (first, last) = samples.first().zip(samples.last())?;
    let span = last.t - first.t;
    let dt = span / (samples.len() - 1).max(1) as f64;
    let periods: Vec<f64> = periods
        .iter()
        .copied()
        .filter(|&p| p.is_finite() && p > 2.0 * dt && p <= span)
        .collect();
    if periods.is_empty() {
        return None;
    }
    let harmonics: Vec<usize> = periods
        .iter()
        .map(|&p| {
            (1..=HARMONICS)
                .take_while(|&h| p / h as f64 > 2.0 * dt)
                .count()
        })
        .collect();
    let n = 2 + 2 * harmonics.iter().sum::<usize>();
    let (t0, scale) = time_scale(samples);
    let c = fit(samples, n, |t, r| {
        r[0] = 1.0;
        r[1] = (t - t0) / scale;
        let mut i = 2;
        for (p, &hs) in periods.iter().zip(&harmonics) {
            for h in 1..=hs {
                let a = TAU * h as f64 * t / p;
                r[i] = a.sin();
                r[i + 1] = a.cos();
                i += 2;
            }
        }
    })?;
    let mut i = 2;
    let terms = harmonics
        .iter()
        .map(|&hs| {
            let t: Vec<(f64, f64)> = (0..hs).map(|h| (c[i + 2 * h], c[i + 2 * h + 1])).collect();
            i += 2 * hs;
            t
        })
        .collect();
    let mut f = StageFit {
        periods,
        terms,
        line: [c[0] - c[1] / scale * t0, c[1] / scale],
        rms_before: 0.0,
        rms_after: 0.0,
    };
    let rms = |it: &mut dyn Iterator<Item = f64>| {
        let (s, n) = it.fold((0.0, 0usize), |(s, n), x| (s + x * x, n + 1));
        (s / n.max(1) as f64).sqrt()
    };
    let (detrended, _) = detrend(samples)?;
    f.rms_before = rms(&mut detrended.iter().map(|s| s.y));
    f.rms_after = rms(&mut samples.iter().map(|s| {
        let stages: f64 = (0..f.periods.len()).map(|k| f.stage_at(k, s.t)).sum();
        s.y - f.line[0] - f.line[1] * s.t - stages
    }));
    Some(f)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two sines of C8-like periods with a harmonic, a drift, every 2 s.
    fn samples() -> Vec<Sample> {
        (0..3000)
            .map(|i| {
                let t = 2.0 * i as f64;
                let y = 9.0 * (TAU * t / 288.0).sin()
                    + 6.0 * (TAU * t / 144.0).sin()
                    + 4.5 * (TAU * t / 110.0 + 1.0).sin()
                    + 0.0008 * t
                    + 3.0;
                Sample { t, y }
            })
            .collect()
    }

    #[test]
    fn the_spectrum_peaks_at_the_periods() {
        let (d, line) = detrend(&samples()).unwrap();
        assert!((line[1] - 0.0008).abs() < 2e-4, "drift {line:?}");
        let p = peaks(&d, &spectrum(&d));
        let mut top: Vec<f64> = p[..3].iter().map(|x| x.0).collect();
        top.sort_by(f64::total_cmp);
        for (got, want) in top.iter().zip([110.0, 144.0, 288.0]) {
            assert!((got / want - 1.0).abs() < 0.005, "peak {got} for {want}");
        }
        assert!((p[0].1 - 9.0).abs() < 1.0, "amplitude {}", p[0].1);
    }

    #[test]
    fn the_stage_fit_recovers_each_stage() {
        let f = fit_stages(&samples(), &[288.0, 110.0]).unwrap();
        // 288 s carries its 144 s harmonic: 9 sin + 6 sin(2x) peaks near
        // 13.3 arcsec; the 110 s stage is a pure 4.5 arcsec sine.
        assert!((f.amplitude(1) - 4.5).abs() < 0.05, "{}", f.amplitude(1));
        let pk = (0..2880)
            .map(|i| f.stage_at(0, i as f64 * 0.1))
            .fold(0.0f64, |m, x| m.max(x.abs()));
        let want = (0..2880)
            .map(|i| {
                let t = i as f64 * 0.1;
                9.0 * (TAU * t / 288.0).sin() + 6.0 * (TAU * t / 144.0).sin()
            })
            .fold(0.0f64, |m, x| m.max(x.abs()));
        assert!((pk - want).abs() < 0.05, "{pk} vs {want}");
        assert!(
            f.rms_after < 1e-3 * f.rms_before,
            "{} {}",
            f.rms_after,
            f.rms_before
        );
    }
}
