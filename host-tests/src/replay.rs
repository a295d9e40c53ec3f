//! PHD2's causal replay of a guide log (docs/reference.md section 3), one
//! guiding section after another.
//!
//! With `m[i]` = RARawDistance and `c[i]` the correction the mount carried out
//! (RAGuideDistance, or the pulse where it was cut short: `row::applied`;
//! plus any dither) of a section's frames, the simulated mount state
//! starts at `x_0 = m[0]`; at frame i the guide algorithm sees x_i (with the
//! row's time and SNR, and a time step: [`TimeStep`]) and returns u_i,
//! and the state moves by `(m[i+1] - (m[i] - c[i])) - u_i`: the gear's own
//! motion between the frames as the log recorded it, minus the simulated
//! control. The gear error is the integral of the applied corrections plus
//! the measured error whatever guided the night (PHD2's predictive guider
//! or hysteresis): the replay reads what was applied, never what an
//! algorithm would have done.
//!
//! Conventions, all checked against INDIGO's reference traces
//! (`indigo_ppec_dataset0N.csv`, tests/replay.rs):
//! - A section with n frames is replayed for n - 2 frames (the traces have
//!   n - 2 rows; the last row of the log is never used).
//! - Dither: the first amount printed by `INFO: DITHER by X, Y` is added to
//!   c of the first frame after the line. That frame's RAGuideDistance is the
//!   dither move itself (about -X); with X added the state carries on
//!   smoothly after that frame, whose state holds the lock's move. This
//!   reproduces the traces' inputs to 1e-14 on every frame
//!   ([`Options::PERFORMANCE_TEST`]). The night's replay measures from the
//!   first lock instead ([`Options::first_lock`]): X is added to m from
//!   that frame on and c is as carried out, so no frame holds the move.
//! - The RMS is over the states after each control, x_1 .. x_{n-2}. That
//!   reproduces INDIGO's improvements (docs/reference.md) 0.27, 0.10, 12.26, 8.31 and
//!   2.22 % (the states before the control give 12.18 % on log 03).
//! - Baseline: hysteresis, aggressiveness 0.7, hysteresis 0.1, min move 0.2
//!   (PHD2's defaults; min moves 0.15 or 0.1 do not reproduce the figures).
//!
//! A night of several sections: each starts again at its first frame's
//! error (the star is locked afresh, so the gear's motion across the
//! pause is unknown) on the night's clock (`Section::start_s` plus
//! `Time`), and the algorithm is told that guiding restarted
//! ([`GuideAlgorithm::restart`]: the pause, and the shift of gear time
//! the pointing gives, [`pointing`]). The whole log's RMS is over every
//! section's states, in px of the first section's pixel scale.

pub mod pointing;
pub mod report;
mod section;
pub mod table;

use crate::data::Error;
use crate::gp::trace::Traced;
use crate::gp::{Carry, GpAlgorithm};
use crate::guide_algorithm::{GuideAlgorithm, Hysteresis, Restart};
use crate::models::{self, Model};
use crate::phd2_log::{GuideLog, Section};
use mkgp_mount::model::additions::Additions;

/// Control and prediction gains of the replay (PHD2's performance test).
pub const CONTROL_GAIN: f64 = 0.7;
pub const PREDICTION_GAIN: f64 = 0.5;

/// The time step the algorithm is given with a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TimeStep {
    /// The section's exposure, as PHD2 gives its predictive guider.
    Exposure,
    /// The section's cadence: its median interval between frames.
    Cadence,
    /// The interval to the next frame.
    ToNext,
    /// The exposure, or the cadence where the frames come at least
    /// [`SLOW_CADENCE`] exposures apart.
    Frames,
}

/// Frames this many exposures apart come at a cadence of their own (a
/// guide-frame time lapse, a slow camera): the firmware's margin for the
/// guider's measured cadence (`mount::guiding::framer`). Below it the
/// interval is the exposure plus the guider's overhead, and the exposure is
/// what PHD2 gives its predictive guider.
pub const SLOW_CADENCE: f64 = 1.5;

