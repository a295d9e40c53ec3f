//! `guide-sim night`: a scripted night of many guiding sections through
//! the firmware's own loop (issue 27, "What a night holds").
//!
//! The rig is `st4_sim`'s [`Rig`]: the firmware's `ControlLoop`, its step
//! generators and its learner, a simulated camera and the PHD2-like
//! hysteresis guider, on a mount whose RA error is a synthetic case. Its
//! mount is the `st4` rig's with the highest rate raised to
//! [`MAX_RATE_SIDEREAL`] (the step timer's limit on C8's mount, whose
//! 288 s worm turns faster, is 93x), so that a meridian flip's half turn
//! takes eight minutes instead of an hour and a half at the default 8x. A [`script`] of timed events drives the night
//! ([`session`]): sections that each start the guider afresh (calibration,
//! guiding, the imaging sequence with downloads, dithers and settling),
//! re-pointings through the command port (`:RS#:Mw#` .. `:Qw#`) or by hand,
//! a meridian flip, refocus pauses, a star lost, clouds.
//!
//! Each night runs three times on the same script, noise and seed: the
//! guider alone (the firmware tracks and obeys the pulses), and with the
//! firmware's `Learner<1>` (fw PPEC) and `Learner<FIRMWARE_STAGES>` (fw
//! MKGP). The score is the pointing RMS (arcsec = px, 10 ms samples) while
//! the main camera images: per section, over the section's first
//! [`session::FIRST_S`] of guiding and after, and over the whole night.
//! The guider alone also writes its side as a PHD2 guide log on request
//! ([`phd2_writer`]): with its pulses only, the log's distances hold the
//! gear error as a replay reconstructs it.

pub mod calibration;
pub mod goals;
pub mod ledger;
pub mod phd2_writer;
pub mod script;
pub mod session;

use crate::cases::Case;
use crate::st4_sim::{self, Extremes, Firmware, Rig};
use ledger::{Activity, Rms, Tally};
use mkgp_mount::control_loop::port_motion::PortMotionCounters;
use mkgp_mount::model::additions::Additions;
use mkgp_mount::model::guider::Faults;
use mkgp_mount::mount::config::MountConfig;
use mkgp_mount::mount::guiding::GuidingCounters;
use mkgp_mount::mount::learner::LearnerCounters;
use mkgp_mount::mount::st4::St4Counters;
use rayon::prelude::*;
use script::Event;
use session::{GuideLogs, SectionScore, Session};
use std::sync::atomic::{AtomicUsize, Ordering};

/// The night's mount's highest rate, multiples of sidereal.
pub const MAX_RATE_SIDEREAL: f32 = 90.0;

/// The mount of a night on `case`: the `st4` rig's, faster.
pub fn mount_config(case: &Case) -> MountConfig {
    MountConfig {
        max_rate_sidereal: MAX_RATE_SIDEREAL,
        ..st4_sim::mount_config(case)
    }
}

/// What the firmware counted over a night.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Counters {
    pub learner: LearnerCounters,
    pub guiding: GuidingCounters,
    pub st4: St4Counters,
    /// The model's own faults (none for the guider alone).
    pub faults: Option<Faults>,
    pub port: PortMotionCounters,
    pub lost_edges: u32,
}

/// The firmware's `dither_threshold_us` at the guide rate, arcsec: an RA
/// pulse moving more is a dither to it.
pub fn dither_threshold_arcsec(case: &Case) -> f64 {
    let mount = mount_config(case)
        .validate()
        .unwrap_or_else(|e| panic!("{e}"));
    mount.guide_rate_arcsec_per_s() as f64 * mount.config().dither_threshold_us as f64 * 1e-6
}

/// One firmware's night.
#[derive(Debug, Clone)]
pub struct NightRun {
    pub sections: Vec<SectionScore>,
    pub counters: Counters,
    pub extremes: Extremes,
    /// Per activity: its windows and the frames learned in them.
    pub tallies: Vec<(Activity, Tally)>,
    /// Every dither's amount, arcsec (positive: RA+).
    pub dithers: Vec<f64>,
    pub logs: Option<GuideLogs>,
}

