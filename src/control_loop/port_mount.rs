//! The command port's [`MountPort`] on top of [`ControlLoop`]: the one
//! implementation the firmware and the simulator share. The interpreter's
//! `feed` is given a [`PortMount`], a view for the moment of the call (the
//! loop, the port's own state, the time and the step counters then).
//!
//! - Guide pulses, manual motion, stops and tracking go to the loop
//!   (`port_motion`): a port pulse takes the ST4 pulse's path.
//! - Position: a sync (`:CM#`) notes where the mount points, the step
//!   counters and the time; from then on RA and Dec follow the counters.
//!   RA holds still under sidereal tracking and moves by the steps beyond
//!   it: the RA axis turning faster than the sky (a west pulse) points the
//!   telescope further west, at a smaller RA, hence the minus sign. Dec
//!   moves with the Dec steps (north positive).
//! - Learning, stages and the learner's counters: the learner runs in
//!   another task, so the caller keeps a [`LearnerSummary`] up to date
//!   after each frame it learned; a model reset asked on the port is a
//!   request the caller takes ([`PortState::take_reset_request`]).

use heapless::{Deque, Vec};

use crate::control_loop::ControlLoop;
use crate::counters::Counters;
use crate::model::guider::Faults;
use crate::model::numeric::clamp;
use crate::mount::config::{Mount, MountConfig, SIDEREAL_ARCSEC_PER_S};
use crate::mount::frame::{FeedForward, Frame, FrameKind};
use crate::mount::guiding::GuidingCounters;
use crate::mount::learner::{Learner, LearnerCounters};
use crate::persist::StoreCounters;
use crate::port::coords::{Dec, Equatorial, Ra};
use crate::port::mount_port::{
    Axis, Counter, CounterGroup, GuidePulse, Identity, Learning, Line, ManualRate, ModelOrigin,
    MountPort, PecState, Stage, Status, StepCounts,
};
use crate::port::telemetry::TelemetryFrame;
use crate::safety::reset_cause::ResetCause;

/// Stages a [`LearnerSummary`] holds (the firmware's model has two).
pub const MAX_STAGES: usize = 4;

/// What the learner knew after its last frame, in the port's units.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct LearnerSummary {
    /// Learning progress, 0..=1000.
    pub learned_permille: u16,
    /// The stages found so far, in order.
    pub stages: Vec<Stage, MAX_STAGES>,
    pub counters: LearnerCounters,
    /// The model's own faults (bad input, failed factorisations, ...).
    pub faults: Faults,
}

impl LearnerSummary {
    /// What `learner` knows now. The model does not expose a stage's
    /// amplitude yet: it reads 0.
    pub fn of<const N: usize>(learner: &Learner<N>) -> Self {
        let g = learner.guider();
        let mut stages = Vec::new();
        for i in 0..N {
            let period_s = g.period_s(i);
            // A stage not found yet has a NaN period: none, and none after.
            if !period_s.is_finite() {
                break;
            }
            let stage = Stage {
                // Saturating casts: a period is seconds to hours.
                period_ms: libm::round(period_s * 1000.0) as u32,
                amplitude_mas: 0,
                gate_permille: libm::round(clamp(g.gate(i), 0.0, 1.0) * 1000.0) as u16,
            };
            if stages.push(stage).is_err() {
                break;
            }
        }
        LearnerSummary {
            learned_permille: libm::round(clamp(g.learning_progress(), 0.0, 1.0) * 1000.0) as u16,
            stages,
            counters: learner.counters(),
            faults: g.faults(),
        }
    }
}

/// Arcseconds to milliarcseconds, rounded; the cast saturates and a NaN
/// reads 0.
fn mas(arcsec: f64) -> i32 {
    libm::round(arcsec * 1000.0) as i32
}

/// A frame the learner has just learned, as the port reports it: the
/// summary its queries answer from, and the telemetry line's values.
#[derive(Clone, Debug, PartialEq)]
pub struct LearnedFrame {
    pub summary: LearnerSummary,
    /// The feed-forward the learner returned for the frame.
    pub feed_forward: FeedForward,
    pub gear_time_s: f64,
    /// The frame as the guiding task made it.
    pub kind: FrameKind,
    pub filled: bool,
    /// The frame's observed gear error, arcsec.
    pub observation_arcsec: f32,
    /// The correction the guider's pulse asked for, arcsec.
    pub pulse_arcsec: f32,
    /// The mean correction applied over the frame, arcsec.
    pub applied_arcsec: f32,
    /// The model's predicted change of the gear error over the next
    /// frame, arcsec.
    pub prediction_arcsec: f32,
}