/// What the replayed algorithm is told besides the frames with a star.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Options {
    pub time_step: TimeStep,
    /// Frames without a star (DROP rows), as such.
    pub drops: bool,
    /// Pauses within a section longer than this many cadences, as frames
    /// without a star at the cadence.
    pub pause_cadences: Option<f64>,
    /// Dithers, with the gear time they shift (the model settles).
    pub dithers: bool,
    /// Each frame measured from the section's first lock position: a
    /// dither's move of the lock is taken out of the measurements, and its
    /// recentring move left in the corrections (`replay::measurements`).
    /// Without it (INDIGO's convention) the dither's row measures the
    /// lock's move and the algorithm's answer to it is replayed and scored.
    pub first_lock: bool,
    /// `Settling started` without a dither: settle.
    pub settling: bool,
}

/// Where pauses begin, in cadences (docs/results.md, "Nights of several
/// sections"): a frame 2.5 cadences late is a slow frame, and telling the
/// model of one moved logs 01, 02 and 05 by up to 0.16 % either way; log
/// 04's pause of 173 s (84 cadences) is one from 5 cadences on.
pub const PAUSE_CADENCES: f64 = 5.0;

impl Options {
    /// INDIGO's replay of PHD2's performance test: the algorithm sees the
    /// frames with a star alone, the exposure as its time step.
    pub const PERFORMANCE_TEST: Options = Options {
        time_step: TimeStep::Exposure,
        drops: false,
        pause_cadences: None,
        dithers: false,
        settling: false,
        first_lock: false,
    };
}

