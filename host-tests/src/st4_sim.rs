//! The firmware's closed loop (`guide-sim st4`): a virtual mount, a virtual
//! guide camera and a PHD2-like guider around the firmware's own loop
//! (`mkgp_mount::control_loop::ControlLoop`, driven as the board's guiding
//! task drives it) and its step generation (`AxisStepper`), with the
//! learner (`Learner`) as the board's learning task runs it.
//!
//! - **Mount.** Each axis is the firmware's `AxisStepper`, advanced by the
//!   ticks of the step timer (`step_tick_hz`) between events, in closed
//!   form (exactly the steps the generator makes due tick by tick; the
//!   STEP/DIR waveform's hold of a step around a reversal is not modelled).
//!   The mount moves by the steps emitted: gear time is RA steps / sidereal
//!   steps per second, and the RA pointing error is `p = g(gear time) - C`,
//!   with `g` the synthetic case's gear error (1 px = 1 arcsec) and `C` the
//!   steps beyond sidereal tracking in arcsec: the lag of the axis behind
//!   the sky. The mount is the default EQ6-class one
//!   (`MountConfig::default()`) with the worm period set to the case's first
//!   sinusoid (432 s, 288 s for C8), so the firmware's prior is its worm.
//! - **Guiding task.** Wakes on every raw ST4 edge and at the loop's
//!   `next_wake_us` (ST4 deadlines, the periodic rate update), exactly as on
//!   the board: `ControlLoop::wake` with the edges, the time, the RA step
//!   count and the newest feed-forward; the rates it returns are set on the
//!   steppers; completed frames move to a queue of `FRAME_QUEUE` while it
//!   has room.
//! - **Learning task.** Takes one frame at a time from that queue and runs
//!   `Learner::learn`; its feed-forward is ready [`INFERENCE_US`] later (the
//!   model's time on the target) and is installed at the guiding task's
//!   next wake-up. Around the frames it does what the library's
//!   `LearningPolicy` decides, as the board's does: a reset asked on a port
//!   before the next frame, and with a store ([`Rig::set_store`]) the
//!   periodic saves and the ports' requests. Guider only: no learner, the
//!   firmware tracks and obeys the pulses.
//! - **Camera.** Back-to-back exposures of 2 s ending at t = 2, 4, ... s;
//!   the measurement is the mean of the pointing over the exposure (10 ms
//!   samples), minus the lock position, plus N(0, noise) from the paper's
//!   generator (one per run and seed). A night's guider (`crate::night`)
//!   sets another exposure, a frame interval longer than it, and holds the
//!   camera while it calibrates ([`Rig::start_guider`],
//!   [`Rig::hold_camera`]), with its own guider off and each exposure taken
//!   ([`Rig::take_exposure`]).
//! - **Guider.** PHD2's hysteresis (aggressiveness 0.7, hysteresis 0.1, min
//!   move 0.2) turns the measurement into a correction; the pulse lasts
//!   correction / guide rate (0.5x sidereal, 7.52 arcsec/s), at most 2.5 s,
//!   on RA+ for a positive correction (the star lags: faster) and RA- for a
//!   negative one. It starts [`LATENCY_US`] after the exposure ends (after
//!   the previous pulse if that is still running) as raw line edges.
//! - **Score.** RMS of the pointing error (10 ms samples) over the final two
//!   thirds, t >= 3600 s of the 10 800 s run (`Rig::score_window_s`).

use crate::cases::Case;
use crate::guide_algorithm::{GuideAlgorithm, Hysteresis};
use crate::noise::{self, Gaussian};
use crate::store_sim::SimStore;
use mkgp_mount::control_loop::learning::{LearningPolicy, StoreStep};
use mkgp_mount::control_loop::port_motion::PortMotionCounters;
use mkgp_mount::control_loop::port_mount::{
    LearnedFrame, LearnerSummary, PortMount, PortState, StoreOutcome, StoreRequest,
};
use mkgp_mount::control_loop::st4_feed::{EdgeQueue, EdgeSource, RawEdge};
use mkgp_mount::control_loop::stepping::AxisStepper;
use mkgp_mount::control_loop::{ControlLoop, FrameRecord};
use mkgp_mount::model::additions::Additions;
use mkgp_mount::model::guider::Faults;
use mkgp_mount::mount::config::{Mount, MountConfig, SIDEREAL_ARCSEC_PER_S};
use mkgp_mount::mount::frame::{Frame, Rates};
use mkgp_mount::mount::guiding::{Guiding, GuidingCounters, FRAME_QUEUE};
use mkgp_mount::mount::learner::{Learner, LearnerCounters, FIRMWARE_STAGES, RECORD_MAX};
use mkgp_mount::mount::st4::{Line, St4Counters};
use mkgp_mount::mount::worm_index::WormIndex;
use mkgp_mount::port::mount_port::StepCounts;
use mkgp_mount::port::{Interpreter, ReplySink};
use rayon::prelude::*;
use std::collections::VecDeque;

