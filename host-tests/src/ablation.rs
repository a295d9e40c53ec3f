//! What each addition around the paper's model is worth (`guide-sim
//! ablate`, issue 28 item 2): the population, the paper's cases and the
//! PHD2 logs run with every addition on, then with each one switched off
//! in turn (`mkgp_mount::model::additions`).
//!
//! An addition is measured in the loop it acts in ([`Acts`]): the
//! learner's, the loop's fast part's, `exact_cells` and `noise_floor` in the firmware's (as
//! `guide-sim st4`: fw MKGP over the guider alone), the restore's, the
//! saved share and the trusted gate across a power cycle (as `guide-sim
//! nights`, the gear moved while off: night 2's first 30 minutes restored,
//! the mean of without and with the index, over the same cold;
//! `placement_search` acts on a known
//! phase out of range, which a re-pointing through the port gives and
//! these nights do not: `guide-sim night` measures it), the model's in
//! the model's (as `guide-sim table`: the model over the reactive guider),
//! all with the firmware's stages ([`MODEL`]). The baselines do not run
//! the model (or, across the power cycle, restore none), so they run once.
//!
//! To keep a run within the hour on a 2-core machine, each mount runs
//! noise-free and at its seeing with its first run seed only (the
//! population's rows average three at the seeing). The paper's cases run
//! as their tables do (0 and 1 px, seeds 1-3).
//!
//! Worth is the change switching the addition off makes: its median and
//! worst ratio over the mounts less those with all on (positive: the
//! addition pays). The spread beside each is the standard deviation of
//! that change over [`RESAMPLES`] redraws of the mounts with replacement
//! (the bootstrap): what another population seed would move it by. The
//! addition pays when it improves the median or the worst by more than
//! its spread at either noise level; it is mixed when it also makes one of
//! them worse by more than its spread.

use crate::cases::Case;
use crate::closed_loop::{Conditions, NOISY_SEEDS};
use crate::data::{self, Error};
use crate::models::Model;
use crate::nights::{self, Night2Start};
use crate::noise::SplitMix64;
use crate::phd2_log;
use crate::population::summary::{Level, Stats};
use crate::population::Mount;
use crate::replay;
use crate::st4_sim::{self, Firmware, Setup};
use crate::table::{self, Column};
use mkgp_mount::model::additions::{Acts, Additions};
use mkgp_mount::mount::config::MountConfig;
use rayon::prelude::*;

/// The model the model's loop and the logs run: the firmware's stage
/// count, so that an addition for a third stage is measured where it acts.
pub const MODEL: Model = Model::Mkgp3;

/// The smallest change that counts, the resolution the ratios print at:
/// where the same mount holds the worst in nearly every redraw, the
/// spread is near 0 and would let a change of 0.0004 pay.
pub const LEAST_CHANGE: f64 = 0.001;

/// Redraws of the mounts for the spread.
pub const RESAMPLES: usize = 1000;

/// The name a loop prints under.
pub fn loop_name(lp: Acts) -> &'static str {
    match lp {
        Acts::Model => "model",
        Acts::Firmware => "firmware",
        Acts::Restore => "restore",
    }
}

const LEVELS: [Level; 2] = [Level::NoiseFree, Level::Seeing];

fn noise_px(mount: &Mount, level: Level) -> f64 {
    match level {
        Level::NoiseFree => 0.0,
        Level::Seeing => mount.seeing_px,
    }
}

/// One cell of a loop: a gear error at a noise level over seeds (the first
/// alone when noise-free), and what each loop is given besides.
struct Cell<'a> {
    case: &'a Case,
    noise: f64,
    seeds: Vec<u64>,
    conditions: Conditions,
    setup: Setup,
    config: MountConfig,
}

impl<'a> Cell<'a> {
    /// `mount` at `level`, from its first run seed.
    fn mount(mount: &'a Mount, level: Level) -> Self {
        Cell {
            case: &mount.case,
            noise: noise_px(mount, level),
            seeds: mount.seeds()[..1].to_vec(),
            conditions: mount.conditions(),
            setup: mount.setup(),
            config: mount.config(),
        }
    }

