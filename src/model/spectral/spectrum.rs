//! The spectrum of the gear error that period tracking and stage discovery
//! read: de-trended by least squares, Hamming-windowed, zero-padded to
//! [`FFT_LEN`] and transformed (paper sec. 2; docs/reference.md section 2).
//!
//! The spectrum only changes when the grid completes a cell, so the guider
//! recomputes it then and reads it on every frame in between.

use crate::model::gp::grid::{Grid, CELL_S};
use crate::model::numeric::scalar::Scalar;
use crate::model::spectral::fft::{power_spectrum, FFT_LEN};

/// Highest bin of the one-sided spectrum (Nyquist).
pub const NYQUIST_BIN: usize = FFT_LEN / 2;
/// Peaks slower than this are drift, not gear error, and are ignored.
pub const MAX_PERIOD_S: f64 = 1500.0;
/// Ridge on the de-trending normal equations (reference implementation).
const RIDGE: f64 = 1e-3;

/// Period (s) of a (fractional) bin.
pub fn bin_period(bin: f64) -> f64 {
    FFT_LEN as f64 * CELL_S / bin
}

/// Fractional bin of a period (s).
pub fn period_bin(period: f64) -> f64 {
    FFT_LEN as f64 * CELL_S / period
}

/// A peak found in the spectrum.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Peak {
    /// Period from the parabola through its bin and the neighbours (s).
    pub period_s: f64,
    /// Power of its bin (|X|², not normalised).
    pub power: f64,
}

/// The power spectrum of the grid, in a borrowed work buffer of 4096
/// scalars (16 KiB in `f32`). The guider reads the peaks it needs at once and
/// then lends the same buffer to the inference as scratch.
pub struct Spectrum<'a, S> {
    buf: &'a [S; FFT_LEN],
    /// Lowest meaningful bin, `ceil(FFT_LEN / cells)`: below it the zero
    /// padding, not the data, sets the resolution.
    low_bin: usize,
    /// A peak's parabola through the logarithm of the power
    /// ([`Additions::log_power_peak`](crate::model::additions::Additions)).
    log_power_peak: bool,
}

impl<'a, S: Scalar> Spectrum<'a, S> {
    /// Compute the power spectrum of the grid's cells in `buf`. Needs two
    /// cells.
    pub fn compute(grid: &Grid<S>, buf: &'a mut [S; FFT_LEN]) -> Option<Self> {
        let n = grid.len();
        if n < 2 {
            return None;
        }
        // Least-squares line g ≈ w0 + w1 t through the cells, t the cell
        // centre, with the reference implementation's ridge of 1e-3 on both
        // normal-equation diagonals. The sums over t are exact for the
        // regular cells; those over g are taken with t centred on the window
        // (accurate in f32) and shifted back in f64.
        let nf = n as f64;
        let t_first = grid.cell_time(0);
        let t_mean = t_first + 0.5 * CELL_S * (nf - 1.0);
        let half = S::from_f64(0.5 * (nf - 1.0));
        let cell = S::from_f64(CELL_S);
        let mut sum_g = S::ZERO;
        let mut sum_cg = S::ZERO;
        for i in 0..n {
            let g = grid.cell(i).0;
            sum_g += g;
            sum_cg += (S::from_usize(i) - half) * cell * g;
        }
        let (sum_g, sum_cg) = (sum_g.to_f64(), sum_cg.to_f64());
        let sum_c2 = CELL_S * CELL_S * nf * (nf * nf - 1.0) / 12.0;
        let a00 = nf + RIDGE;
        let a01 = nf * t_mean;
        let a11 = sum_c2 + nf * t_mean * t_mean + RIDGE;
        let b0 = sum_g;
        let b1 = sum_cg + t_mean * sum_g;
        let det = a00 * a11 - a01 * a01;
        let (w0, w1) = if det != 0.0 {
            ((b0 * a11 - a01 * b1) / det, (a00 * b1 - a01 * b0) / det)
        } else {
            (0.0, 0.0)
        };
        // The trend at the window's centre, and its slope per cell.
        let level = S::from_f64(w0 + w1 * t_mean);
        let step = S::from_f64(w1 * CELL_S);

        let two_pi_over = S::from_f64(2.0 * core::f64::consts::PI / (nf - 1.0));
        for (i, x) in buf.iter_mut().enumerate().take(n) {
            let g = grid.cell(i).0;
            let i_s = S::from_usize(i);
            let detrended = g - level - step * (i_s - half);
            let hamming = S::from_f64(0.54) - S::from_f64(0.46) * (two_pi_over * i_s).cos();
            *x = detrended * hamming;
        }
        for x in buf.iter_mut().skip(n) {
            *x = S::ZERO;
        }
        power_spectrum(buf);
        let low_bin = FFT_LEN.div_ceil(n).min(NYQUIST_BIN);
        // Peaks slower than MAX_PERIOD_S are drift.
        let drift_bins = period_bin(MAX_PERIOD_S);
        for k in low_bin..=NYQUIST_BIN {
            if (k as f64) < drift_bins {
                buf[k] = S::ZERO;
            }
        }
        Some(Self {
            buf,
            low_bin,
            log_power_peak: false,
        })
    }