/// Length of a run, s.
pub const RUN_S: f64 = 10_800.0;
/// The score covers t >= this, s (the final two thirds).
pub const SCORE_FROM_S: f64 = 3_600.0;
/// Exposure and guide cadence, s.
pub const EXPOSURE_S: f64 = 2.0;
/// Pointing sample interval, us.
pub const SAMPLE_US: u64 = 10_000;
/// From the end of an exposure to the start of its pulse, us.
pub const LATENCY_US: u64 = 20_000;
/// From the start of a frame's inference to its feed-forward, us.
pub const INFERENCE_US: u64 = 50_000;
/// Longest guide pulse the guider sends (PHD2's max RA duration), us.
pub const MAX_PULSE_US: u64 = 2_500_000;
/// Pause between a pulse and the next one when they would overlap, us.
pub const PULSE_GAP_US: u64 = 5_000;
/// The seeds of the noisy runs.
pub const SEEDS: [u64; 3] = [1, 2, 3];

/// The guider in front of the firmware, as its user set it up (PHD2's
/// hysteresis algorithm; its hysteresis stays 0.1). The default is the
/// guider the firmware's configuration assumes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GuiderSettings {
    pub aggressiveness: f64,
    /// Exposure and guide cycle, s (back to back).
    pub exposure_s: f64,
    /// Smallest correction the guider sends, arcsec (1 px = 1 arcsec).
    pub min_move: f64,
    /// The guide rate the guider's calibration measured over the true one:
    /// its pulses are `correction / (calibration x guide rate)` long.
    pub calibration: f64,
}

impl Default for GuiderSettings {
    fn default() -> Self {
        GuiderSettings {
            aggressiveness: 0.7,
            exposure_s: EXPOSURE_S,
            min_move: 0.2,
            calibration: 1.0,
        }
    }
}

impl GuiderSettings {
    fn exposure_us(&self) -> u64 {
        (self.exposure_s * 1e6) as u64
    }
}

/// What moves the star besides the gear: no periodic error, so no model
/// explains it (wall time; all 0 by default).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Sky {
    /// A constant RA drift, arcsec per minute (polar misalignment,
    /// refraction).
    pub drift_arcsec_per_min: f64,
    /// A random walk (flexure, seeing's slow part): its spread grows by
    /// this many arcsec per square root of a minute, drawn every second
    /// from its own generator (seed + 1000).
    pub walk_arcsec_per_sqrt_min: f64,
    /// A bump: the star steps by this many arcsec at 900 s and back at
    /// 1800 s, and so on every 1800 s (a cable snag, a gust).
    pub bump_arcsec: f64,
}

/// BUMP_PERIOD_S / 2: the bump's half period, s.
const BUMP_HALF_PERIOD_S: f64 = 900.0;

/// Everything a table's runs share besides the case and the noise.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Setup {
    pub guider: GuiderSettings,
    pub sky: Sky,
    /// The firmware's `least_pulse_share` (its default unless set).
    pub least_pulse_share: f32,
    /// The additions the firmware runs (all unless set).
    pub additions: Additions,
}

impl Default for Setup {
    fn default() -> Self {
        Setup {
            guider: GuiderSettings::default(),
            sky: Sky::default(),
            least_pulse_share: MountConfig::default().least_pulse_share,
            additions: Additions::ALL,
        }
    }
}

/// What runs in the firmware.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Firmware {
    /// Tracking and the guider's pulses, no learning.
    GuiderOnly,
    /// `Learner<1>`.
    Ppec,
    /// `Learner<FIRMWARE_STAGES>`.
    Mkgp,
}

enum AnyLearner {
    None,
    One(Box<Learner<1>>),
    Mkgp(Box<Learner<FIRMWARE_STAGES>>),
}

impl AnyLearner {
    /// The frame learned, as the port reports it (the feed-forward in it).
    fn learn(&mut self, f: Frame) -> Option<LearnedFrame> {
        match self {
            AnyLearner::None => None,
            AnyLearner::One(l) => {
                let ff = l.learn(f);
                Some(LearnedFrame::of(l, &f, ff))
            }
            AnyLearner::Mkgp(l) => {
                let ff = l.learn(f);
                Some(LearnedFrame::of(l, &f, ff))
            }
        }
    }
    fn summary(&self) -> LearnerSummary {
        match self {
            AnyLearner::None => LearnerSummary::default(),
            AnyLearner::One(l) => LearnerSummary::of(l),
            AnyLearner::Mkgp(l) => LearnerSummary::of(l),
        }
    }

    fn counters(&self) -> LearnerCounters {
        match self {
            AnyLearner::None => LearnerCounters::default(),
            AnyLearner::One(l) => l.counters(),
            AnyLearner::Mkgp(l) => l.counters(),
        }
    }

    /// The model's own fault counters (none without a learner).
    fn faults(&self) -> Option<Faults> {
        match self {
            AnyLearner::None => None,
            AnyLearner::One(l) => Some(l.guider().faults()),
            AnyLearner::Mkgp(l) => Some(l.guider().faults()),
        }
    }

    fn reset(&mut self) {
        match self {
            AnyLearner::None => {}
            AnyLearner::One(l) => l.reset(),
            AnyLearner::Mkgp(l) => l.reset(),
        }
    }

