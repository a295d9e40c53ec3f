//! Discovery of the gear stages beyond the worm (paper sec. 3.5-3.6).
//!
//! Each new spectrum, every stage s > 0 that has no period yet searches the
//! spectrum for the strongest peak that is neither notched (a harmonic or
//! sub-harmonic of a known stage) nor commensurate with one, inside the band
//! `[4 cells, 1.2 P_0]` or around a user-supplied seed. A peak in a notch or the guard around a harmonic (or
//! multiple) of a known stage is admitted once the data spans
//! [`HARMONIC_BEATS`] beat periods against that harmonic: it is then a line
//! of its own, a gear a few percent off the worm's k-th harmonic, not the
//! harmonic itself. A found stage then follows its peak in a band around
//! its own period; its evidence gate opens with the peak's amplitude
//! relative to the worm's.

use crate::model::additions::Additions;
use crate::model::gp::grid::CELL_S;
use crate::model::numeric::scalar::Scalar;
use crate::model::spectral::fft::FFT_LEN;
use crate::model::spectral::period::PeriodTracker;
use crate::model::spectral::spectrum::{bin_period, period_bin, Peak, Spectrum, NYQUIST_BIN};

/// Half-width of a notch, relative, in frequency: the paper's 8 %. A stage
/// inside it (C5's 155 s beside the 432 s worm's 144 s division, 7 % off)
/// is admitted once the data resolves it from that harmonic
/// (`near_harmonic`).
pub const NOTCH_WIDTH: f64 = 0.08;
/// Multiples `k P` of a known period that are notched, `k = 1..=`.
pub const NOTCH_MULTIPLES: u32 = 5;
/// Divisions `P / k` of a known period that are notched, `k = 2..=`.
pub const NOTCH_DIVISIONS: u32 = 3;
/// Commensurability tolerance and the largest ratio it checks.
pub const COMMENSURATE_TOLERANCE: f64 = 0.06;
pub const COMMENSURATE_MAX_RATIO: u32 = 5;
/// The unseeded band: from 4 cells to this many worm periods.
pub const BAND_WORM_PERIODS: f64 = 1.2;
/// Half-width of the band around a seed, or around a found stage's own
/// period while it follows its peak, relative in frequency.
pub const FOLLOW_WIDTH: f64 = 0.1;
/// Beat periods of data against a harmonic `k P` or `P / k` (k >= 2) of a
/// known period from which a peak inside its notch or guard counts as a
/// line of its own. A true harmonic sits at the harmonic itself, whatever
/// the span, so it stays refused. Fewer beats would help the near-harmonic
/// cases H1-H11 more, but admit C8's 55 s line (its second stage's own
/// harmonic, 4.5 % off the worm's fifth) before the 110 s fundamental, and
/// the stage then misses it: see `docs/model.md`.
pub const HARMONIC_BEATS: f64 = 1.5;
/// A found stage moves up to twice its period where that line has at least
/// 1 / this of its own power and would open a gate on its own (the stage's
/// fundamental: a kernel of period 2P also represents P), only to periods
/// below this many worm periods. Measured on C5-C8 and the PHD2 logs: see
/// `docs/model.md`.
pub const MOVE_POWER_RATIO: f64 = 2.0;
pub const MOVE_MAX_WORM_PERIODS: f64 = 0.9;
/// Evidence gate thresholds on the smoothed amplitude ratio.
pub const GATE_OFF: f64 = 0.15;
pub const GATE_FULL: f64 = 0.35;
/// Weight of a new amplitude ratio in the smoothed one, per frame: a gate
/// opens over some 30 frames, so that one lucky spectrum does not let a
/// stage in.
pub const RATIO_SMOOTHING: f64 = 0.03;
/// The weight without the addition `convergence_gate`: the period
/// tracker's, which the ratio had before.
pub const UNGATED_RATIO_SMOOTHING: f64 = 0.1;
/// The worm's period convergence (0..=1) from which the search runs.
pub const SEARCH_MIN_CONVERGENCE: f64 = 0.3;
/// A found stage whose smoothed ratio is below this after this many frames
/// is given up and searched for again.
pub const FORGET_RATIO: f64 = 0.5 * GATE_OFF;
pub const FORGET_AFTER_FRAMES: u32 = 100;

/// A peak is a line where its power is at least this many times the
/// median of the independent bins around it. On noise alone a bin's power
/// over its mean is exponential, and the median is ln 2 of the mean: a
/// peak this far up comes from noise with a chance of e^-11 in a bin,
/// about 1 % over the few hundred independent bins a search reads.
pub const NOISE_FLOOR: f64 = 16.0;
/// Independent bins (resolutions) either side of a peak whose median is
/// its noise floor.
pub const FLOOR_RESOLUTIONS: usize = 16;

/// The evidence gate for a smoothed amplitude ratio.
pub fn gate(ratio: f64) -> f64 {
    ((ratio - GATE_OFF) / (GATE_FULL - GATE_OFF)).clamp(0.0, 1.0)
}

/// Beat periods between lines at periods `a` and `b` that `span_s` of
/// data spans: how far apart the two lie in the spectrum's resolution.
fn beats(span_s: f64, a: f64, b: f64) -> f64 {
    span_s * (1.0 / a - 1.0 / b).abs()
}