impl LearnedFrame {
    /// `frame` as `learner` has just learned it, with the feed-forward it
    /// returned.
    pub fn of<const N: usize>(
        learner: &Learner<N>,
        frame: &Frame,
        feed_forward: FeedForward,
    ) -> Self {
        LearnedFrame {
            summary: LearnerSummary::of(learner),
            feed_forward,
            gear_time_s: frame.gear_time_s,
            kind: frame.kind,
            filled: frame.filled,
            observation_arcsec: frame.gear_error_arcsec,
            pulse_arcsec: frame.pulse_arcsec,
            applied_arcsec: frame.applied_arcsec,
            prediction_arcsec: learner.guider().prediction(),
        }
    }

    /// The telemetry line's values, sent at `time_us` (the board's clock).
    pub fn telemetry(&self, time_us: u64) -> TelemetryFrame<'_> {
        TelemetryFrame {
            time_ms: time_us / 1000,
            // Saturating, NaN to 0: gear time is never negative.
            gear_time_ms: libm::round(self.gear_time_s * 1000.0) as u64,
            kind: match self.kind {
                FrameKind::Measured if self.filled => b'f',
                FrameKind::Measured => b'm',
                FrameKind::Unmeasured => b'u',
                FrameKind::Moved => b's',
                FrameKind::Calibration => b'c',
                FrameKind::Dither { .. } => b'd',
            },
            observation_mas: mas(self.observation_arcsec.into()),
            pulse_mas: mas(self.pulse_arcsec.into()),
            applied_mas: mas(self.applied_arcsec.into()),
            prediction_mas: mas(self.prediction_arcsec.into()),
            feed_forward_mas_per_s: mas(self.feed_forward.rate_arcsec_per_s.into()),
            learned_permille: self.summary.learned_permille,
            stages: &self.summary.stages,
        }
    }
}

/// What the port asked of the store, for the caller that owns it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StoreRequest {
    /// Save this configuration (`:~KW#` on port `port`, whose reply waits
    /// for the outcome); the next start uses it.
    Config { config: MountConfig, port: usize },
    /// Save the learned model now (`:~W#` on port `port`, as above).
    Model { port: usize },
    /// Parked with the axes at these counts (`:hP#`): save them and the
    /// model.
    Park(StepCounts),
    /// Unparked (`:hR#`): the saved counts no longer say where the worm is.
    Unpark,
}

impl StoreRequest {
    /// The port whose reply waits for this request's outcome.
    pub fn reply_to(&self) -> Option<usize> {
        match *self {
            StoreRequest::Config { port, .. } | StoreRequest::Model { port } => Some(port),
            StoreRequest::Park(_) | StoreRequest::Unpark => None,
        }
    }
}

/// What became of a store request, for the caller that serves the ports:
/// the reply of the port that asked ([`Interpreter::store_done`]) and the
/// store's counters for the port's queries.
///
/// [`Interpreter::store_done`]: crate::port::Interpreter::store_done
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StoreOutcome {
    pub reply_to: Option<usize>,
    /// Saved, and read back as written.
    pub saved: bool,
    pub counters: StoreCounters,
}

/// Store requests waiting for the caller: a burst of commands fits.
const STORE_REQUESTS: usize = 4;

/// Where a sync put the mount: the coordinates and the counters then.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct SyncPoint {
    at: Equatorial,
    steps: StepCounts,
    at_us: u64,
}

/// The port's state beside the loop: the sync, the learner's summary,
/// what identifies the firmware.
#[derive(Clone, Debug)]
pub struct PortState {
    sync: Option<SyncPoint>,
    /// RA arcsec per step, sidereal steps per second, Dec arcsec per step.
    ra_arcsec_per_step: f64,
    sidereal_sps: f64,
    dec_arcsec_per_step: f64,
    pub learner: LearnerSummary,
    pub identity: Identity,
    pub reset_cause: ResetCause,
    reset_requested: bool,
    /// The configuration a save stores and the next start uses.
    pending: MountConfig,
    /// The caller has a store that takes [`PortState::take_store_request`]'s
    /// requests; without one the saves are refused.
    pub store: bool,
    requests: Deque<StoreRequest, STORE_REQUESTS>,
    /// Parked (`:hP#`): no motion from the port until unparked.
    pub parked: bool,
    /// Where the model came from at start-up (the caller's to set).
    pub model_origin: ModelOrigin,
    /// The store's counters, as the last [`StoreOutcome`] brought them.
    pub store_counters: StoreCounters,
}