    /// The model's record for the store: none for the guider alone, nor
    /// while the learner refuses it (a restored model not yet placed).
    fn snapshot(&self) -> Option<Vec<u8>> {
        let mut out = vec![0; RECORD_MAX];
        let n = match self {
            AnyLearner::None => return None,
            AnyLearner::One(l) => l.snapshot(&mut out),
            AnyLearner::Mkgp(l) => l.snapshot(&mut out),
        };
        out.truncate(n.ok()?);
        Some(out)
    }
}

/// The mount used for a case: the default mount with the case's worm.
pub fn mount_config(case: &Case) -> MountConfig {
    let mut c = MountConfig::default();
    if let Some(s) = case.sinusoids.first() {
        c.worm_period_s = s.period_s as f32;
    }
    c
}

/// Extremes of what the controller asked for, and the counters.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Extremes {
    pub ra_min: f32,
    pub ra_max: f32,
    pub dec_abs_max: f32,
    pub non_finite: u32,
}

/// The raw edges due by a wake-up, as the hal's queue would hold them (the
/// simulated queue never overflows).
struct DueEdges<'a> {
    edges: &'a mut VecDeque<(u64, Line, bool)>,
    now_us: u64,
    levels: &'a mut [bool; 4],
}

impl EdgeSource for DueEdges<'_> {
    fn next_edge(&mut self) -> Option<RawEdge> {
        let &(at_us, line, asserted) = self.edges.front()?;
        if at_us > self.now_us {
            return None;
        }
        self.edges.pop_front();
        self.levels[line as usize] = asserted;
        Some(RawEdge {
            line,
            asserted,
            at_us,
        })
    }

    fn queue(&self) -> EdgeQueue {
        EdgeQueue {
            dropped: 0,
            levels: *self.levels,
        }
    }
}

/// The learning task: one frame at a time, each taking [`INFERENCE_US`],
/// and what the library's policy asks around them (a reset, a save).
struct LearningTask {
    learner: AnyLearner,
    policy: LearningPolicy<SimStore>,
    /// The frame queue between the tasks.
    frames: VecDeque<FrameRecord>,
    /// The frame being learned and when its feed-forward is ready.
    busy: Option<(u64, Option<LearnedFrame>)>,
    /// The newest learned frame not yet taken (the board's signal).
    ready: Option<LearnedFrame>,
}

impl LearningTask {
    /// Finishes the inference due by `now_us`, then starts the next; each
    /// frame taken goes to `record`, and when it was taken and whether the
    /// model learned from it to `learned`.
    fn run(&mut self, now_us: u64, record: &mut Vec<Frame>, learned: &mut Vec<FrameLearned>) {
        if self
            .busy
            .as_ref()
            .is_some_and(|(done_us, _)| *done_us > now_us)
        {
            return;
        }
        if let Some((_, learned)) = self.busy.take() {
            if learned.is_some() {
                self.ready = learned;
            }
        }
        if let Some(r) = self.frames.pop_front() {
            record.push(r.frame);
            if self.policy.frame().reset_first {
                self.learner.reset();
            }
            let before = self.learner.counters().learned;
            let frame = self.learner.learn(r.frame);
            learned.push(FrameLearned {
                at_us: now_us,
                learned: self.learner.counters().learned != before,
            });
            let done_us = now_us + INFERENCE_US;
            if let Some(save) = self.policy.learned(done_us) {
                let model = self.learner.snapshot();
                save.storage
                    .save_model(model.as_deref(), save.erase, save.index_pass);
            }
            self.busy = Some((done_us, frame));
        }
    }

    fn next_event_us(&self) -> Option<u64> {
        self.busy.as_ref().map(|(t, _)| *t)
    }
}

/// A frame the learning task took: when, and whether the model learned
/// from it as gear error.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameLearned {
    pub at_us: u64,
    pub learned: bool,
}

/// One exposure of the guide camera, as it ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Exposure {
    pub end_us: u64,
    /// What the guider measures: the mean pointing over the exposure minus
    /// the lock position, plus the camera's noise, arcsec.
    pub measured_arcsec: f64,
    /// The same without the noise: the truth.
    pub pointing_arcsec: f64,
    /// The mean gear error over the exposure, arcsec.
    pub gear_error_arcsec: f64,
}

/// A pulse the guider sent.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SentPulse {
    pub line: Line,
    pub start_us: u64,
    pub duration_us: u64,
}

/// What the guider did with a measurement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Correction {
    /// The guide algorithm's correction, or a dither's amount, arcsec
    /// (positive: RA+, west).
    pub arcsec: f64,
    /// The pulse it sent, if any.
    pub pulse: Option<SentPulse>,
    /// The pulse was a dither's.
    pub dither: bool,
}