/// Whether `span_s` of data leaves a peak at `period` unresolved from the
/// `k`-th multiple or division (`harmonic`) of a known period `p` or of its
/// line `line` as measured in this spectrum. Both: a tracked period lags
/// its line, and early on a true harmonic of the line sits beats away from
/// the tracked period's harmonic (C8's 144 s, with the 288 s worm tracked
/// some percent off, was taken for a stage). The known period itself
/// (k = 1) is never resolved: a line that close to a stage's own is that
/// stage's.
fn unresolved(
    period: f64,
    (p, line): (f64, f64),
    k: u32,
    harmonic: impl Fn(f64, f64) -> f64,
    span_s: f64,
) -> bool {
    let kf = k as f64;
    let near = |centre: f64| beats(span_s, period, centre) < HARMONIC_BEATS;
    k == 1 || near(harmonic(p, kf)) || near(harmonic(line, kf))
}

fn multiple(p: f64, k: f64) -> f64 {
    p * k
}

fn division(p: f64, k: f64) -> f64 {
    p / k
}

/// Whether a peak at `period` lies in the notch ([`NOTCH_WIDTH`] either
/// side, relative) of a known period, at a multiple or division that `span_s` of
/// data does not resolve it from (span 0: any). `lines[i]` is the line of
/// `known[i]` in this spectrum.
pub fn notched(period: f64, known: &[f64], lines: &[f64], span_s: f64) -> bool {
    known.iter().zip(lines).any(|(&p, &line)| {
        let near = |k: u32, harmonic: fn(f64, f64) -> f64| {
            (harmonic(p, k as f64) / period - 1.0).abs() <= NOTCH_WIDTH
                && unresolved(period, (p, line), k, harmonic, span_s)
        };
        (1..=NOTCH_MULTIPLES).any(|k| near(k, multiple))
            || (2..=NOTCH_DIVISIONS).any(|k| near(k, division))
    })
}

/// Whether `period` is within tolerance of a small-integer multiple or
/// division of a known period that `span_s` of data does not resolve it
/// from (span 0: any). `lines` as for [`notched`].
pub fn commensurate(period: f64, known: &[f64], lines: &[f64], span_s: f64) -> bool {
    known.iter().zip(lines).any(|(&p, &line)| {
        (1..=COMMENSURATE_MAX_RATIO).any(|k| {
            let kf = k as f64;
            ((p / (kf * period) - 1.0).abs() < COMMENSURATE_TOLERANCE
                && unresolved(period, (p, line), k, division, span_s))
                || ((period / (kf * p) - 1.0).abs() < COMMENSURATE_TOLERANCE
                    && unresolved(period, (p, line), k, multiple, span_s))
        })
    })
}

/// Bins (fractional) of the band `width` either side of `period`, in
/// frequency.
fn band_bins(period: f64, width: f64) -> (f64, f64) {
    let b = period_bin(period);
    (b * (1.0 - width), b * (1.0 + width))
}

/// The strongest peak in the bins `[lo, hi]` that is a local maximum of the
/// spectrum (the strongest bin beside a notch is otherwise the skirt of the
/// notched peak's main lobe) and neither notched nor commensurate with a
/// known period, unless `span_s` of data resolves it from that harmonic
/// (`lines` as for [`notched`]).
fn strongest_peak<S: Scalar>(
    spectrum: &Spectrum<'_, S>,
    (lo, hi): (f64, f64),
    known: &[f64],
    lines: &[f64],
    span_s: f64,
    adds: &Additions,
) -> Option<Peak> {
    let lo = libm::ceil(lo.max(1.0)) as usize;
    let hi = (libm::floor(hi) as usize).min(NYQUIST_BIN);
    // No span resolves a harmonic without `near_harmonic`.
    let span_s = if adds.near_harmonic { span_s } else { 0.0 };
    // A bin must rise above the bins this far either side: its neighbours,
    // or without `local_maximum` bins outside the spectrum (power 0).
    let d = if adds.local_maximum { 1 } else { FFT_LEN };
    spectrum.strongest(lo, hi, |k| {
        let p = bin_period(k as f64);
        let power = spectrum.power(k);
        power > spectrum.power(k.saturating_sub(d))
            && power > spectrum.power(k + d)
            && !notched(p, known, lines, span_s)
            && !commensurate(p, known, lines, span_s)
    })
}

/// Whether `peak` stands [`NOISE_FLOOR`] times above the median of the
/// independent bins (one resolution apart) within [`FLOOR_RESOLUTIONS`]
/// of it, its own main lobe left out.
fn above_noise<S: Scalar>(spectrum: &Spectrum<'_, S>, peak: &Peak) -> bool {
    let (low, high) = spectrum.bins();
    let step = low.max(1);
    let centre = libm::round(period_bin(peak.period_s)) as usize;
    let bins = (2..=FLOOR_RESOLUTIONS + 1)
        .flat_map(|j| [centre.checked_sub(j * step), centre.checked_add(j * step)])
        .flatten()
        .filter(|&k| k >= low && k <= high);
    let mut around = [0.0; 2 * FLOOR_RESOLUTIONS];
    let mut n = 0;
    for (slot, k) in around.iter_mut().zip(bins) {
        *slot = spectrum.power(k);
        n += 1;
    }
    // The median by counting: 32 values, and no sort's code in the flash.
    let values = || around.iter().take(n).copied();
    let median = values().find(|&x| {
        let below = values().filter(|&y| y < x).count();
        let at = values().filter(|&y| y == x).count();
        below <= n / 2 && n / 2 < below + at
    });
    median.is_none_or(|m| peak.power >= NOISE_FLOOR * m)
}

