//! A population of mounts (`guide-sim population`, issue 28): mounts drawn
//! from documented physical ranges ([`ranges`]), each run through the
//! model's closed loop (as `guide-sim table`: reactive, PPEC, MKGP) and the
//! firmware's (as `guide-sim st4`: the guider alone, fw PPEC, fw MKGP),
//! noise-free and at the mount's seeing.
//!
//! A mount is a gear error (a worm with harmonics, maybe modulated, and
//! 0-3 further stages with harmonics, one of which may fade; a polar
//! drift), a random walk of the star, a camera noise (its seeing) and an
//! exposure. Both loops take it as they take a case: the model's loop
//! frames every exposure ([`closed_loop::Conditions`]), the firmware's
//! guider exposes for it and the firmware is configured with the worm's
//! period and the guider's cycle (what its user would set). The walk is
//! drawn from each run's seed + 1000 in both.
//!
//! Noise levels: the tables run 0 and 1 px; a drawn mount runs 0 and its
//! own seeing ([`ranges::SEEING_PX`], around the tables' 1 px), and its
//! row's `noise_px` is that figure. The noisy figure is the mean over the
//! mount's three run seeds, as the tables' over seeds 1-3.
//!
//! Mount k of a seed is the same whatever the count: the population's
//! generator gives each mount the seed of its own. Two seeds below 2^32
//! share no mount.

mod draw;
pub mod ranges;
pub mod summary;

use crate::cases::Case;
use crate::closed_loop::{self, Conditions};
use crate::models::Model;
use crate::noise::SplitMix64;
use crate::st4_sim::{self, Firmware, GuiderSettings, Setup, Sky};
use crate::table::{self, Column};
use mkgp_mount::model::additions::Additions;
use mkgp_mount::mount::config::MountConfig;
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::sync::Mutex;

/// The development seed: the tests and docs/results.md use it; other
/// seeds are for evaluation.
pub const DEVELOPMENT_SEED: u64 = 28;

/// A worm's amplitude modulation (a drawn [`crate::cases::Envelope::Modulated`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Modulation {
    pub depth: f64,
    pub period_s: f64,
    pub phase_rad: f64,
}

/// A stage's fade (a drawn [`crate::cases::Envelope::Fade`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fade {
    pub from_s: f64,
    pub over_s: f64,
    pub to: f64,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum StageKind {
    /// A spur or motor gear turning `ratio` times per worm turn.
    Gear { ratio: f64 },
    /// A belt drive's pulley.
    Belt,
}

/// A stage beyond the worm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stage {
    pub kind: StageKind,
    pub period_s: f64,
    /// Its fundamental, px peak.
    pub amplitude_px: f64,
    /// Its 2nd and 3rd harmonics, as shares of the fundamental.
    pub harmonics: [f64; 2],
    pub fade: Option<Fade>,
}

/// A drawn mount: its parameters, and the gear error they make.
#[derive(Debug, Clone, PartialEq)]
pub struct Mount {
    /// Its number in the population, from 1.
    pub index: usize,
    pub teeth: u32,
    pub worm_period_s: f64,
    /// The worm's fundamental, px peak.
    pub worm_px: f64,
    /// The worm's 2nd-4th harmonics, as shares of its fundamental.
    pub worm_harmonics: [f64; 3],
    pub modulation: Option<Modulation>,
    pub stages: Vec<Stage>,
    pub drift_px_per_s: f64,
    pub walk_px_per_sqrt_min: f64,
    pub seeing_px: f64,
    pub exposure_s: f64,
    /// The noise-free run's seed; the noisy runs take it and the next two.
    pub run_seed: u64,
    /// The gear error (worm first: the firmware's worm period is its
    /// first sinusoid's, `st4_sim::mount_config`) and the drift. The
    /// sinusoids' phases are drawn too, and only here.
    pub case: Case,
}

impl Mount {
    /// The seeds of its runs: noise-free the first, noisy all three.
    pub fn seeds(&self) -> [u64; 3] {
        [0, 1, 2].map(|k| self.run_seed + k)
    }

    /// What the model's loop runs besides the gear.
    pub fn conditions(&self) -> Conditions {
        Conditions {
            dt_s: self.exposure_s,
            walk_px_per_sqrt_min: self.walk_px_per_sqrt_min,
            paper_seeds: false,
        }
    }