/// The virtual rig: mount, camera, guider and the firmware.
pub struct Rig {
    pub mount: Mount,
    pub case: Case,
    control: ControlLoop,
    ra: AxisStepper,
    dec: AxisStepper,
    learning: LearningTask,
    pub now_us: u64,
    rates: Rates,
    /// Raw edges still to come, sorted by time.
    edges: VecDeque<(u64, Line, bool)>,
    levels: [bool; 4],
    /// The guider: its settings, its hysteresis, noise, whether it answers
    /// at all.
    guider: GuiderSettings,
    hysteresis: Hysteresis,
    noise: Option<(f64, Gaussian)>,
    pub guider_on: bool,
    /// The guider's lock position (arcsec of pointing error it aims at).
    pub lock_arcsec: f64,
    /// The gear's phase: its error at gear time `t` is the case's at
    /// `t + gear_phase_s` (0: the gear starts where the case does; another
    /// night starts elsewhere, `crate::nights`).
    pub gear_phase_s: f64,
    /// The mount pushed by hand with the clutch released: the star moves by
    /// this much, arcsec, with no step (0 unless `crate::night` pushes it).
    pub hand_arcsec: f64,
    /// The score covers these seconds of the run, [from, until).
    pub score_window_s: (f64, f64),
    /// What moves the star besides the gear, and the random walk so far
    /// (arcsec) with its generator.
    sky: Sky,
    walk: (f64, Gaussian),
    /// A dither the guider sends with its next pulse: amount, arcsec.
    dither_next: Option<f64>,
    exposure_sum: f64,
    exposure_gear_sum: f64,
    exposure_n: u32,
    next_exposure_end_us: u64,
    /// The camera waits this long between exposures (0: back to back).
    frame_gap_us: u64,
    /// The exposure that ended last, until taken ([`Rig::take_exposure`]).
    exposure: Option<Exposure>,
    last_pulse_end_us: u64,
    score_sq: f64,
    score_n: u64,
    pub extremes: Extremes,
    /// Every frame the learner took (for tests).
    pub frames: Vec<Frame>,
    /// For each of them, when it was taken and whether it was learned.
    pub frames_learned: Vec<FrameLearned>,
    /// Every feed-forward installed (for tests): (time us, rate).
    pub feed_forwards: Vec<(u64, f32)>,
    /// The newest learned frame the guiding task took, for the command
    /// ports' telemetry ([`Rig::take_learned`]).
    learned: Option<LearnedFrame>,
}

impl Rig {
    pub fn new(case: &Case, firmware: Firmware, noise_px: f64, seed: u64) -> Self {
        Self::with_mount(case, firmware, noise_px, seed, mount_config(case))
    }

    pub fn with_mount(
        case: &Case,
        firmware: Firmware,
        noise_px: f64,
        seed: u64,
        config: MountConfig,
    ) -> Self {
        Self::with_additions(case, firmware, noise_px, seed, config, Additions::ALL)
    }

    /// [`with_mount`](Self::with_mount) with some of the firmware's
    /// `additions` switched off (the learner's and the loop's fast part's).
    pub fn with_additions(
        case: &Case,
        firmware: Firmware,
        noise_px: f64,
        seed: u64,
        config: MountConfig,
        additions: Additions,
    ) -> Self {
        let mount = config.validate().unwrap_or_else(|e| panic!("{e}"));
        let learner = match firmware {
            Firmware::GuiderOnly => AnyLearner::None,
            Firmware::Ppec => AnyLearner::One(Box::new(Learner::with_additions(&mount, additions))),
            Firmware::Mkgp => {
                AnyLearner::Mkgp(Box::new(Learner::with_additions(&mount, additions)))
            }
        };
        let tick_hz = mount.config().step_tick_hz;
        let mut ra = AxisStepper::new(mount.max_ra_steps_per_s(), tick_hz);
        let mut dec = AxisStepper::new(mount.max_dec_steps_per_s(), tick_hz);
        let (control, rates) = ControlLoop::start_with(&mount, additions, 0, 0);
        ra.set_rate(rates.ra_steps_per_s);
        dec.set_rate(rates.dec_steps_per_s);
        let mut rig = Rig {
            control,
            ra,
            dec,
            mount,
            case: case.clone(),
            learning: LearningTask {
                learner,
                policy: LearningPolicy::without_store(),
                frames: VecDeque::new(),
                busy: None,
                ready: None,
            },
            now_us: 0,
            rates: Rates::default(),
            edges: VecDeque::new(),
            levels: [false; 4],
            guider: GuiderSettings::default(),
            hysteresis: Hysteresis::phd2_baseline(),
            noise: (noise_px > 0.0).then(|| (noise_px, noise::for_run(seed))),
            guider_on: true,
            lock_arcsec: 0.0,
            gear_phase_s: 0.0,
            hand_arcsec: 0.0,
            score_window_s: (SCORE_FROM_S, f64::INFINITY),
            sky: Sky::default(),
            walk: (0.0, noise::walk(seed)),
            dither_next: None,
            exposure_sum: 0.0,
            exposure_gear_sum: 0.0,
            exposure_n: 0,
            next_exposure_end_us: GuiderSettings::default().exposure_us(),
            frame_gap_us: 0,
            exposure: None,
            last_pulse_end_us: 0,
            score_sq: 0.0,
            score_n: 0,
            extremes: Extremes {
                ra_min: f32::INFINITY,
                ra_max: f32::NEG_INFINITY,
                ..Extremes::default()
            },
            frames: Vec::new(),
            frames_learned: Vec::new(),
            feed_forwards: Vec::new(),
            learned: None,
        };
        rig.note_rates(rates);
        rig
    }

    /// Sets up the guider; call before the run starts.
    pub fn set_guider(&mut self, guider: GuiderSettings) {
        self.hysteresis = Hysteresis::new(guider.aggressiveness, 0.1, guider.min_move);
        self.next_exposure_end_us = self.now_us + guider.exposure_us();
        self.guider = guider;
    }