/// The peak a found stage follows: the strongest within [`FOLLOW_WIDTH`] of
/// `period`.
fn peak_near<S: Scalar>(
    spectrum: &Spectrum<'_, S>,
    period: f64,
    known: &[f64],
    lines: &[f64],
    span_s: f64,
    adds: &Additions,
) -> Option<Peak> {
    strongest_peak(
        spectrum,
        band_bins(period, FOLLOW_WIDTH),
        known,
        lines,
        span_s,
        adds,
    )
}

/// Where a found stage's line stands against its octaves: a periodic
/// kernel of period 2P also represents a line at P (its second harmonic),
/// one of period P never a line at 2P.
struct Octaves {
    /// The stage's period and the power of its own peak (0: none).
    own: f64,
    own_power: f64,
    /// The stage may move up to its fundamental (`fundamental_move`).
    fundamental: bool,
    worm_power: f64,
    /// The periods a stage may move to.
    range: (f64, f64),
}

impl Octaves {
    /// The peak the stage moves to, if any: twice its period where that
    /// line is the stage's fundamental, a line of its own (the weakest
    /// amplitude ratio that opens a gate) with at least
    /// 1 / [`MOVE_POWER_RATIO`] of the stage's power, as C6's 155 s beside
    /// its 77.5 s harmonic (C7's weak 155 s stays below).
    fn choose<S: Scalar>(
        &self,
        spectrum: &Spectrum<'_, S>,
        known: &[f64],
        lines: &[f64],
        span_s: f64,
        adds: &Additions,
    ) -> Option<Peak> {
        if !self.fundamental {
            return None;
        }
        let up = 2.0 * self.own;
        if up < self.range.0 || up > self.range.1 {
            return None;
        }
        peak_near(spectrum, up, known, lines, span_s, adds).filter(|r| {
            r.power >= self.own_power / MOVE_POWER_RATIO
                && r.power >= GATE_OFF * GATE_OFF * self.worm_power
        })
    }
}

/// What the search knows of one stage.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct StageSearch {
    /// The stage has a period (found, or seeded and found near the seed).
    found: bool,
    /// Its peak in the current spectrum, if any.
    peak_period_s: Option<f64>,
    /// Amplitude of that peak relative to the worm's.
    ratio_now: f64,
    /// Smoothed ratio, which drives the gate.
    ratio: f64,
    /// Frames since the stage was found.
    frames_found: u32,
}

/// Search state of the stages; index 0 (the worm) is unused.
pub struct Discovery<const N: usize> {
    stages: [StageSearch; N],
    seeds: [Option<f64>; N],
}

/// The spans of data, s, that resolve a spectrum's lines from each other
/// (a stage beside another's harmonic is admitted once they do).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spans {
    /// For a found stage following its own line: the grid's span.
    pub own_s: f64,
    /// For a new stage and a stage's move to another line: the grid's
    /// span, or with `one_piece` the data learned since a placement (a
    /// line across it shows as a split peak, no stage of its own).
    pub new_s: f64,
}

impl Spans {
    /// One span for every line.
    pub const fn whole(span_s: f64) -> Self {
        Self {
            own_s: span_s,
            new_s: span_s,
        }
    }
}

impl<const N: usize> Discovery<N> {
    /// `seeds[s]`: the user's estimate of stage s's period, if any.
    pub fn new(seeds: [Option<f64>; N]) -> Self {
        Self {
            stages: [StageSearch::default(); N],
            seeds,
        }
    }

    pub fn clear(&mut self) {
        self.stages = [StageSearch::default(); N];
    }

    /// Smoothed amplitude ratio of a stage.
    pub fn ratio(&self, stage: usize) -> f64 {
        self.stages.get(stage).map_or(0.0, |s| s.ratio)
    }

    /// What a snapshot keeps of stage `s`: whether it was found, its
    /// smoothed amplitude ratio and the frames since it was found.
    pub fn saved(&self, s: usize) -> (bool, f64, u32) {
        self.stages
            .get(s)
            .map_or((false, 0.0, 0), |st| (st.found, st.ratio, st.frames_found))
    }

    /// Take stage `s` back from a snapshot; its peak is looked for again in
    /// the next spectrum.
    pub fn restore(&mut self, s: usize, found: bool, ratio: f64, frames_found: u32) {
        if let Some(st) = self.stages.get_mut(s) {
            *st = StageSearch {
                found,
                ratio,
                frames_found,
                ..StageSearch::default()
            };
        }
    }