    /// A paper case as its tables run it (`nights` runs every seed, each
    /// its own night-2 phase, noise-free too).
    fn case(case: &'a Case, noise: f64) -> Self {
        Cell {
            case,
            noise,
            seeds: NOISY_SEEDS.to_vec(),
            conditions: Conditions::PAPER,
            setup: Setup::default(),
            config: st4_sim::mount_config(case),
        }
    }

    /// RMS of MKGP (`Some(additions)`) or of the loop's baseline (`None`),
    /// the mean over the seeds.
    fn rms(&self, lp: Acts, mkgp: Option<Additions>) -> f64 {
        match lp {
            Acts::Model => {
                let (column, additions) = match mkgp {
                    Some(a) => (Column::Model(MODEL), a),
                    None => (Column::Reactive, Additions::ALL),
                };
                table::rms_in(
                    self.case,
                    self.noise,
                    &self.seeds,
                    &self.conditions,
                    column,
                    additions,
                )
            }
            Acts::Firmware => {
                let (firmware, additions) = match mkgp {
                    Some(a) => (Firmware::Mkgp, a),
                    None => (Firmware::GuiderOnly, Additions::ALL),
                };
                let setup = Setup {
                    additions,
                    ..self.setup
                };
                let seeds = if self.noise > 0.0 {
                    &self.seeds[..]
                } else {
                    &self.seeds[..1]
                };
                let rms = seeds.iter().map(|&seed| {
                    st4_sim::run_on(self.case, firmware, self.noise, seed, setup, self.config).rms
                });
                rms.sum::<f64>() / seeds.len() as f64
            }
            Acts::Restore => {
                let run = nights::Run {
                    case: self.case,
                    noise_px: self.noise,
                    setup: Setup {
                        additions: mkgp.unwrap_or(Additions::ALL),
                        ..self.setup
                    },
                    config: self.config,
                    calibrates: false,
                };
                let rms = self.seeds.iter().map(|&seed| {
                    let [_, cold, unknown, index] = nights::one_seed(run, seed, Night2Start::Moved);
                    match mkgp {
                        Some(_) => 0.5 * (unknown + index),
                        None => cold,
                    }
                });
                rms.sum::<f64>() / self.seeds.len() as f64
            }
        }
    }
}

/// One configuration's figures in one loop.
#[derive(Debug, Clone, PartialEq)]
pub struct Figures {
    /// Per level (noise-free, seeing), per mount in order: MKGP over the
    /// baseline.
    pub mounts: [Vec<f64>; 2],
    /// Per paper case and noise level (0, 1 px): MKGP over the baseline.
    pub cases: Vec<f64>,
    /// The PHD2 logs' MKGP gain over hysteresis, % (the model's loop
    /// only: the replay runs the model, not the learner).
    pub log_gains_pct: Vec<f64>,
}

impl Figures {
    /// The mean ratio over the paper's cases at the table's level that
    /// stands for `level` (0 px; 1 px for the seeing).
    pub fn cases_mean(&self, level: Level) -> f64 {
        let at: Vec<f64> = self
            .cases
            .iter()
            .skip(level_index(level))
            .step_by(table::NOISE_LEVELS.len())
            .copied()
            .collect();
        at.iter().sum::<f64>() / at.len() as f64
    }
}

/// What a loop's figures are measured against: the baselines, once.
pub struct Bench<'a> {
    pub lp: Acts,
    pub mounts: &'a [Mount],
    pub cases: &'a [Case],
    pub logs: &'a [phd2_log::GuideLog],
    /// Per level, per mount; then per case and level.
    baseline_mounts: [Vec<f64>; 2],
    baseline_cases: Vec<f64>,
}

impl<'a> Bench<'a> {
    /// Runs the baselines.
    pub fn new(
        lp: Acts,
        mounts: &'a [Mount],
        cases: &'a [Case],
        logs: &'a [phd2_log::GuideLog],
    ) -> Self {
        let baseline_mounts = LEVELS.map(|l| {
            mounts
                .par_iter()
                .map(|m| Cell::mount(m, l).rms(lp, None))
                .collect()
        });
        let baseline_cases = table::cells(cases)
            .par_iter()
            .map(|&(c, noise)| Cell::case(c, noise).rms(lp, None))
            .collect();
        Bench {
            lp,
            mounts,
            cases,
            logs,
            baseline_mounts,
            baseline_cases,
        }
    }