    /// A guider started afresh now (no memory of an earlier one: its
    /// hysteresis starts from nothing), whose camera exposes for
    /// `guider.exposure_s` every `interval_s` (at least the exposure), the
    /// first exposure starting now.
    pub fn start_guider(&mut self, guider: GuiderSettings, interval_s: f64) {
        self.set_guider(guider);
        self.dither_next = None;
        let interval_us = (interval_s * 1e6) as u64;
        self.frame_gap_us = interval_us.saturating_sub(guider.exposure_us());
        self.hold_camera(self.now_us);
    }

    /// The camera takes no exposure before `until_us` (the guider waits for
    /// a pulse, or pauses): the next one starts then.
    pub fn hold_camera(&mut self, until_us: u64) {
        self.next_exposure_end_us = until_us.max(self.now_us) + self.guider.exposure_us();
        self.exposure_sum = 0.0;
        self.exposure_gear_sum = 0.0;
        self.exposure_n = 0;
        self.exposure = None;
    }

    /// When the exposure under way ends, us.
    pub fn next_exposure_end_us(&self) -> u64 {
        self.next_exposure_end_us
    }

    /// The exposure that ended last, once (the guider's own measurement
    /// happens whether or not `guider_on`).
    pub fn take_exposure(&mut self) -> Option<Exposure> {
        self.exposure.take()
    }

    /// Runs until the exposure under way has been taken (at the first
    /// pointing sample at or after its end), or until `limit_us`.
    pub fn run_to_exposure(&mut self, limit_us: u64) -> Option<Exposure> {
        let end = self.next_exposure_end_us.div_ceil(SAMPLE_US) * SAMPLE_US;
        self.run_until(end.min(limit_us));
        self.take_exposure()
    }

    /// Sets what moves the star besides the gear; call before the run.
    pub fn set_sky(&mut self, sky: Sky) {
        self.sky = sky;
    }

    /// The star's motion besides the gear at the current time, arcsec.
    fn sky_arcsec(&self) -> f64 {
        let t = self.now_us as f64 * 1e-6;
        let bump = if (t / BUMP_HALF_PERIOD_S) as u64 % 2 == 1 {
            self.sky.bump_arcsec
        } else {
            0.0
        };
        self.sky.drift_arcsec_per_min * t / 60.0 + self.walk.0 + bump
    }

    /// The share of the RA guide pulses the MKGP learner carries out now.
    pub fn pulse_share(&self) -> f32 {
        match &self.learning.learner {
            AnyLearner::Mkgp(l) => l.pulse_share(),
            AnyLearner::One(l) => l.pulse_share(),
            AnyLearner::None => 1.0,
        }
    }

    /// The part of a guide pulse the learner takes for gear error.
    pub fn pulse_weight(&self) -> f32 {
        match &self.learning.learner {
            AnyLearner::Mkgp(l) => l.pulse_weight(),
            AnyLearner::One(l) => l.pulse_weight(),
            AnyLearner::None => 1.0,
        }
    }

    pub fn learner_counters(&self) -> LearnerCounters {
        self.learning.learner.counters()
    }

    /// The firmware's learner (`Firmware::Mkgp`), e.g. to save
    /// or restore its model.
    pub fn mkgp_learner(&mut self) -> Option<&mut Learner<FIRMWARE_STAGES>> {
        match &mut self.learning.learner {
            AnyLearner::Mkgp(l) => Some(l),
            _ => None,
        }
    }

    /// What the learner knows now, for the command port.
    /// The newest frame learned since the last call: the board's guiding
    /// task sends its telemetry line to the ports that asked.
    pub fn take_learned(&mut self) -> Option<LearnedFrame> {
        self.learned.take()
    }

    /// A model reset asked on a command port: the learning task carries it
    /// out before its next frame, as on the board.
    pub fn reset_model(&mut self) {
        self.learning.policy.ask_reset();
    }

    /// Gives the firmware `store` from now on (an erased one, or what an
    /// earlier rig left in it): the learning task saves the model into it
    /// as the policy asks (every `SAVE_EVERY_US`, never erasing) and
    /// serves the ports' requests ([`Rig::ask_store`]). Not parked: the
    /// rig's counters start at 0.
    pub fn set_store(&mut self, store: SimStore) {
        let index = WormIndex::new(&self.mount);
        self.learning.policy = LearningPolicy::with_store(store, false, index, self.now_us);
    }

    /// What [`Rig::set_store`] gave, with what was saved into it since.
    pub fn store(&mut self) -> Option<&mut SimStore> {
        self.learning.policy.storage()
    }

    /// A port's request to the store, served now (the board's learning
    /// task serves it between frames; here a frame is learned at once).
    pub fn ask_store(&mut self, request: StoreRequest) -> StoreOutcome {
        let learning = &mut self.learning;
        match learning.policy.store_request(request) {
            StoreStep::Serve {
                storage,
                request,
                index_pass,
            } => {
                let model = learning.learner.snapshot();
                storage.serve(model.as_deref(), request, index_pass)
            }
            StoreStep::Refuse(outcome) => outcome,
        }
    }

    pub fn learner_summary(&self) -> LearnerSummary {
        self.learning.learner.summary()
    }