    /// Read a new spectrum: find or follow every stage's peak.
    /// `worm` is the worm's peak (the strongest) in it, `spans` the data
    /// that resolves its lines; `adds` switches the additions of the
    /// search.
    pub fn scan<S: Scalar>(
        &mut self,
        spectrum: &Spectrum<'_, S>,
        trackers: &mut [PeriodTracker; N],
        worm: Option<Peak>,
        spans: Spans,
        adds: &Additions,
    ) {
        // The notches and the guard stand around the worm's period: while
        // that is still far from its spectral estimate there is nothing to
        // place them by, and what the search finds is noise (log 04).
        if adds.convergence_gate && trackers[0].convergence() < SEARCH_MIN_CONVERGENCE {
            for stage in &mut self.stages {
                stage.peak_period_s = None;
                stage.ratio_now = 0.0;
            }
            return;
        }
        let worm_power = worm.map_or(0.0, |p| p.power);
        let worm_line = worm.map_or(trackers[0].period_s, |p| p.period_s);
        for s in 1..N {
            // A found stage follows its line past the stages after it that
            // carry no weight yet: with three stages, an ungated third
            // stage wandering over noise peaks otherwise notches the
            // second's line and closes its gate (C6, docs/model.md).
            let following = adds.follow_past && self.stages[s].found;
            let mut known = [0.0; N];
            let mut lines = [0.0; N];
            let mut n_known = 0;
            for (k, t) in trackers.iter().enumerate() {
                let stage = &self.stages[k];
                let weighs = k < s || !following || stage.ratio >= GATE_OFF;
                if k != s && (k == 0 || (stage.found && weighs)) {
                    known[n_known] = t.period_s;
                    lines[n_known] = if k == 0 {
                        worm_line
                    } else {
                        stage.peak_period_s.unwrap_or(t.period_s)
                    };
                    n_known += 1;
                }
            }
            let known = &known[..n_known];
            let lines = &lines[..n_known];
            let stage = &mut self.stages[s];
            stage.peak_period_s = None;
            stage.ratio_now = 0.0;
            if !(worm_power > 0.0) {
                continue;
            }
            let band_lo = 4.0 * CELL_S;
            let band_hi = BAND_WORM_PERIODS * trackers[0].period_s;
            let peak = if stage.found && adds.follow_band {
                let own = trackers[s].period_s;
                let mut peak = peak_near(spectrum, own, known, lines, spans.own_s, adds);
                let octaves = Octaves {
                    own,
                    own_power: peak.map_or(0.0, |p| p.power),
                    fundamental: adds.fundamental_move,
                    worm_power,
                    range: (band_lo, MOVE_MAX_WORM_PERIODS * trackers[0].period_s),
                };
                if let Some(r) = octaves.choose(spectrum, known, lines, spans.new_s, adds) {
                    peak = Some(r);
                    trackers[s] = PeriodTracker {
                        period_s: r.period_s,
                        ..trackers[s]
                    };
                }
                peak
            } else {
                let band = match self.seeds[s] {
                    Some(p) => band_bins(p, FOLLOW_WIDTH),
                    None => (period_bin(band_hi), period_bin(band_lo)),
                };
                strongest_peak(spectrum, band, known, lines, spans.new_s, adds)
            };
            let Some(peak) = peak else { continue };
            if adds.noise_floor && !above_noise(spectrum, &peak) {
                continue;
            }
            if !stage.found {
                stage.found = true;
                trackers[s] = PeriodTracker::new(peak.period_s);
            }
            stage.peak_period_s = Some(peak.period_s);
            stage.ratio_now = libm::sqrt(peak.power / worm_power);
        }
    }