    /// MKGP with `additions` over the baselines.
    pub fn figures(&self, additions: Additions) -> Result<Figures, Error> {
        let lp = self.lp;
        let mounts = LEVELS.map(|l| {
            let rms: Vec<f64> = self
                .mounts
                .par_iter()
                .map(|m| Cell::mount(m, l).rms(lp, Some(additions)))
                .collect();
            let base = &self.baseline_mounts[level_index(l)];
            rms.iter().zip(base).map(|(r, b)| r / b).collect()
        });
        let cases = table::cells(self.cases)
            .par_iter()
            .map(|&(c, noise)| Cell::case(c, noise).rms(lp, Some(additions)))
            .collect::<Vec<f64>>()
            .iter()
            .zip(&self.baseline_cases)
            .map(|(r, b)| r / b)
            .collect();
        let log_gains_pct = match lp {
            Acts::Model => self
                .logs
                .par_iter()
                .map(|log| replay::gain_with(log, MODEL, additions))
                .collect::<Result<_, _>>()?,
            Acts::Firmware | Acts::Restore => Vec::new(),
        };
        Ok(Figures {
            mounts,
            cases,
            log_gains_pct,
        })
    }

    /// The mounts' numbers, in order.
    pub fn mount_numbers(&self) -> Vec<usize> {
        self.mounts.iter().map(|m| m.index).collect()
    }
}

fn level_index(level: Level) -> usize {
    match level {
        Level::NoiseFree => 0,
        Level::Seeing => 1,
    }
}

/// What switching one addition off does at one level.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Worth {
    pub level: Level,
    /// The mounts' ratios with the addition off.
    pub off: Stats,
    /// Median and worst with it off less with all on (positive: it pays).
    pub median_change: f64,
    pub worst_change: f64,
    /// Their bootstrap standard deviations over redrawn mounts.
    pub median_spread: f64,
    pub worst_spread: f64,
}

impl Worth {
    /// The addition improves the median or the worst by more than its
    /// spread (and [`LEAST_CHANGE`]).
    pub fn pays(&self) -> bool {
        self.beyond(self.median_change, self.worst_change)
    }

    /// The addition makes the median or the worst worse by more than its
    /// spread (and [`LEAST_CHANGE`]).
    pub fn hurts(&self) -> bool {
        self.beyond(-self.median_change, -self.worst_change)
    }

    fn beyond(&self, median: f64, worst: f64) -> bool {
        median > self.median_spread.max(LEAST_CHANGE) || worst > self.worst_spread.max(LEAST_CHANGE)
    }
}

/// What an addition's worth at both levels comes to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// It pays at a level and hurts at none.
    Pays,
    /// It pays at a level and hurts at another, or at the other figure.
    Mixed,
    /// It pays at no level.
    DoesNotPay,
}

impl Verdict {
    pub fn of(worth: &[Worth; 2]) -> Verdict {
        match (
            worth.iter().any(Worth::pays),
            worth.iter().any(Worth::hurts),
        ) {
            (true, false) => Verdict::Pays,
            (true, true) => Verdict::Mixed,
            (false, _) => Verdict::DoesNotPay,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Verdict::Pays => "yes",
            Verdict::Mixed => "mixed",
            Verdict::DoesNotPay => "no",
        }
    }
}

/// All on against one off, per level; `numbers`: the mounts' numbers in
/// the figures' order.
pub fn worth(numbers: &[usize], on: &Figures, off: &Figures) -> [Worth; 2] {
    LEVELS.map(|level| {
        let k = level_index(level);
        let (a, b) = (&on.mounts[k], &off.mounts[k]);
        let stats = |x: &[f64]| {
            Stats::of(x.iter().copied().zip(numbers.iter().copied()).collect())
                .unwrap_or_else(|| panic!("ablation of no mounts"))
        };
        let (s_on, s_off) = (stats(a), stats(b));
        let mut rng = SplitMix64::new(RESAMPLES as u64 + k as u64);
        let n = a.len();
        let (mut dm, mut dw) = (Vec::new(), Vec::new());
        for _ in 0..RESAMPLES {
            let pick: Vec<usize> = (0..n).map(|_| rng.below(n as u64) as usize).collect();
            let draw = |x: &[f64]| stats(&pick.iter().map(|&i| x[i]).collect::<Vec<_>>());
            let (r_on, r_off) = (draw(a), draw(b));
            dm.push(r_off.median - r_on.median);
            dw.push(r_off.worst - r_on.worst);
        }
        Worth {
            level,
            off: s_off,
            median_change: s_off.median - s_on.median,
            worst_change: s_off.worst - s_on.worst,
            median_spread: std_dev(&dm),
            worst_spread: std_dev(&dw),
        }
    })
}