    /// The firmware's loop: the default guider exposing for the mount's
    /// exposure, the walk (1 px = 1 arcsec; the drift is the case's).
    pub fn setup(&self) -> Setup {
        Setup {
            guider: GuiderSettings {
                exposure_s: self.exposure_s,
                ..GuiderSettings::default()
            },
            sky: Sky {
                walk_arcsec_per_sqrt_min: self.walk_px_per_sqrt_min,
                ..Sky::default()
            },
            ..Setup::default()
        }
    }

    /// The firmware's configuration: the default mount with this worm and
    /// the guider's cycle.
    pub fn config(&self) -> MountConfig {
        MountConfig {
            guide_cadence_s: self.exposure_s as f32,
            ..st4_sim::mount_config(&self.case)
        }
    }
}

/// Mounts 1..=`count` of `seed`.
pub fn draw(seed: u64, count: usize) -> Vec<Mount> {
    let mut population = SplitMix64::new(stream_seed(seed));
    (1..=count)
        .map(|index| draw::mount(index, &mut SplitMix64::new(population.next_u64())))
        .collect()
}

/// Where `seed`'s mounts start in the generator's stream: one step per
/// mount, so nearby seeds are spread apart ([`crate::noise::apart`]),
/// anchored at the development seed so that its mounts stay those the docs
/// measure.
fn stream_seed(seed: u64) -> u64 {
    crate::noise::apart(seed, DEVELOPMENT_SEED)
}

/// One mount at one noise level: residual RMS (model's loop) and pointing
/// RMS (firmware's), px.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Row {
    pub mount: usize,
    pub noise_px: f64,
    pub open_loop: f64,
    pub reactive: f64,
    pub ppec: f64,
    pub mkgp: f64,
    pub guider_only: f64,
    pub fw_ppec: f64,
    pub fw_mkgp: f64,
}

impl Row {
    /// The figures in the CSV's order, `open_loop` to `fw_mkgp`.
    pub fn figures(&self) -> [f64; 7] {
        [
            self.open_loop,
            self.reactive,
            self.ppec,
            self.mkgp,
            self.guider_only,
            self.fw_ppec,
            self.fw_mkgp,
        ]
    }
}

/// The two rows of `mount`: noise-free, then at its seeing, with the
/// model's and the firmware's `additions` (every column's).
pub fn rows(mount: &Mount, additions: Additions) -> [Row; 2] {
    let (case, conditions, seeds) = (&mount.case, mount.conditions(), mount.seeds());
    let open_loop = closed_loop::open_loop_rms_in(case, seeds[0], &conditions);
    [0.0, mount.seeing_px].map(|noise_px| {
        let model = |c| table::rms_in(case, noise_px, &seeds, &conditions, c, additions);
        let firmware = |fw| firmware_rms(mount, fw, noise_px, additions);
        let ((reactive, ppec), (mkgp, (guider_only, (fw_ppec, fw_mkgp)))) = rayon::join(
            || {
                rayon::join(
                    || model(Column::Reactive),
                    || model(Column::Model(Model::Ppec)),
                )
            },
            || {
                rayon::join(
                    || model(Column::Model(Model::Mkgp)),
                    || {
                        rayon::join(
                            || firmware(Firmware::GuiderOnly),
                            || {
                                rayon::join(
                                    || firmware(Firmware::Ppec),
                                    || firmware(Firmware::Mkgp),
                                )
                            },
                        )
                    },
                )
            },
        );
        Row {
            mount: mount.index,
            noise_px,
            open_loop,
            reactive,
            ppec,
            mkgp,
            guider_only,
            fw_ppec,
            fw_mkgp,
        }
    })
}

/// Mean pointing RMS of `firmware` on `mount` (one run noise-free, the
/// mean over its seeds in seed order with noise).
fn firmware_rms(mount: &Mount, firmware: Firmware, noise_px: f64, additions: Additions) -> f64 {
    let seeds = mount.seeds();
    let seeds = if noise_px > 0.0 {
        &seeds[..]
    } else {
        &seeds[..1]
    };
    let setup = Setup {
        additions,
        ..mount.setup()
    };
    let config = mount.config();
    let rms: Vec<f64> = seeds
        .par_iter()
        .map(|&seed| st4_sim::run_on(&mount.case, firmware, noise_px, seed, setup, config).rms)
        .collect();
    rms.iter().sum::<f64>() / rms.len() as f64
}