    /// Bytes received on a command port now: `port` carries them out on
    /// this mount through the firmware's own `PortMount` (the loop, the
    /// steppers' counts), with the learner's summary as of now. A motion
    /// they start takes effect at the loop's next wake-up, as on the board.
    pub fn feed_port(
        &mut self,
        port: &mut Interpreter,
        state: &mut PortState,
        bytes: &[u8],
        out: &mut impl ReplySink,
    ) {
        state.learner = self.learner_summary();
        let mut mount = PortMount {
            control: &mut self.control,
            state,
            now_us: self.now_us,
            steps: StepCounts {
                ra: self.ra.steps(),
                dec: self.dec.steps(),
            },
            port: 0,
        };
        port.feed(bytes, self.now_us, &mut mount, out);
    }

    pub fn guiding_counters(&self) -> GuidingCounters {
        self.control.guiding().counters()
    }

    pub fn st4_counters(&self) -> St4Counters {
        self.control.st4_counters()
    }

    /// The model's own fault counters (none for the guider alone).
    pub fn model_faults(&self) -> Option<Faults> {
        self.learning.learner.faults()
    }

    /// What the command port's motion did and refused.
    pub fn port_counters(&self) -> PortMotionCounters {
        self.control.port_counters()
    }

    /// ST4 edges a full queue lost (none in the simulation, whose queue
    /// never overflows; counted by the loop all the same).
    pub fn lost_edges(&self) -> u32 {
        self.control.lost_edges()
    }

    /// The firmware's guiding state (feed-forward, silence).
    pub fn guiding(&self) -> &Guiding {
        self.control.guiding()
    }

    /// The rates the loop asked for last.
    pub fn rates(&self) -> Rates {
        self.rates
    }

    pub fn ra_steps(&self) -> i64 {
        self.ra.steps()
    }

    pub fn dec_steps(&self) -> i64 {
        self.dec.steps()
    }

    /// The applied correction C (steps beyond sidereal, arcsec) now.
    pub fn applied_arcsec(&self) -> f64 {
        let a = SIDEREAL_ARCSEC_PER_S / self.mount.sidereal_ra_steps_per_s_f64();
        self.ra_steps() as f64 * a - SIDEREAL_ARCSEC_PER_S * self.now_us as f64 * 1e-6
    }

    /// Gear time now: RA steps / sidereal steps per second, s.
    pub fn gear_time_s(&self) -> f64 {
        self.ra_steps() as f64 / self.mount.sidereal_ra_steps_per_s_f64()
    }

    /// The gear error now, arcsec.
    pub fn gear_error_arcsec(&self) -> f64 {
        self.case.gear_error(self.gear_time_s() + self.gear_phase_s)
    }

    /// The pointing error now: the axis' lag behind the sky, arcsec.
    pub fn pointing_arcsec(&self) -> f64 {
        self.pointing_with(self.gear_error_arcsec())
    }

    /// The pointing error with the gear error `gear_arcsec`.
    fn pointing_with(&self, gear_arcsec: f64) -> f64 {
        gear_arcsec - self.applied_arcsec() + self.sky_arcsec() + self.hand_arcsec
    }

    /// The Dec axis' steps since the start, arcsec (no Dec error is
    /// modelled: only the guider's Dec pulses and the port's motion move it).
    pub fn dec_arcsec(&self) -> f64 {
        self.dec_steps() as f64 * 3600.0 / self.mount.config().dec_steps_per_degree as f64
    }

    /// Residual RMS over the scored samples so far.
    pub fn score(&self) -> f64 {
        (self.score_sq / self.score_n.max(1) as f64).sqrt()
    }

    /// The sum of the squared residuals scored so far, and their number.
    pub fn score_sums(&self) -> (f64, u64) {
        (self.score_sq, self.score_n)
    }

    /// A raw edge at `at_us` (not before now).
    pub fn edge(&mut self, line: Line, asserted: bool, at_us: u64) {
        let at = at_us.max(self.now_us);
        let i = self.edges.partition_point(|e| e.0 <= at);
        self.edges.insert(i, (at, line, asserted));
    }

    /// A pulse on `line` from `start_us` for `duration_us`.
    pub fn pulse(&mut self, line: Line, start_us: u64, duration_us: u64) {
        self.edge(line, true, start_us);
        self.edge(line, false, start_us + duration_us);
    }

    /// The guider dithers by `amount_arcsec` with its next pulse: one long
    /// RA pulse of amount / guide rate, and the lock position moves by the
    /// amount (positive amount: RA+, the mount moves ahead).
    pub fn dither(&mut self, amount_arcsec: f64) {
        self.dither_next = Some(amount_arcsec);
    }

    /// The next time anything happens: a wake-up of the guiding task (an
    /// edge, or the loop's own), the learner finishing, or a sample.
    fn next_event_us(&self, end_us: u64) -> u64 {
        let sample = (self.now_us / SAMPLE_US + 1) * SAMPLE_US;
        let mut t = sample.min(end_us).min(self.control.next_wake_us());
        if let Some(&(at, _, _)) = self.edges.front() {
            t = t.min(at);
        }
        if let Some(at) = self.learning.next_event_us() {
            t = t.min(at);
        }
        t.max(self.now_us + 1)
    }