impl PortState {
    pub fn new(mount: &Mount, identity: Identity, reset_cause: ResetCause) -> Self {
        let sidereal_sps = mount.sidereal_ra_steps_per_s_f64();
        PortState {
            sync: None,
            ra_arcsec_per_step: SIDEREAL_ARCSEC_PER_S / sidereal_sps,
            sidereal_sps,
            dec_arcsec_per_step: f64::from(mount.arcsec_per_dec_step()),
            learner: LearnerSummary::default(),
            identity,
            reset_cause,
            reset_requested: false,
            pending: *mount.config(),
            store: false,
            requests: Deque::new(),
            parked: false,
            model_origin: ModelOrigin::Cold,
            store_counters: StoreCounters::default(),
        }
    }

    /// The oldest request for the store not yet taken.
    pub fn take_store_request(&mut self) -> Option<StoreRequest> {
        self.requests.pop_front()
    }

    /// Queues `request` if there is a store and room.
    fn ask_store(&mut self, request: StoreRequest) -> bool {
        self.store && self.requests.push_back(request).is_ok()
    }

    /// Whether a model reset was asked since the last call (`:~R#`).
    pub fn take_reset_request(&mut self) -> bool {
        core::mem::take(&mut self.reset_requested)
    }

    /// Where the mount points at `now_us` with the counters at `steps`:
    /// the sync moved by the steps since (before any sync, 0h 0° at the
    /// first question).
    pub fn position(&mut self, steps: StepCounts, now_us: u64) -> Equatorial {
        let sync = *self.sync.get_or_insert(SyncPoint {
            at: Equatorial::default(),
            steps,
            at_us: now_us,
        });
        let dt_s = now_us.saturating_sub(sync.at_us) as f64 * 1e-6;
        let beyond_tracking =
            steps.ra.wrapping_sub(sync.steps.ra) as f64 - self.sidereal_sps * dt_s;
        // 15 arcsec of rotation per second of RA.
        let ra_s =
            f64::from(sync.at.ra.seconds()) - beyond_tracking * self.ra_arcsec_per_step / 15.0;
        let dec_arcsec = f64::from(sync.at.dec.arcsec())
            + steps.dec.wrapping_sub(sync.steps.dec) as f64 * self.dec_arcsec_per_step;
        // Rounded to the nearest second; the casts saturate (a NaN is 0).
        let ra = Ra::wrapping_from_seconds(libm::round(ra_s) as i64);
        let limit = 90.0 * 3600.0;
        let dec_arcsec = libm::round(clamp(dec_arcsec, -limit, limit)) as i32;
        let dec = Dec::from_arcsec(dec_arcsec).unwrap_or_default();
        Equatorial { ra, dec }
    }

    /// From now on the mount points at `to`.
    pub fn sync(&mut self, to: Equatorial, steps: StepCounts, now_us: u64) {
        self.sync = Some(SyncPoint {
            at: to,
            steps,
            at_us: now_us,
        });
    }
}

/// The mount as the port sees it at one moment: hand it to
/// `Interpreter::feed` with the time and the counters of that moment.
pub struct PortMount<'a> {
    pub control: &'a mut ControlLoop,
    pub state: &'a mut PortState,
    pub now_us: u64,
    pub steps: StepCounts,
    /// The port being served (the index its store outcomes come back to).
    pub port: usize,
}

/// The faults group: edges the ST4 queue lost, the model's faults, then
/// the store's.
fn fault_counter(
    lost_edges: u32,
    f: &Faults,
    store: &StoreCounters,
    index: usize,
) -> Option<(&'static str, u32)> {
    let model = index.checked_sub(1);
    let store_index = model.and_then(|i| i.checked_sub(Faults::NAMES.len()));
    match (model, store_index) {
        (None, _) => Some(("lost_edges", lost_edges)),
        (Some(i), None) => f.get(i),
        (Some(_), Some(i)) => store.get(i),
    }
}