/// The night's replay: the time step of the frames' own cadence where they
/// come slower than the exposure, frames without a star and pauses told as
/// such, every frame measured from the first lock. Dithers are not told:
/// the replay takes a dither's move out of the measurements, so the state
/// is the gear's own motion, and a model told of it would settle on an
/// error that is not there; for the same reason neither is settling.
impl Default for Options {
    fn default() -> Self {
        Options {
            time_step: TimeStep::Frames,
            drops: true,
            pause_cadences: Some(PAUSE_CADENCES),
            dithers: false,
            settling: false,
            first_lock: true,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReplayResult {
    /// Number of guide algorithm calls (frames of each section minus two).
    pub frames: usize,
    /// RMS of the simulated state after each control (px).
    pub rms: f64,
}

/// One section's part of a replay.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SectionResult {
    /// Index in [`GuideLog::sections`].
    pub section: usize,
    pub frames: usize,
    /// In px of the section's own pixel scale.
    pub rms: f64,
}

/// A replay of a whole log, and of each section it replayed (those of at
/// least 3 frames).
#[derive(Debug, Clone, PartialEq)]
pub struct LogResult {
    pub whole: ReplayResult,
    pub sections: Vec<SectionResult>,
}

/// The measurements `m[i]` and corrections `c[i]` (what the mount carried
/// out) of a section, each dither's amount X added: with
/// [`Options::first_lock`] to every measurement from its row on (each
/// measured from the section's first lock), else to the correction of its
/// row (INDIGO's convention, above).
pub fn measurements(section: &Section, first_lock: bool) -> (Vec<f64>, Vec<f64>) {
    let mut m: Vec<f64> = section.frames.iter().map(|f| f.ra_raw).collect();
    let mut c: Vec<f64> = section.frames.iter().map(|f| f.ra_applied).collect();
    for (next, x, _) in section.dithers() {
        if first_lock {
            for v in m.iter_mut().skip(next) {
                *v += x;
            }
        } else {
            c[next] += x;
        }
    }
    (m, c)
}

/// Replay `log` with `algorithm`, the default [`Options`].
pub fn run(log: &GuideLog, algorithm: &mut dyn GuideAlgorithm) -> Result<ReplayResult, Error> {
    run_with(log, algorithm, &Options::default()).map(|r| r.whole)
}

/// Replay `log` with `algorithm`, section by section.
pub fn run_with(
    log: &GuideLog,
    algorithm: &mut dyn GuideAlgorithm,
    options: &Options,
) -> Result<LogResult, Error> {
    let replayed: Vec<usize> = (0..log.sections.len())
        .filter(|&k| log.sections[k].frames.len() >= 3)
        .collect();
    let Some(&first) = replayed.first() else {
        let n = log
            .sections
            .iter()
            .map(|s| s.frames.len())
            .max()
            .unwrap_or(0);
        return Err(Error::new(
            &log.path,
            None,
            format!("{n} guide frame(s) in its longest section; the replay needs at least 3"),
        ));
    };
    let scale0 = log.sections[first].header.pixel_scale;
    let mut sections = Vec::new();
    let (mut frames, mut sum_sq) = (0, 0.0);
    let mut previous: Option<&Section> = None;
    for &k in &replayed {
        let s = &log.sections[k];
        if let Some(p) = previous {
            algorithm.restart(&restart(p, s, options));
        }
        let (n, sq) = section::replay(s, algorithm, options);
        sections.push(SectionResult {
            section: k,
            frames: n,
            rms: (sq / n as f64).sqrt(),
        });
        // Each section's px in the first section's.
        let to_first = match (s.header.pixel_scale, scale0) {
            (Some(own), Some(first)) => own / first,
            _ => 1.0,
        };
        frames += n;
        sum_sq += sq * to_first * to_first;
        previous = Some(s);
    }
    Ok(LogResult {
        whole: ReplayResult {
            frames,
            rms: (sum_sq / frames as f64).sqrt(),
        },
        sections,
    })
}

/// What the algorithm is told when section `next` starts after `last`.
fn restart(last: &Section, next: &Section, options: &Options) -> Restart {
    let first_frame = next.start_s + next.frames.first().map_or(0.0, |f| f.time_s);
    Restart {
        gap_s: (first_frame - last.end_s()).max(0.0),
        step_s: time_step_s(next, options),
        gear_shift_s: pointing::gear_shift_s(last, next),
        pier_flip: pointing::pier_flip(last, next),
        scale_ratio: match (next.header.pixel_scale, last.header.pixel_scale) {
            (Some(new), Some(old)) => new / old,
            _ => 1.0,
        },
    }
}

/// The time step `options` give `section`'s frames, s (its cadence where
/// each frame has its own).
pub fn time_step_s(section: &Section, options: &Options) -> f64 {
    let cadence = section::cadence_s(section);
    section::step_s(section, options.time_step, cadence).unwrap_or(cadence)
}

/// Section `k` of `log` as a log of its own.
pub fn section_alone(log: &GuideLog, k: usize) -> GuideLog {
    GuideLog {
        path: log.path.clone(),
        sections: log.sections.get(k).cloned().into_iter().collect(),
    }
}

/// `model` on `log` with the replay's gains.
pub fn run_model(log: &GuideLog, model: Model) -> Result<ReplayResult, Error> {
    run(log, &mut *model_algorithm(model))
}

/// `model` with the replay's gains, as a fresh algorithm.
pub fn model_algorithm(model: Model) -> Box<dyn GuideAlgorithm> {
    models::algorithm(model, Some(CONTROL_GAIN), Some(PREDICTION_GAIN))
}

/// MKGP's replay of `log` as the `mkgp` column runs it (two stages, the
/// replay's gains, carried across sections), traced: its result and what
/// the model holds after each call ([`crate::gp::trace`], on the log's
/// clock: `Section::start_s` plus `Time`).
pub fn traced_mkgp(log: &GuideLog) -> Result<(ReplayResult, String), Error> {
    let model = GpAlgorithm::<2>::new(Some(CONTROL_GAIN), Some(PREDICTION_GAIN))
        .with_carry(Carry::default());
    let mut traced = Traced::new(model);
    let result = run(log, &mut traced)?;
    Ok((result, traced.csv().to_string()))
}

/// `model`'s gain in percent over PHD2's hysteresis 0.7 on `log`.
pub fn gain_over_hysteresis(log: &GuideLog, model: Model) -> Result<f64, Error> {
    gain_with(log, model, Additions::ALL)
}

/// [`gain_over_hysteresis`] with the model's `additions` as given.
pub fn gain_with(log: &GuideLog, model: Model, additions: Additions) -> Result<f64, Error> {
    let hysteresis = run(log, &mut Hysteresis::phd2_baseline())?;
    let mut algorithm = models::carrying(
        model,
        Some(CONTROL_GAIN),
        Some(PREDICTION_GAIN),
        Carry::default(),
        additions,
    );
    Ok(gain_pct(run(log, &mut *algorithm)?.rms, hysteresis.rms))
}

/// Improvement of `model_rms` over `baseline_rms` in percent:
/// 100 (1 - model / baseline).
pub fn gain_pct(model_rms: f64, baseline_rms: f64) -> f64 {
    100.0 * (1.0 - model_rms / baseline_rms)
}
