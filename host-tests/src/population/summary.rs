//! The population's summary: per noise level, each model's ratio to the
//! loop's own baseline (the reactive guider in the model's loop, the
//! guider alone in the firmware's) over the mounts: median, 90th
//! percentile, worst, and how many mounts it is worse on (ratio above 1
//! by more than a tie, [`TIE`]).

use super::Row;

/// Which noise rows a summary line covers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Level {
    NoiseFree,
    /// The mount's seeing.
    Seeing,
}

impl Level {
    pub fn name(self) -> &'static str {
        match self {
            Level::NoiseFree => "0",
            Level::Seeing => "seeing",
        }
    }

    fn holds(self, row: &Row) -> bool {
        (row.noise_px > 0.0) == (self == Level::Seeing)
    }
}

/// Ratios within this of 1 are ties, not worse: a millionth of the RMS
/// is, on these mounts, less than a ten-thousandth of a microstep (0.094
/// arcsec), no difference in guiding. A firmware whose feed-forward is
/// switched off guides as the guider alone, but from where the first hour
/// left its steps: the RMS moves by about that much either way.
pub const TIE: f64 = 1e-6;

/// Whether a ratio to the baseline is worse than it (beyond a tie).
pub fn worse(ratio: f64) -> bool {
    ratio > 1.0 + TIE
}

/// A column over its loop's baseline.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ratio {
    MkgpToReactive,
    PpecToReactive,
    FwMkgpToGuiderOnly,
    FwPpecToGuiderOnly,
}

impl Ratio {
    pub const ALL: [Ratio; 4] = [
        Ratio::MkgpToReactive,
        Ratio::PpecToReactive,
        Ratio::FwMkgpToGuiderOnly,
        Ratio::FwPpecToGuiderOnly,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Ratio::MkgpToReactive => "mkgp/reactive",
            Ratio::PpecToReactive => "ppec/reactive",
            Ratio::FwMkgpToGuiderOnly => "fw_mkgp/guider_only",
            Ratio::FwPpecToGuiderOnly => "fw_ppec/guider_only",
        }
    }

    pub fn of(self, r: &Row) -> f64 {
        match self {
            Ratio::MkgpToReactive => r.mkgp / r.reactive,
            Ratio::PpecToReactive => r.ppec / r.reactive,
            Ratio::FwMkgpToGuiderOnly => r.fw_mkgp / r.guider_only,
            Ratio::FwPpecToGuiderOnly => r.fw_ppec / r.guider_only,
        }
    }
}

/// A ratio's order statistics over the mounts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stats {
    pub mounts: usize,
    pub median: f64,
    /// Nearest rank: the smallest ratio at least 90 % of the mounts reach.
    pub p90: f64,
    pub worst: f64,
    pub worst_mount: usize,
    /// Mounts on which the ratio is above 1 by more than a tie.
    pub worse: usize,
}

impl Stats {
    /// Over `(ratio, mount)` pairs; `None` if there are none.
    pub fn of(mut x: Vec<(f64, usize)>) -> Option<Stats> {
        x.sort_by(|a, b| a.0.total_cmp(&b.0));
        let n = x.len();
        let (worst, worst_mount) = *x.last()?;
        Some(Stats {
            mounts: n,
            median: median_of_sorted(&x),
            p90: x[(n * 9).div_ceil(10) - 1].0,
            worst,
            worst_mount,
            worse: x.iter().filter(|(v, _)| worse(*v)).count(),
        })
    }
}

/// The median of a non-empty list sorted by its first member.
fn median_of_sorted(x: &[(f64, usize)]) -> f64 {
    let n = x.len();
    if n % 2 == 1 {
        x[n / 2].0
    } else {
        (x[n / 2 - 1].0 + x[n / 2].0) / 2.0
    }
}

/// One ratio at one level over the mounts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Line {
    pub level: Level,
    pub ratio: Ratio,
    pub stats: Stats,
}

pub const CSV_HEADER: &str = "noise,ratio,mounts,median,p90,worst,worst_mount,worse";

impl Line {
    pub fn csv(&self) -> String {
        let s = &self.stats;
        format!(
            "{},{},{},{:.3},{:.3},{:.3},{},{}",
            self.level.name(),
            self.ratio.name(),
            s.mounts,
            s.median,
            s.p90,
            s.worst,
            s.worst_mount,
            s.worse
        )
    }
}

/// A line per level and ratio (none for a level without rows).
pub fn summarize(rows: &[Row]) -> Vec<Line> {
    let mut lines = Vec::new();
    for level in [Level::NoiseFree, Level::Seeing] {
        let at: Vec<&Row> = rows.iter().filter(|r| level.holds(r)).collect();
        for ratio in Ratio::ALL {
            let x = at.iter().map(|r| (ratio.of(r), r.mount)).collect();
            if let Some(stats) = Stats::of(x) {
                lines.push(Line {
                    level,
                    ratio,
                    stats,
                });
            }
        }
    }
    lines
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(mount: usize, noise_px: f64, mkgp: f64) -> Row {
        Row {
            mount,
            noise_px,
            open_loop: 5.0,
            reactive: 1.0,
            ppec: 1.0,
            mkgp,
            guider_only: 2.0,
            fw_ppec: 1.0,
            fw_mkgp: 1.0,
        }
    }

    #[test]
    fn order_statistics() {
        let rows: Vec<Row> = (1..=10)
            .map(|k| row(k, 0.0, k as f64 / 8.0))
            .chain([row(1, 0.7, 0.5)])
            .collect();
        let lines = summarize(&rows);
        assert_eq!(lines.len(), 8);
        let (l, s) = (lines[0], lines[0].stats);
        assert_eq!(
            (l.level, l.ratio, s.mounts),
            (Level::NoiseFree, Ratio::MkgpToReactive, 10)
        );
        assert_eq!(s.median, 5.5 / 8.0);
        assert_eq!(s.p90, 9.0 / 8.0);
        assert_eq!((s.worst, s.worst_mount, s.worse), (10.0 / 8.0, 10, 2));
        let fw = lines[2].stats;
        assert_eq!((fw.median, fw.worse), (0.5, 0));
        // A tie is not worse; a hair beyond it is.
        let tie = |by: f64| {
            let r = [row(1, 0.0, 1.0 + by)];
            summarize(&r)[0].stats.worse
        };
        assert_eq!((tie(0.0), tie(TIE / 2.0), tie(2.0 * TIE)), (0, 0, 1));
        let seeing = lines[4];
        assert_eq!(
            (seeing.level, seeing.stats.mounts, seeing.stats.median),
            (Level::Seeing, 1, 0.5)
        );
    }
}