impl MountPort for PortMount<'_> {
    fn position(&mut self) -> Equatorial {
        self.state.position(self.steps, self.now_us)
    }

    fn sync(&mut self, to: Equatorial) {
        self.state.sync(to, self.steps, self.now_us);
    }

    fn guide(&mut self, pulse: GuidePulse) {
        // A refusal is counted by the loop; the port has no reply for it.
        if !self.state.parked {
            let _ = self.control.port_guide(pulse, self.now_us);
        }
    }

    fn move_at(&mut self, line: Line, rate: ManualRate) {
        if !self.state.parked {
            let _ = self.control.port_move(line, rate, self.now_us);
        }
    }

    fn stop(&mut self, axis: Axis) {
        self.control.port_stop(axis, self.now_us);
    }

    fn set_tracking(&mut self, on: bool) {
        // Parked: tracking stays off until unparked.
        self.control.set_tracking(on && !self.state.parked);
    }

    fn status(&mut self) -> Status {
        let guiding = self.control.guiding();
        let pulse = guiding.pulse_start_us(Axis::Ra).is_some()
            || guiding.pulse_start_us(Axis::Dec).is_some();
        let pec = if !self.control.feed_forward_on() {
            PecState::Off
        } else if guiding.feed_forward_now() != 0.0 {
            PecState::Playing
        } else {
            PecState::Learning
        };
        Status {
            tracking: self.control.tracking(),
            parked: self.state.parked,
            guiding: pulse,
            pec,
        }
    }

    fn identity(&self) -> Identity {
        self.state.identity
    }

    fn learning(&mut self) -> Learning {
        Learning {
            learned_permille: self.state.learner.learned_permille.min(1000),
            feed_forward_mas_per_s: mas(self.control.guiding().feed_forward_now().into()),
            feed_forward_on: self.control.feed_forward_on(),
            origin: self.state.model_origin,
        }
    }

    fn stage(&mut self, index: usize) -> Option<Stage> {
        self.state.learner.stages.get(index).copied()
    }

    fn counter(&mut self, group: CounterGroup, index: usize) -> Option<Counter> {
        let (name, value) = match group {
            CounterGroup::St4 => self.control.st4_counters().get(index)?,
            // Guiding's own counters, then the port motion's (ownership
            // refusals).
            CounterGroup::Guiding => match self.control.guiding().counters().get(index) {
                Some(nv) => nv,
                None => self
                    .control
                    .port_counters()
                    .get(index.checked_sub(GuidingCounters::NAMES.len())?)?,
            },
            CounterGroup::Learner => self.state.learner.counters.get(index)?,
            CounterGroup::Faults => fault_counter(
                self.control.lost_edges(),
                &self.state.learner.faults,
                &self.state.store_counters,
                index,
            )?,
        };
        Some(Counter { name, value })
    }

    fn step_counts(&mut self) -> StepCounts {
        self.steps
    }

    fn set_feed_forward(&mut self, on: bool) {
        self.control.set_feed_forward_on(on);
    }

    fn reset_model(&mut self) {
        self.state.reset_requested = true;
    }

    fn reset_cause(&mut self) -> ResetCause {
        self.state.reset_cause
    }

    fn pending_config(&mut self) -> MountConfig {
        self.state.pending
    }

    fn set_pending_config(&mut self, config: MountConfig) {
        self.state.pending = config;
    }

    fn save_config(&mut self) -> bool {
        let config = self.state.pending;
        self.state.ask_store(StoreRequest::Config {
            config,
            port: self.port,
        })
    }

    fn park(&mut self) {
        self.control.port_stop(Axis::Ra, self.now_us);
        self.control.port_stop(Axis::Dec, self.now_us);
        self.control.set_tracking(false);
        if !self.state.parked {
            self.state.parked = true;
            let _ = self.state.ask_store(StoreRequest::Park(self.steps));
        }
    }

    fn unpark(&mut self) {
        if self.state.parked {
            self.state.parked = false;
            self.control.set_tracking(true);
            let _ = self.state.ask_store(StoreRequest::Unpark);
        }
    }

    fn save_model(&mut self) -> bool {
        self.state
            .ask_store(StoreRequest::Model { port: self.port })
    }
}