    /// Run the loop until `end_us`.
    pub fn run_until(&mut self, end_us: u64) {
        while self.now_us < end_us {
            let t = self.next_event_us(end_us);
            self.advance_steppers(t);
            self.now_us = t;
            self.learning
                .run(t, &mut self.frames, &mut self.frames_learned);
            let edge_due = self.edges.front().is_some_and(|e| e.0 <= t);
            if edge_due || t >= self.control.next_wake_us() {
                self.guiding_task();
                self.learning
                    .run(t, &mut self.frames, &mut self.frames_learned);
            }
            if t.is_multiple_of(SAMPLE_US) {
                self.sample();
            }
        }
    }

    /// The step ticks in (now, t].
    fn advance_steppers(&mut self, t: u64) {
        let hz = u128::from(self.ra.tick_hz());
        let ticks_by = |us: u64| (u128::from(us) * hz / 1_000_000) as u64;
        let ticks = ticks_by(t) - ticks_by(self.now_us);
        self.ra.advance(ticks);
        self.dec.advance(ticks);
    }

    /// One wake-up of the board's guiding task.
    fn guiding_task(&mut self) {
        let now = self.now_us;
        let mut due = DueEdges {
            edges: &mut self.edges,
            now_us: now,
            levels: &mut self.levels,
        };
        let learned = self.learning.ready.take();
        let ff = learned.as_ref().map(|l| l.feed_forward);
        let wake = self.control.wake(now, self.ra.steps(), &mut due, ff);
        if let Some(ff) = ff {
            self.feed_forwards.push((now, ff.rate_arcsec_per_s));
        }
        if learned.is_some() {
            self.learned = learned;
        }
        if let Some(r) = wake.rates {
            self.ra.set_rate(r.ra_steps_per_s);
            self.dec.set_rate(r.dec_steps_per_s);
            self.note_rates(r);
        }
        while self.learning.frames.len() < FRAME_QUEUE {
            let Some(record) = self.control.take_frame() else {
                break;
            };
            self.learning.frames.push_back(record);
        }
    }

    fn note_rates(&mut self, r: Rates) {
        let e = &mut self.extremes;
        if !(r.ra_steps_per_s.is_finite() && r.dec_steps_per_s.is_finite()) {
            e.non_finite += 1;
        }
        e.ra_min = e.ra_min.min(r.ra_steps_per_s);
        e.ra_max = e.ra_max.max(r.ra_steps_per_s);
        e.dec_abs_max = e.dec_abs_max.max(r.dec_steps_per_s.abs());
        self.rates = r;
    }

    /// The pointing sample: score, exposure, and the guider at the end of an
    /// exposure.
    fn sample(&mut self) {
        if self.sky.walk_arcsec_per_sqrt_min > 0.0 && self.now_us.is_multiple_of(1_000_000) {
            let (walk, g) = &mut self.walk;
            *walk += self.sky.walk_arcsec_per_sqrt_min / 60f64.sqrt() * g.next();
        }
        let gear = self.gear_error_arcsec();
        let p = self.pointing_with(gear);
        let t = self.now_us as f64 * 1e-6;
        if (self.score_window_s.0..self.score_window_s.1).contains(&t) {
            let r = p - self.lock_arcsec;
            self.score_sq += r * r;
            self.score_n += 1;
        }
        let exposure_us = self.guider.exposure_us();
        // Within the exposure: (its end - its length, its end].
        if self.now_us + exposure_us > self.next_exposure_end_us {
            self.exposure_sum += p;
            self.exposure_gear_sum += gear;
            self.exposure_n += 1;
        }
        if self.now_us >= self.next_exposure_end_us {
            let n = self.exposure_n.max(1) as f64;
            let mean = self.exposure_sum / n;
            let pointing = mean - self.lock_arcsec;
            let gear_error = self.exposure_gear_sum / n;
            self.exposure_sum = 0.0;
            self.exposure_gear_sum = 0.0;
            self.exposure_n = 0;
            self.next_exposure_end_us += exposure_us + self.frame_gap_us;
            let noise = match self.noise.as_mut() {
                Some((sigma, g)) => *sigma * g.next(),
                None => 0.0,
            };
            let measured = mean - self.lock_arcsec + noise;
            self.exposure = Some(Exposure {
                end_us: self.now_us,
                measured_arcsec: measured,
                pointing_arcsec: pointing,
                gear_error_arcsec: gear_error,
            });
            if self.guider_on {
                self.guide(measured);
            }
        }
    }

    /// When the guider's last pulse ends, us.
    pub fn pulses_end_us(&self) -> u64 {
        self.last_pulse_end_us
    }

    /// The rate the guider believes in, arcsec/s.
    pub fn believed_guide_rate(&self) -> f64 {
        self.mount.guide_rate_arcsec_per_s() as f64 * self.guider.calibration
    }

    /// The guider sends a pulse on `line` as soon as it can after the
    /// exposure that just ended: [`LATENCY_US`] on, after the pulse before
    /// it.
    pub fn send_pulse(&mut self, line: Line, duration_us: u64) -> SentPulse {
        let start_us = (self.now_us + LATENCY_US).max(self.last_pulse_end_us + PULSE_GAP_US);
        self.pulse(line, start_us, duration_us);
        self.last_pulse_end_us = start_us + duration_us;
        SentPulse {
            line,
            start_us,
            duration_us,
        }
    }