fn std_dev(x: &[f64]) -> f64 {
    let n = x.len() as f64;
    let mean = x.iter().sum::<f64>() / n;
    (x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt()
}

/// The PHD2 logs of host-tests/data.
pub fn phd2_logs() -> Result<Vec<phd2_log::GuideLog>, Error> {
    data::phd2_logs()?
        .iter()
        .map(|p| phd2_log::load(p))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use mkgp_mount::mount::learner::FIRMWARE_STAGES;

    fn figures(noise_free: Vec<f64>, seeing: Vec<f64>) -> Figures {
        Figures {
            mounts: [noise_free, seeing],
            cases: vec![0.5, 0.9, 0.7, 1.1],
            log_gains_pct: Vec::new(),
        }
    }

    #[test]
    fn an_addition_that_changes_nothing_does_not_pay() {
        let on = figures(vec![0.5, 0.6, 0.7, 0.8, 0.9], vec![0.7; 5]);
        for w in worth(&[1, 2, 3, 4, 5], &on, &on) {
            assert_eq!((w.median_change, w.worst_change), (0.0, 0.0));
            assert_eq!((w.median_spread, w.worst_spread), (0.0, 0.0));
            assert!(!w.pays());
        }
        assert_eq!(on.cases_mean(Level::NoiseFree), 0.6);
        assert_eq!(on.cases_mean(Level::Seeing), 1.0);
    }

    #[test]
    fn an_addition_pays_where_it_helps_beyond_the_spread() {
        let numbers: Vec<usize> = (1..=40).collect();
        let base: Vec<f64> = numbers.iter().map(|&k| 0.4 + 0.01 * k as f64).collect();
        let on = figures(base.clone(), base.clone());
        // Off: every mount 0.1 worse noise-free (pays on the median); at the
        // seeing one mount worse (only its worst moves), one better.
        let mut seeing = base.clone();
        seeing[39] = 1.3;
        seeing[0] = 0.1;
        let off = figures(base.iter().map(|r| r + 0.1).collect(), seeing);
        let [free, at_seeing] = worth(&numbers, &on, &off);
        assert!((free.median_change - 0.1).abs() < 1e-12, "{free:?}");
        assert!(free.median_spread < 1e-12 && free.pays(), "{free:?}");
        assert_eq!((free.off.worst_mount, free.off.worse), (40, 0));
        assert_eq!(at_seeing.median_change, 0.0);
        assert!(
            (at_seeing.worst_change - 0.5).abs() < 1e-12,
            "{at_seeing:?}"
        );
        assert!(
            at_seeing.worst_spread > 0.0 && at_seeing.pays(),
            "{at_seeing:?}"
        );
        assert_eq!(at_seeing.off.worse, 1);
        assert!(!free.hurts() && !at_seeing.hurts());
        assert_eq!(Verdict::of(&[free, at_seeing]), Verdict::Pays);
        // A change below the resolution pays nothing, whatever its spread.
        let mut tiny = base.clone();
        tiny[39] += 0.0004;
        let [_, slight] = worth(&numbers, &on, &figures(base.clone(), tiny));
        assert!(slight.worst_change > slight.worst_spread, "{slight:?}");
        assert!(!slight.pays() && !slight.hurts(), "{slight:?}");
        // Better off at one level than on: mixed.
        let better = figures(base.iter().map(|r| r - 0.1).collect(), base.clone());
        let [worse_free, _] = worth(&numbers, &on, &better);
        assert!(worse_free.hurts() && !worse_free.pays());
        assert_eq!(Verdict::of(&[worse_free, free]), Verdict::Mixed);
        assert_eq!(Verdict::of(&[worse_free, worse_free]), Verdict::DoesNotPay);
    }

    #[test]
    fn the_firmware_loop_runs_the_firmware_model() {
        assert_eq!(MODEL.stages(), FIRMWARE_STAGES);
    }
}