/// The rows of every mount, in order (two each). The mounts start in
/// order on rayon's threads; `each` is given each mount's rows in order as
/// soon as it and all before it are done (a long run shows them as it
/// goes).
pub fn run(
    mounts: &[Mount],
    additions: Additions,
    each: impl FnMut(&Mount, &[Row; 2]) + Send,
) -> Vec<Row> {
    // The rows done out of order, the next mount in order, the rows so far.
    let state = Mutex::new((each, BTreeMap::new(), 0, Vec::new()));
    mounts.iter().enumerate().par_bridge().for_each(|(i, m)| {
        let r = rows(m, additions);
        let mut guard = state.lock().unwrap_or_else(|e| e.into_inner());
        let (each, pending, next, out) = &mut *guard;
        pending.insert(i, r);
        while let Some(r) = pending.remove(next) {
            each(&mounts[*next], &r);
            out.extend(r);
            *next += 1;
        }
    });
    let (_, _, _, out) = state.into_inner().unwrap_or_else(|e| e.into_inner());
    out
}

/// The CSV header: the columns of `table` and `st4`, then the drawn
/// parameters (a stage's columns empty when the mount has fewer; gear
/// ratios are turns per worm turn, harmonics shares of their fundamental).
pub fn csv_header() -> String {
    let mut h = String::from(
        "mount,noise_px,open_loop,reactive,ppec,mkgp,guider_only,fw_ppec,fw_mkgp,\
         teeth,worm_period_s,worm_px,worm_h2,worm_h3,worm_h4,am_depth,am_period_s,stages",
    );
    for i in 1..=ranges::STAGES.1 {
        for col in ["kind", "ratio", "period_s", "px", "h2", "h3"] {
            h.push_str(&format!(",s{i}_{col}"));
        }
    }
    h.push_str(
        ",fade_stage,fade_from_s,fade_over_s,fade_to,drift_px_per_s,walk_px_per_sqrt_min,seeing_px,exposure_s",
    );
    h
}

/// A row as CSV, with its mount's parameters.
pub fn csv_line(row: &Row, mount: &Mount) -> String {
    let mut s = format!("{},{:.3}", row.mount, row.noise_px);
    for x in row.figures() {
        s.push_str(&format!(",{x:.3}"));
    }
    let m = mount;
    let [h2, h3, h4] = m.worm_harmonics;
    s.push_str(&format!(
        ",{},{:.2},{:.2},{h2:.3},{h3:.3},{h4:.3}",
        m.teeth, m.worm_period_s, m.worm_px
    ));
    match m.modulation {
        Some(am) => s.push_str(&format!(",{:.3},{:.0}", am.depth, am.period_s)),
        None => s.push_str(",,"),
    }
    s.push_str(&format!(",{}", m.stages.len()));
    for i in 0..ranges::STAGES.1 {
        match m.stages.get(i) {
            Some(st) => {
                let (kind, ratio) = match st.kind {
                    StageKind::Gear { ratio } => ("gear", format!("{ratio:.4}")),
                    StageKind::Belt => ("belt", String::new()),
                };
                let [h2, h3] = st.harmonics;
                s.push_str(&format!(
                    ",{kind},{ratio},{:.2},{:.2},{h2:.3},{h3:.3}",
                    st.period_s, st.amplitude_px
                ));
            }
            None => s.push_str(",,,,,,"),
        }
    }
    match m.stages.iter().position(|st| st.fade.is_some()) {
        Some(i) => {
            let f = m.stages[i].fade.unwrap();
            s.push_str(&format!(
                ",{},{:.0},{:.0},{:.3}",
                i + 1,
                f.from_s,
                f.over_s,
                f.to
            ));
        }
        None => s.push_str(",,,,"),
    }
    s.push_str(&format!(
        ",{:.5},{:.3},{:.3},{}",
        m.drift_px_per_s, m.walk_px_per_sqrt_min, m.seeing_px, m.exposure_s
    ));
    s
}

/// A mount in a few words, for the text table: the worm (teeth, period,
/// amplitude, "am" if modulated), each stage (a gear's ratio or a belt's
/// period, amplitude, "fades"), the exposure and seeing.
pub fn describe(m: &Mount) -> String {
    let mut s = format!(
        "worm {} teeth {:.0} s {:.1} px{}",
        m.teeth,
        m.worm_period_s,
        m.worm_px,
        if m.modulation.is_some() { " am" } else { "" }
    );
    for st in &m.stages {
        match st.kind {
            StageKind::Gear { ratio } => s.push_str(&format!("; gear x{ratio:.3}")),
            StageKind::Belt => s.push_str(&format!("; belt {:.0} s", st.period_s)),
        }
        s.push_str(&format!(" {:.1} px", st.amplitude_px));
        if st.fade.is_some() {
            s.push_str(" fades");
        }
    }
    s.push_str(&format!(
        "; exposure {} s, seeing {:.2} px",
        m.exposure_s, m.seeing_px
    ));
    s
}