    /// The guider's answer to the exposure that just ended, measured
    /// `measured` arcsec from the lock: the dither asked for, or the guide
    /// algorithm's correction as an RA pulse (none below its minimum move).
    pub fn guide(&mut self, measured: f64) -> Correction {
        let guide_rate = self.believed_guide_rate();
        let ra_line = |x: f64| if x > 0.0 { Line::RaPlus } else { Line::RaMinus };
        if let Some(amount) = self.dither_next.take() {
            let dur = (amount.abs() / guide_rate * 1e6) as u64;
            let pulse = self.send_pulse(ra_line(amount), dur);
            // The mount moves ahead by the amount: the lag drops by it.
            self.lock_arcsec -= amount;
            return Correction {
                arcsec: amount,
                pulse: Some(pulse),
                dither: true,
            };
        }
        let control = self
            .hysteresis
            .step(0.0, measured, 10.0, self.guider.exposure_s);
        let dur = ((control.abs() / guide_rate * 1e6) as u64).min(MAX_PULSE_US);
        let pulse = (dur > 0).then(|| self.send_pulse(ra_line(control), dur));
        Correction {
            arcsec: control,
            pulse,
            dither: false,
        }
    }
}

/// One run's outcome.
#[derive(Debug, Clone, Copy)]
pub struct RunResult {
    pub rms: f64,
    pub extremes: Extremes,
    pub guiding: GuidingCounters,
    pub learner: LearnerCounters,
    pub st4: St4Counters,
    /// The learner's pulse weight at the end.
    pub pulse_weight: f32,
}

/// One full run behind the default guider: `noise_px` 0 is noise-free (the
/// seed is then unused).
pub fn run(case: &Case, firmware: Firmware, noise_px: f64, seed: u64) -> RunResult {
    run_with(case, firmware, noise_px, seed, Setup::default())
}

/// [`run`] in `setup`.
pub fn run_with(
    case: &Case,
    firmware: Firmware,
    noise_px: f64,
    seed: u64,
    setup: Setup,
) -> RunResult {
    let config = MountConfig {
        least_pulse_share: setup.least_pulse_share,
        ..mount_config(case)
    };
    run_on(case, firmware, noise_px, seed, setup, config)
}

/// [`run_with`] on a mount configured as `config` (its `least_pulse_share`
/// is the one used, not `setup`'s).
pub fn run_on(
    case: &Case,
    firmware: Firmware,
    noise_px: f64,
    seed: u64,
    setup: Setup,
    config: MountConfig,
) -> RunResult {
    let mut rig = Rig::with_additions(case, firmware, noise_px, seed, config, setup.additions);
    rig.set_guider(setup.guider);
    rig.set_sky(setup.sky);
    rig.run_until((RUN_S * 1e6) as u64);
    RunResult {
        rms: rig.score(),
        extremes: rig.extremes,
        guiding: rig.guiding_counters(),
        learner: rig.learner_counters(),
        st4: rig.st4_counters(),
        pulse_weight: rig.pulse_weight(),
    }
}

/// One row of the table.
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    pub case: String,
    pub noise_px: f64,
    pub guider_only: f64,
    pub fw_ppec: f64,
    pub fw_mkgp: f64,
}

pub const CSV_HEADER: &str = "case,noise_px,guider_only,fw_ppec,fw_mkgp";

/// Mean pointing RMS of `firmware` on `case` with `noise_px` of noise (0:
/// one noise-free run; else the mean over [`SEEDS`], added in seed order).
fn mean_rms(case: &Case, firmware: Firmware, noise_px: f64, setup: Setup) -> f64 {
    let seeds: &[u64] = if noise_px > 0.0 { &SEEDS } else { &SEEDS[..1] };
    let rms: Vec<f64> = seeds
        .par_iter()
        .map(|&seed| run_with(case, firmware, noise_px, seed, setup).rms)
        .collect();
    rms.iter().sum::<f64>() / rms.len() as f64
}

/// The table for `cases` and noise levels behind the default guider, one
/// row per case and level in that order; the runs are spread over rayon's
/// threads.
pub fn table(cases: &[Case], noise_levels: &[f64]) -> Vec<Row> {
    table_with(cases, noise_levels, Setup::default())
}

/// [`table`] in `setup`.
pub fn table_with(cases: &[Case], noise_levels: &[f64], setup: Setup) -> Vec<Row> {
    let rows: Vec<(&Case, f64)> = cases
        .iter()
        .flat_map(|case| noise_levels.iter().map(move |&noise| (case, noise)))
        .collect();
    rows.into_par_iter()
        .map(|(case, noise)| {
            let firmware = |fw| mean_rms(case, fw, noise, setup);
            let (guider_only, (fw_ppec, fw_mkgp)) = rayon::join(
                || firmware(Firmware::GuiderOnly),
                || rayon::join(|| firmware(Firmware::Ppec), || firmware(Firmware::Mkgp)),
            );
            Row {
                case: case.name.clone(),
                noise_px: noise,
                guider_only,
                fw_ppec,
                fw_mkgp,
            }
        })
        .collect()
}