    /// Once per frame: follow the peaks found by the last scan.
    pub fn step(
        &mut self,
        trackers: &mut [PeriodTracker; N],
        gates: &mut [f64; N],
        adds: &Additions,
    ) {
        let w = if adds.convergence_gate {
            RATIO_SMOOTHING
        } else {
            UNGATED_RATIO_SMOOTHING
        };
        for s in 1..N {
            let stage = &mut self.stages[s];
            stage.ratio = (1.0 - w) * stage.ratio + w * stage.ratio_now;
            if let Some(p) = stage.peak_period_s {
                trackers[s].observe(p);
            }
            if stage.found {
                stage.frames_found = stage.frames_found.saturating_add(1);
                // A peak that has faded (or was never more than a skirt) is
                // given up, so that the search can find the real one.
                if adds.drop_faded
                    && stage.frames_found > FORGET_AFTER_FRAMES
                    && stage.ratio < FORGET_RATIO
                {
                    *stage = StageSearch::default();
                }
            }
            gates[s] = if stage.found { gate(stage.ratio) } else { 0.0 };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn notches_cover_harmonics_and_divisions() {
        let known = [432.0];
        // C5's second stage, 7 % from the worm's 144 s division, lies in the
        // notch until the data resolves the two (`near_harmonic`).
        for p in [432.0, 864.0, 2160.0, 216.0, 144.0, 420.0, 150.0, 155.0] {
            assert!(notched(p, &known, &known, 0.0), "{p}");
        }
        let beat = 1.0 / (1.0 / 144.0 - 1.0 / 155.0);
        assert!(!notched(155.0, &known, &known, 1.1 * HARMONIC_BEATS * beat));
        for p in [380.0, 288.0, 110.0, 108.0] {
            assert!(!notched(p, &known, &known, 0.0), "{p}");
        }
    }

    #[test]
    fn guard_refuses_commensurate_periods() {
        // C4: 108 s is the worm's fourth harmonic.
        assert!(commensurate(108.0, &[432.0], &[432.0], 0.0));
        // The paper's limitation case: 150 s against 288 s is within 4 % of 2:1.
        assert!(commensurate(150.0, &[288.0], &[288.0], 0.0));
        for p in [380.0, 288.0, 155.0] {
            assert!(!commensurate(p, &[432.0], &[432.0], 0.0), "{p}");
        }
        assert!(!commensurate(110.0, &[288.0], &[288.0], 0.0));
    }

    #[test]
    fn near_harmonic_admitted_once_the_span_resolves_it() {
        // H1: a gear 5 % off the 432 s worm's second harmonic (216 s) beats
        // with it at 4,320 s.
        let (period, worm) = (205.7, [432.0]);
        let beat = 1.0 / (1.0 / period - 2.0 / 432.0);
        let before = 0.9 * HARMONIC_BEATS * beat;
        let after = 1.1 * HARMONIC_BEATS * beat;
        assert!(
            notched(period, &worm, &worm, before) && commensurate(period, &worm, &worm, before)
        );
        assert!(
            !notched(period, &worm, &worm, after) && !commensurate(period, &worm, &worm, after)
        );
        // Near the third and fourth harmonics, either side.
        for (period, k) in [(139.8, 3.0), (151.6, 3.0), (105.9, 4.0), (112.5, 4.0)] {
            let beat = 1.0 / (1.0 / period - k / 432.0).abs();
            let before = 0.9 * HARMONIC_BEATS * beat;
            let after = 1.1 * HARMONIC_BEATS * beat;
            assert!(commensurate(period, &worm, &worm, before), "{period}");
            assert!(!notched(period, &worm, &worm, after), "{period}");
            assert!(!commensurate(period, &worm, &worm, after), "{period}");
        }
        // A multiple of a known stage (a slower stage 3 % off twice a 110 s
        // one) likewise.
        let beat = 1.0 / (1.0 / 220.0 - 1.0 / 226.6);
        assert!(commensurate(
            226.6,
            &[110.0],
            &[110.0],
            0.9 * HARMONIC_BEATS * beat
        ));
        assert!(!commensurate(
            226.6,
            &[110.0],
            &[110.0],
            1.1 * HARMONIC_BEATS * beat
        ));
    }

    #[test]
    fn exact_harmonics_refused_whatever_the_span() {
        for span in [0.0, 1e4, 1e6, 1e9] {
            for k in 2..=5 {
                let p = 432.0 / k as f64;
                assert!(commensurate(p, &[432.0], &[432.0], span), "{k} {span}");
            }
            for k in 2..=3 {
                assert!(
                    notched(432.0 / k as f64, &[432.0], &[432.0], span),
                    "{k} {span}"
                );
            }
            // 0.1 % off (a worm period tracked that closely) needs more
            // data than the grid holds (10,240 s).
            assert!(commensurate(432.0 / 4.0 * 1.001, &[432.0], &[432.0], 1e4));
            // A worm tracked 4 % long (300 s for 288 s) still bars its true
            // second harmonic, by its line in the spectrum.
            assert!(commensurate(144.0, &[300.0], &[288.0], span), "{span}");
            assert!(notched(144.0, &[300.0], &[288.0], span), "{span}");
            // The known period itself, and 5 % beside it, whatever the span.
            assert!(
                notched(432.0, &[432.0], &[432.0], span)
                    && commensurate(432.0, &[432.0], &[432.0], span)
            );
            assert!(commensurate(411.4, &[432.0], &[432.0], span));
        }
    }

    /// `g` sampled every 2 s over `span` s.
    fn sampled(g: impl Fn(f64) -> f64, span: f64) -> crate::model::gp::grid::Grid<f64> {
        let mut grid =
            crate::model::gp::grid::Grid::new(crate::model::gp::grid::Averaging::Reference);
        let mut t = 0.0;
        while t < span {
            grid.push(t, g(t), 1.0);
            t += 2.0;
        }
        grid
    }

    /// The second stage's period after one scan of `g` sampled over
    /// `span` s, with the worm tracked at 432 s; None if none was found.
    fn second_stage(g: impl Fn(f64) -> f64, span: f64) -> Option<f64> {
        use crate::model::spectral::spectrum::Spectrum;
        let grid = sampled(g, span);
        let mut buf = [0.0; crate::model::spectral::fft::FFT_LEN];
        let spectrum = Spectrum::compute(&grid, &mut buf)?;
        let worm = spectrum.strongest(0, NYQUIST_BIN, |_| true)?;
        let mut trackers = [PeriodTracker::new(432.0); 2];
        trackers[0].disagreement = 0.0;
        let mut d: Discovery<2> = Discovery::new([None, None]);
        let span = grid.len() as f64 * CELL_S;
        d.scan(
            &spectrum,
            &mut trackers,
            Some(worm),
            Spans::whole(span),
            &Additions::ALL,
        );
        d.saved(1).0.then_some(trackers[1].period_s)
    }

    /// H2: a 432 s worm with a true second harmonic (216 s) and a gear 5 %
    /// off it (205.7 s), beat 4,320 s.
    fn h2(t: f64) -> f64 {
        let pi2 = 2.0 * core::f64::consts::PI;
        9.0 * libm::sin(pi2 * t / 432.0)
            + 3.0 * libm::sin(pi2 * t / 216.0)
            + 4.5 * libm::sin(pi2 * t / 205.7)
    }

    #[test]
    fn scan_admits_a_near_harmonic_stage_beside_a_true_harmonic() {
        // Two beats: found at its own period, not at the harmonic's.
        let late = second_stage(h2, 8640.0).unwrap();
        assert!((late - 205.7).abs() < 1.5, "{late}");
        // Half a beat: the two lines are one lobe, in the notch, refused
        // (what is found, if anything, lies elsewhere).
        let early = second_stage(h2, 0.5 * 4320.0);
        assert!(
            early.is_none_or(|p| (p / 216.0 - 1.0).abs() > NOTCH_WIDTH),
            "{early:?}"
        );
    }

    #[test]
    fn a_new_line_needs_the_new_span_a_found_stage_keeps_its_own() {
        // H2 over two beats, as after a placement 1,000 s ago (`one_piece`).
        use crate::model::spectral::spectrum::Spectrum;
        let grid = sampled(h2, 8640.0);
        let mut buf = [0.0; crate::model::spectral::fft::FFT_LEN];
        let spectrum = Spectrum::compute(&grid, &mut buf).unwrap();
        let worm = spectrum.strongest(0, NYQUIST_BIN, |_| true);
        let grid_s = grid.len() as f64 * CELL_S;
        let placed = Spans {
            own_s: grid_s,
            new_s: 1000.0,
        };
        let scan = |d: &mut Discovery<2>, trackers: &mut [PeriodTracker; 2], spans| {
            d.scan(&spectrum, trackers, worm, spans, &Additions::ALL)
        };
        let mut trackers = [PeriodTracker::new(432.0); 2];
        trackers[0].disagreement = 0.0;
        // A new stage beside the harmonic: refused until the data since
        // the placement resolves it.
        let mut fresh: Discovery<2> = Discovery::new([None, None]);
        scan(&mut fresh, &mut trackers, placed);
        let line = fresh.stages[1].peak_period_s;
        assert!(line.is_none_or(|p| (p - 205.7).abs() > 5.0), "{line:?}");
        // A stage found before the placement follows its own line.
        let mut trackers = [PeriodTracker::new(432.0); 2];
        trackers[0].disagreement = 0.0;
        let mut found: Discovery<2> = Discovery::new([None, None]);
        scan(&mut found, &mut trackers, Spans::whole(grid_s));
        scan(&mut found, &mut trackers, placed);
        let line = found.stages[1].peak_period_s;
        assert!(line.is_some_and(|p| (p - 205.7).abs() < 1.5), "{line:?}");
    }

    #[test]
    fn scan_never_admits_a_true_harmonic() {
        // H11: a worm with true 2nd-4th harmonics and nothing else; the
        // grid's longest span.
        let pi2 = 2.0 * core::f64::consts::PI;
        let g = |t: f64| {
            9.0 * libm::sin(pi2 * t / 432.0)
                + 6.0 * libm::sin(pi2 * t / 216.0 + 1.0)
                + 3.0 * libm::sin(pi2 * t / 144.0 + 2.0)
                + 1.5 * libm::sin(pi2 * t / 108.0)
        };
        for span in [2000.0, 5000.0, 10240.0] {
            let found = second_stage(g, span);
            assert!(
                found.is_none_or(|p| (2..=5).all(|k| (p * k as f64 / 432.0 - 1.0).abs() > 0.02)),
                "{span}: {found:?}"
            );
        }
    }

    #[test]
    fn scan_finds_the_second_stage_of_a_known_spectrum() {
        use crate::model::spectral::spectrum::Spectrum;
        // C8's two stages, each with its second harmonic.
        let pi2 = 2.0 * core::f64::consts::PI;
        let g = |t: f64| {
            9.0 * libm::sin(pi2 * t / 288.0)
                + 6.0 * libm::sin(pi2 * t / 144.0)
                + 4.5 * libm::sin(pi2 * t / 110.0)
                + 3.6 * libm::sin(pi2 * t / 55.0)
        };
        let grid = sampled(g, 4000.0);
        let mut buf = [0.0; crate::model::spectral::fft::FFT_LEN];
        let spectrum = Spectrum::compute(&grid, &mut buf).unwrap();
        let worm = spectrum.strongest(0, NYQUIST_BIN, |_| true).unwrap();
        assert!((worm.period_s - 288.0).abs() < 3.0, "{worm:?}");
        let mut trackers = [PeriodTracker::new(worm.period_s); 2];
        trackers[0].disagreement = 0.0;
        let mut gates = [1.0, 0.0];
        let mut d: Discovery<2> = Discovery::new([None, None]);
        d.scan(
            &spectrum,
            &mut trackers,
            Some(worm),
            Spans::whole(grid.len() as f64 * CELL_S),
            &Additions::ALL,
        );
        // The 144 s harmonic is notched; the strongest admissible peak is
        // the second stage's fundamental.
        assert!(
            (trackers[1].period_s - 110.0).abs() < 1.5,
            "{:?}",
            trackers[1]
        );
        for _ in 0..200 {
            d.step(&mut trackers, &mut gates, &Additions::ALL);
        }
        // Amplitude ratio 4.5 / 9: the gate opens fully.
        assert!(d.ratio(1) > GATE_FULL, "{}", d.ratio(1));
        assert_eq!(gates[1], 1.0);
        // With the worm still unsettled nothing is searched.
        let mut fresh: Discovery<2> = Discovery::new([None, None]);
        let mut unsettled = [PeriodTracker::new(300.0); 2];
        fresh.scan(
            &spectrum,
            &mut unsettled,
            Some(worm),
            Spans::whole(4000.0),
            &Additions::ALL,
        );
        fresh.step(&mut unsettled, &mut gates, &Additions::ALL);
        assert_eq!(gates[1], 0.0);
    }

    /// The second stage's period after a scan that finds it near a seed
    /// and one more that follows it, on 4,000 s of `g` with the worm
    /// tracked at 432 s.
    fn followed_stage(g: impl Fn(f64) -> f64, seed: f64) -> f64 {
        use crate::model::spectral::spectrum::Spectrum;
        let grid = sampled(g, 4000.0);
        let mut buf = [0.0; crate::model::spectral::fft::FFT_LEN];
        let spectrum = Spectrum::compute(&grid, &mut buf).unwrap();
        let worm = spectrum.strongest(0, NYQUIST_BIN, |_| true);
        let mut trackers = [PeriodTracker::new(432.0); 2];
        trackers[0].disagreement = 0.0;
        let mut d: Discovery<2> = Discovery::new([None, Some(seed)]);
        let spans = Spans::whole(grid.len() as f64 * CELL_S);
        d.scan(&spectrum, &mut trackers, worm, spans, &Additions::ALL);
        assert!((trackers[1].period_s - seed).abs() < 1.5, "{trackers:?}");
        d.scan(&spectrum, &mut trackers, worm, spans, &Additions::ALL);
        trackers[1].period_s
    }

    #[test]
    fn a_stage_moves_up_to_its_fundamental() {
        let pi2 = 2.0 * core::f64::consts::PI;
        // (worm's second harmonic, stage, stage's second harmonic): C6's
        // 155 s line carries more than half its harmonic's power, C7's a
        // quarter.
        for (h2, fundamental, harmonic, want) in [(6.0, 4.5, 3.6, 155.0), (3.0, 2.4, 4.8, 77.5)] {
            let g = |t: f64| {
                9.0 * libm::sin(pi2 * t / 432.0)
                    + h2 * libm::sin(pi2 * t / 216.0)
                    + fundamental * libm::sin(pi2 * t / 155.0)
                    + harmonic * libm::sin(pi2 * t / 77.5)
            };
            let got = followed_stage(g, 77.5);
            assert!((got - want).abs() < 1.5, "{fundamental}: {got}");
        }
        // A stage found at its fundamental stays there.
        let g = |t: f64| {
            9.0 * libm::sin(pi2 * t / 432.0)
                + 4.5 * libm::sin(pi2 * t / 155.0)
                + 3.6 * libm::sin(pi2 * t / 77.5)
        };
        let got = followed_stage(g, 155.0);
        assert!((got - 155.0).abs() < 1.5, "{got}");
    }

    /// The additions as the firmware runs them, but `name` off.
    fn without(name: &str) -> Additions {
        let mut adds = Additions::ALL;
        adds.set(name, false).unwrap();
        adds
    }

    /// A scripted spectrum: the worm's line at bin 40 (512 s) with power
    /// 10,000 and each `(bin, power)` a line, every line's neighbours at
    /// half its power (its parabola's vertex on the bin itself).
    fn lines(at: &[(usize, f64)]) -> [f64; crate::model::spectral::fft::FFT_LEN] {
        let mut buf = [0.0; crate::model::spectral::fft::FFT_LEN];
        for &(k, power) in [(40, 1e4)].iter().chain(at) {
            buf[k] = power;
            buf[k - 1] = 0.5 * power;
            buf[k + 1] = 0.5 * power;
        }
        buf
    }

    /// The worm tracked at 512 s and converged; the other stages at
    /// `periods`.
    fn tracked<const N: usize>(periods: [f64; N]) -> [PeriodTracker; N] {
        let mut trackers = periods.map(PeriodTracker::new);
        trackers[0] = PeriodTracker::new(bin_period(40.0));
        trackers[0].disagreement = 0.0;
        trackers
    }

    /// One scan of `buf` over `span_s` s of data.
    fn scan_scripted<const N: usize>(
        d: &mut Discovery<N>,
        trackers: &mut [PeriodTracker; N],
        buf: &[f64; crate::model::spectral::fft::FFT_LEN],
        span_s: f64,
        adds: &Additions,
    ) {
        use crate::model::spectral::spectrum::Spectrum;
        let spectrum = Spectrum::scripted(buf);
        let worm = spectrum.strongest(0, NYQUIST_BIN, |_| true);
        d.scan(&spectrum, trackers, worm, Spans::whole(span_s), adds);
    }

    /// The period a fresh search finds for stage 1, if any.
    fn found(
        buf: &[f64; crate::model::spectral::fft::FFT_LEN],
        mut trackers: [PeriodTracker; 2],
        span_s: f64,
        adds: &Additions,
    ) -> Option<f64> {
        let mut d: Discovery<2> = Discovery::new([None, None]);
        scan_scripted(&mut d, &mut trackers, buf, span_s, adds);
        d.saved(1).0.then_some(trackers[1].period_s)
    }

    #[test]
    fn without_local_maximum_the_skirt_of_a_notched_line_is_a_stage() {
        // The worm tracked at 500 s notches its line's bins up to 44; the
        // skirt falls on through 45 (455 s), resolved from the worm.
        let mut buf = lines(&[]);
        for (k, power) in [(42, 2500.0), (43, 1500.0), (44, 1000.0), (45, 500.0)] {
            buf[k] = power;
        }
        let mut trackers = tracked([0.0; 2]);
        trackers[0].period_s = 500.0;
        assert_eq!(found(&buf, trackers, 10240.0, &Additions::ALL), None);
        assert_eq!(
            found(&buf, trackers, 10240.0, &without("local_maximum")),
            Some(bin_period(45.0))
        );
    }

    #[test]
    fn without_noise_floor_a_line_in_the_noise_is_a_stage() {
        // Noise of power 100 in every bin; a line at bin 112 of 10 and of
        // 20 times that (amplitude ratios 0.32 and 0.45 to the worm's).
        for (power, with, without_floor) in [
            (1000.0, None, Some(112.0)),
            (2000.0, Some(112.0), Some(112.0)),
        ] {
            let mut buf = [100.0; crate::model::spectral::fft::FFT_LEN];
            let line = lines(&[(112, power)]);
            for (b, l) in buf.iter_mut().zip(&line) {
                *b = b.max(*l);
            }
            let trackers = tracked([0.0; 2]);
            let want = |bin: Option<f64>| bin.map(bin_period);
            assert_eq!(
                found(&buf, trackers, 10240.0, &Additions::ALL),
                want(with),
                "{power}"
            );
            assert_eq!(
                found(&buf, trackers, 10240.0, &without("noise_floor")),
                want(without_floor),
                "{power}"
            );
        }
    }

    #[test]
    fn without_drop_faded_a_faded_stage_is_kept() {
        for (adds, kept) in [(Additions::ALL, false), (without("drop_faded"), true)] {
            let mut d: Discovery<2> = Discovery::new([None, None]);
            d.restore(1, true, 0.0, 0);
            let mut trackers = tracked([0.0, 182.0]);
            let mut gates = [1.0, 0.0];
            for _ in 0..FORGET_AFTER_FRAMES {
                d.step(&mut trackers, &mut gates, &adds);
            }
            assert_eq!(d.saved(1), (true, 0.0, FORGET_AFTER_FRAMES));
            d.step(&mut trackers, &mut gates, &adds);
            let frames = if kept { FORGET_AFTER_FRAMES + 1 } else { 0 };
            assert_eq!(d.saved(1), (kept, 0.0, frames));
        }
    }

    #[test]
    fn without_convergence_gate_an_unsettled_worm_lets_the_search_run() {
        // A line of amplitude ratio 0.5 to the worm's.
        let buf = lines(&[(112, 2500.0)]);
        let step_once = |trackers: &mut [PeriodTracker; 2], adds: &Additions| {
            let mut d: Discovery<2> = Discovery::new([None, None]);
            scan_scripted(&mut d, trackers, &buf, 10240.0, adds);
            d.step(trackers, &mut [1.0, 0.0], adds);
            (d.saved(1).0, d.ratio(1))
        };
        let mut unsettled = [PeriodTracker::new(bin_period(40.0)); 2];
        assert_eq!(step_once(&mut unsettled, &Additions::ALL), (false, 0.0));
        let off = without("convergence_gate");
        assert_eq!(
            step_once(&mut unsettled, &off),
            (true, UNGATED_RATIO_SMOOTHING * 0.5)
        );
        // Settled, the search runs either way; the ratio is smoothed more.
        let mut settled = tracked([0.0; 2]);
        assert_eq!(
            step_once(&mut settled, &Additions::ALL),
            (true, RATIO_SMOOTHING * 0.5)
        );
    }

    #[test]
    fn without_near_harmonic_a_resolved_line_in_a_notch_is_refused() {
        // 176.6 s, 3.4 % from the worm's third division: two beats in
        // 10,240 s.
        let buf = lines(&[(116, 2500.0)]);
        let trackers = tracked([0.0; 2]);
        assert_eq!(
            found(&buf, trackers, 10240.0, &Additions::ALL),
            Some(bin_period(116.0))
        );
        assert_eq!(
            found(&buf, trackers, 10240.0, &without("near_harmonic")),
            None
        );
    }

    /// Stage 1's period and peak after one scan of `buf`, the stage found
    /// at 182.9 s (bin 112) with smoothed amplitude ratio `ratio`.
    fn followed(
        buf: &[f64; crate::model::spectral::fft::FFT_LEN],
        ratio: f64,
        adds: &Additions,
    ) -> (f64, Option<f64>) {
        let mut d: Discovery<2> = Discovery::new([None, None]);
        d.restore(1, true, ratio, 0);
        let mut trackers = tracked([0.0, bin_period(112.0)]);
        scan_scripted(&mut d, &mut trackers, buf, 10240.0, adds);
        (trackers[1].period_s, d.stages[1].peak_period_s)
    }

    #[test]
    fn without_fundamental_move_a_stage_stays_on_its_harmonic() {
        // A fully gated stage; its fundamental has 3/4 of its power.
        let buf = lines(&[(112, 400.0), (56, 300.0)]);
        let (own, fundamental) = (bin_period(112.0), bin_period(56.0));
        assert_eq!(
            followed(&buf, 0.5, &Additions::ALL),
            (fundamental, Some(fundamental))
        );
        assert_eq!(
            followed(&buf, 0.5, &without("fundamental_move")),
            (own, Some(own))
        );
    }

    #[test]
    fn without_follow_band_a_stage_takes_the_strongest_line() {
        // A stronger line at 113.8 s, far from the stage's own.
        let buf = lines(&[(112, 400.0), (180, 1600.0)]);
        let own = bin_period(112.0);
        assert_eq!(followed(&buf, 0.5, &Additions::ALL), (own, Some(own)));
        assert_eq!(
            followed(&buf, 0.5, &without("follow_band")),
            (own, Some(bin_period(180.0)))
        );
    }

    #[test]
    fn without_follow_past_an_ungated_later_stage_notches_a_line() {
        // Stage 2, ungated, at twice stage 1's period.
        let buf = lines(&[(112, 400.0)]);
        let peak = |adds: &Additions| {
            let mut d: Discovery<3> = Discovery::new([None; 3]);
            d.restore(1, true, 0.5, 0);
            d.restore(2, true, 0.0, 0);
            let mut trackers = tracked([0.0, bin_period(112.0), bin_period(56.0)]);
            scan_scripted(&mut d, &mut trackers, &buf, 10240.0, adds);
            d.stages[1].peak_period_s
        };
        assert_eq!(peak(&Additions::ALL), Some(bin_period(112.0)));
        assert_eq!(peak(&without("follow_past")), None);
    }

    #[test]
    fn gate_is_linear_between_thresholds() {
        assert_eq!(gate(0.1), 0.0);
        assert_eq!(gate(0.5), 1.0);
        assert!((gate(0.25) - 0.5).abs() < 1e-12);
    }
}