    /// The same spectrum, its peaks refined through the logarithm of the
    /// power (`on`) or through the power, as the reference does.
    pub fn log_power_peak(self, on: bool) -> Self {
        Self {
            log_power_peak: on,
            ..self
        }
    }

    /// A spectrum of the given power per bin, every bin from 1 meaningful:
    /// scripted input for the tests of what reads it.
    #[cfg(test)]
    pub fn scripted(buf: &'a [S; FFT_LEN]) -> Self {
        Self {
            buf,
            low_bin: 1,
            log_power_peak: false,
        }
    }

    /// Power of bin `k` (0 outside the meaningful range).
    pub fn power(&self, k: usize) -> f64 {
        if k >= self.low_bin && k <= NYQUIST_BIN {
            self.buf[k].to_f64()
        } else {
            0.0
        }
    }

    /// Meaningful bins, inclusive.
    pub fn bins(&self) -> (usize, usize) {
        (self.low_bin, NYQUIST_BIN)
    }

    /// The strongest peak among the bins in `[lo, hi]` for which `keep`
    /// holds, refined by a parabola through its neighbours (which may lie
    /// outside the band). The first of equal maxima wins.
    pub fn strongest(&self, lo: usize, hi: usize, keep: impl Fn(usize) -> bool) -> Option<Peak> {
        let lo = lo.max(self.low_bin);
        let hi = hi.min(NYQUIST_BIN);
        let mut best: Option<(usize, f64)> = None;
        for k in lo..=hi {
            if !keep(k) {
                continue;
            }
            let p = self.power(k);
            if best.is_none_or(|(_, bp)| p > bp) {
                best = Some((k, p));
            }
        }
        let (k, peak) = best?;
        let mut bin = k as f64;
        if k > self.low_bin && k < NYQUIST_BIN && peak > 0.0 {
            let y0 = self.power(k - 1) / peak;
            let y2 = self.power(k + 1) / peak;
            bin += if self.log_power_peak && y0 > 0.0 && y2 > 0.0 {
                log_parabola_offset(y0, y2)
            } else {
                power_parabola_offset(y0, y2)
            };
        }
        if !(bin > 0.0) || !peak.is_finite() {
            return None;
        }
        Some(Peak {
            period_s: bin_period(bin),
            power: peak,
        })
    }
}

/// The vertex of the parabola through the power of a peak's bin (1) and of
/// its neighbours (`y0` below, `y2` above, relative to it), in bins from
/// the peak's: the reference's estimator. A windowed line's main lobe is
/// not a parabola, so the vertex leans towards the bin's centre by a few
/// hundredths of a bin.
fn power_parabola_offset(y0: f64, y2: f64) -> f64 {
    let (lo3, hi3) = (y0.min(y2).min(1.0), y0.max(y2).max(1.0));
    let curvature = y0 + y2 - 2.0;
    if hi3 - lo3 >= 1e-10 && curvature != 0.0 {
        -0.5 * (y2 - y0) / curvature
    } else {
        0.0
    }
}