impl NightRun {
    /// The whole night's imaging.
    pub fn night(&self) -> Rms {
        self.sections.iter().fold(Rms::default(), |r, s| r + s.all)
    }

    pub fn tally(&self, activity: Activity) -> Tally {
        self.tallies
            .iter()
            .find(|(a, _)| *a == activity)
            .map_or(Tally::default(), |(_, t)| *t)
    }
}

/// `script` (checked first) with `firmware` on `case`, running
/// `additions`; `log`: also the guider's PHD2 log and its truth.
pub fn run(
    case: &Case,
    firmware: Firmware,
    noise_px: f64,
    seed: u64,
    script: &[Event],
    additions: Additions,
    log: bool,
) -> Result<NightRun, script::ScriptError> {
    script::check(script, MAX_RATE_SIDEREAL as f64)?;
    let config = mount_config(case);
    let rig = Rig::with_additions(case, firmware, noise_px, seed, config, additions);
    let out = Session::new(rig, noise_px, seed, log).run(script);
    let rig = &out.rig;
    let tallies = Activity::ALL
        .iter()
        .map(|&a| (a, ledger::tally(a, &out.windows, &rig.frames_learned)))
        .collect();
    Ok(NightRun {
        sections: out.sections,
        counters: Counters {
            learner: rig.learner_counters(),
            guiding: rig.guiding_counters(),
            st4: rig.st4_counters(),
            faults: rig.model_faults(),
            port: rig.port_counters(),
            lost_edges: rig.lost_edges(),
        },
        extremes: rig.extremes,
        tallies,
        dithers: out.dithers,
        logs: out.logs,
    })
}

/// One night, case, noise and seed, for the three firmwares.
#[derive(Debug, Clone)]
pub struct Night {
    pub case: String,
    pub noise_px: f64,
    pub seed: u64,
    /// The longest RA move the firmware takes for a guide pulse rather
    /// than a dither, arcsec ([`dither_threshold_arcsec`]).
    pub dither_threshold_arcsec: f64,
    pub guider_only: NightRun,
    pub fw_ppec: NightRun,
    pub fw_mkgp: NightRun,
}

/// The three firmwares on one night (in parallel), running `additions`;
/// if `log`, each writes its logs (the guider alone's PHD2 log and truth,
/// the MKGP learner's rows).
pub fn night(
    case: &Case,
    noise_px: f64,
    seed: u64,
    script: &[Event],
    additions: Additions,
    log: bool,
) -> Result<Night, script::ScriptError> {
    let fw = |f, log| run(case, f, noise_px, seed, script, additions, log);
    let (guider_only, (fw_ppec, fw_mkgp)) = rayon::join(
        || fw(Firmware::GuiderOnly, log),
        || rayon::join(|| fw(Firmware::Ppec, false), || fw(Firmware::Mkgp, log)),
    );
    Ok(Night {
        case: case.name.clone(),
        noise_px,
        seed,
        dither_threshold_arcsec: dither_threshold_arcsec(case),
        guider_only: guider_only?,
        fw_ppec: fw_ppec?,
        fw_mkgp: fw_mkgp?,
    })
}

/// Every case, noise level and seed (in that order), the nights spread
/// over rayon's threads; `progress(done, total, night)` as each ends.
pub fn sweep(
    cases: &[Case],
    levels: &[f64],
    seeds: &[u64],
    script: &[Event],
    additions: Additions,
    progress: impl Fn(usize, usize, &Night) + Sync,
) -> Result<Vec<Night>, script::ScriptError> {
    let runs: Vec<(&Case, f64, u64)> = cases
        .iter()
        .flat_map(|c| {
            levels
                .iter()
                .flat_map(move |&n| seeds.iter().map(move |&s| (c, n, s)))
        })
        .collect();
    let done = AtomicUsize::new(0);
    runs.par_iter()
        .map(|&(case, noise, seed)| {
            let n = night(case, noise, seed, script, additions, false)?;
            progress(done.fetch_add(1, Ordering::SeqCst) + 1, runs.len(), &n);
            Ok(n)
        })
        .collect()
}