/// The same through the logarithm of the power (a Gaussian through the
/// three bins): the Hamming window's main lobe is close to a Gaussian near
/// its top, so the vertex lies near the line's frequency wherever it falls
/// between bins. Both neighbours must hold power. In `f64`, as the rest of
/// the peak's refinement.
fn log_parabola_offset(y0: f64, y2: f64) -> f64 {
    let (l0, l2) = (libm::log(y0), libm::log(y2));
    let curvature = l0 + l2;
    if curvature < 0.0 {
        -0.5 * (l2 - l0) / curvature
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::gp::grid::Averaging;

    fn grid_of(f: impl Fn(f64) -> f64, until: f64) -> Grid<f64> {
        let mut g = Grid::new(Averaging::Reference);
        let mut t = 0.0;
        while t < until {
            g.push(t, f(t), 1.0);
            t += 2.0;
        }
        g
    }

    #[test]
    fn finds_a_tone_and_its_period() {
        let pi2 = 2.0 * core::f64::consts::PI;
        let g = grid_of(|t| 9.0 * libm::sin(pi2 * t / 432.0) + 0.001 * t, 8000.0);
        let mut buf = [0.0; FFT_LEN];
        let s = Spectrum::compute(&g, &mut buf).unwrap();
        let peak = s.strongest(0, NYQUIST_BIN, |_| true).unwrap();
        assert!((peak.period_s - 432.0).abs() < 2.0, "{peak:?}");
    }

    /// The worst error (s) of the worm's period over sines of 420-440 s on
    /// a full grid, with the peak refined one way or the other.
    fn worst_period_error(log_power_peak: bool) -> f64 {
        let pi2 = 2.0 * core::f64::consts::PI;
        let mut worst: f64 = 0.0;
        for period in 420..=440 {
            let period = period as f64;
            let g = grid_of(|t| 5.0 * libm::sin(pi2 * t / period), 12_000.0);
            let mut buf = [0.0; FFT_LEN];
            let s = Spectrum::compute(&g, &mut buf)
                .unwrap()
                .log_power_peak(log_power_peak);
            let peak = s.strongest(0, NYQUIST_BIN, |_| true).unwrap();
            worst = worst.max((peak.period_s - period).abs());
        }
        worst
    }

    #[test]
    fn the_log_power_peak_finds_the_period_where_the_power_parabola_is_off() {
        let (log, power) = (worst_period_error(true), worst_period_error(false));
        println!("worst period error over 420-440 s: log power {log:.3} s, power {power:.3} s");
        // Across a meridian flip's 100 worm turns a worm of 432 s keeps
        // its third harmonic's phase to a tenth of a turn only while its
        // period is right to 0.14 s: the goal, which the reference's
        // estimator misses.
        let goal_s = 0.14;
        assert!(log <= goal_s, "{log}");
        assert!(power > goal_s, "{power}");
    }

    #[test]
    fn band_and_notch_select_the_second_peak() {
        let pi2 = 2.0 * core::f64::consts::PI;
        let g = grid_of(
            |t| 9.0 * libm::sin(pi2 * t / 288.0) + 4.5 * libm::sin(pi2 * t / 110.0),
            8000.0,
        );
        let mut buf = [0.0; FFT_LEN];
        let s = Spectrum::compute(&g, &mut buf).unwrap();
        let primary = period_bin(288.0);
        let peak = s
            .strongest(0, NYQUIST_BIN, |k| {
                ((k as f64) / primary - 1.0).abs() > 0.08
            })
            .unwrap();
        assert!((peak.period_s - 110.0).abs() < 1.0, "{peak:?}");
    }

    #[test]
    fn drift_alone_leaves_no_gear_peak() {
        let g = grid_of(|t| 0.01 * t, 4000.0);
        let mut buf = [0.0; FFT_LEN];
        let s = Spectrum::compute(&g, &mut buf).unwrap();
        // What a 1 px tone over these cells would put in its peak bin.
        let n = g.len() as f64;
        let tone = (0.5 * 0.54 * n) * (0.5 * 0.54 * n);
        let (lo, hi) = s.bins();
        for k in lo..=hi {
            assert!(s.power(k) < 1e-3 * tone, "bin {k}: {}", s.power(k));
        }
    }
}
