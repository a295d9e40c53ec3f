//! The guider around the model: one call per guide frame turns the measured
//! error into a control, blending the model's prediction with a reactive
//! hysteresis term as far as the model has earned trust.
//!
//! With `N = 1` this is the single-kernel predictive PEC guider and
//! reproduces the reference implementation (INDIGO 3.0) frame by frame; see
//! `host-tests/tests/indigo_reference.rs`. `N > 1` adds the stages of the
//! multi-kernel model.
//!
//! Sign convention: `input` is the measured error and the returned control
//! is the amount of it to remove, in the same units (px or arcsec). A
//! simulator applies it as `U += control`; INDIGO reports `-control` as its
//! "correction".

use core::mem::MaybeUninit;

use crate::model::additions::Additions;
use crate::model::gp::grid::{Averaging, Grid, Push, CELL_S, GRID_CELLS};
use crate::model::gp::infer::Gp;
use crate::model::gp::kernel::Kernel;
use crate::model::in_place::{build, fill, init_fields};
use crate::model::numeric::clamp;
use crate::model::numeric::scalar::Scalar;
use crate::model::snapshot::{Phase, Snapshot, SnapshotError};
use crate::model::spectral::discovery::{Discovery, Spans};
use crate::model::spectral::fft::FFT_LEN;
use crate::model::spectral::period::PeriodTracker;
use crate::model::spectral::spectrum::{Spectrum, NYQUIST_BIN};

mod control_law;
mod restore;
pub mod stage_watch;
mod trust;

use control_law::Law;
use restore::{Fit, Restore, Stages};
use stage_watch::StageWatch;
use trust::Trust;

/// Frames of proportional control without learning after a dither.
pub const DITHER_FRAMES: u8 = 10;
/// Frames before the model is consulted at all.
const WARM_UP_FRAMES: u32 = 10;
/// Weight of the previous control in the hysteresis term.
pub(crate) const HYSTERESIS: f64 = 0.1;
/// Variance given to a frame without a star.
const DARK_VARIANCE: f64 = 1e4;
/// SNR assumed when the caller does not know it.
const DEFAULT_SNR: f64 = 10.0;
/// The longest time step (to the next frame) the guider predicts over,
/// seconds. Guide cycles run from 0.1 s to about a minute (a 30 s exposure
/// plus download and settling); a longer step is clamped to this, so that
/// a wrong step cannot turn the prediction into a move of many pixels.
pub const MAX_TIME_STEP_S: f64 = 60.0;
/// The largest shift of gear time one dither may make, seconds. A dither
/// moves gear time by amount / rate: a few px at the sidereal rate in px
/// per second (1.5 px/s even at 10"/px), i.e. seconds; 600 s leaves room
/// for any real one and stays far inside the grid's window (2.8 h), so that
/// no dither can make the grid restart or stall.
pub const MAX_DITHER_OFFSET_S: f64 = 600.0;
/// The longest interval between two frames of one clock, seconds: a frame
/// further ahead (or behind by more) is held until the next frame says
/// which clock is right. Guide cycles are at most about a minute and a
/// paused guider resumes after minutes; 600 s keeps the longest gap of the
/// reference logs (173 s) one clock, and a glitch within it costs at most
/// 600 s of frames.
pub const MAX_FRAME_GAP_S: f64 = 600.0;

/// Tuning of the guider.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GuiderConfig<S> {
    /// Reactive gain (aggressiveness), 0..=1.
    pub control_gain: S,
    /// Gain on the predicted change of the gear error.
    pub prediction_gain: S,
    /// Errors smaller than this get no reactive correction.
    pub min_move: S,
    /// The worm period assumed until the spectrum says otherwise, seconds.
    pub prior_period_s: f64,
    /// Track the periods from the spectrum; if false, the prior is kept.
    pub compute_period: bool,
    /// The prior is the worm's own period on the caller's clock: the mount
    /// turns the worm once per configured period of gear time (the
    /// learner's). With the addition `configured_worm` the worm's tracker
    /// keeps it unless a faster line is louder; the other stages are still
    /// tracked. False: the prior is a guess the spectrum corrects (a PC
    /// guider's, the paper's).
    pub worm_period_known: bool,
    /// Worm periods of data before the prediction is fully blended in.
    pub periods_for_inference: f64,
    /// Worm periods of data before the period is estimated.
    pub periods_for_estimation: f64,
    /// Inputs larger than this (px or arcsec) are no guide error the guider
    /// could mean: such a frame is handled as one without a star and counted
    /// in [`Faults::bad_input`], so that one absurd value cannot poison the
    /// model for the length of its window.
    pub max_input: S,
    /// The user's estimate of the period of stages 1, 2, 3 (seconds), if
    /// known: the search for that stage is then confined to a band around it.
    pub stage_seeds_s: [Option<f64>; MAX_SEEDED_STAGES],
    /// Predict the gear error at its own time: the grid averages its cells
    /// exactly ([`Averaging::Exact`], with the addition `exact_cells`), so
    /// each cell stands for its centre whatever the frames' times; for a
    /// feed-forward applied as a rate over the coming interval (the
    /// mount's). False keeps the reference's averaging and timing, which a
    /// PC guider's correction of its next frame measures better (INDIGO's
    /// traces, the PHD2 logs; docs/model.md, `exact_cells`).
    pub prediction_at_gear_time: bool,
    /// The fastest the gear error can change (px or arcsec per second): a
    /// prediction is held within this rate over its span, and a restored
    /// snapshot whose cells change faster is refused. The learner sets the
    /// mount's guide rate: no feed-forward can follow a gear faster than
    /// the mount can correct it. Infinite (the default) for a PC guider,
    /// which keeps the reference's arithmetic.
    pub max_gear_rate: f64,
    /// The additions around the paper's model, each switchable by name.
    pub additions: Additions,
}

/// Stages beyond the worm that can be given a seed period.
pub const MAX_SEEDED_STAGES: usize = 3;

impl<S: Scalar> Default for GuiderConfig<S> {
    fn default() -> Self {
        Self {
            control_gain: S::from_f64(0.6),
            prediction_gain: S::from_f64(0.5),
            min_move: S::from_f64(0.2),
            prior_period_s: 300.0,
            compute_period: true,
            worm_period_known: false,
            periods_for_inference: 2.0,
            periods_for_estimation: 2.0,
            max_input: S::from_f64(100.0),
            stage_seeds_s: [None; MAX_SEEDED_STAGES],
            prediction_at_gear_time: false,
            max_gear_rate: f64::INFINITY,
            additions: Additions::ALL,
        }
    }
}

crate::counters! {
    /// What went wrong, counted since construction. Each has a defined outcome
    /// that never reaches the motor as garbage.
    pub struct Faults("model_") {
        /// Frame time not finite, or not continuing the clock (earlier than
        /// the previous frame, or more than [`MAX_FRAME_GAP_S`] later): the
        /// frame was ignored and the control is 0. A frame off the clock by
        /// more than [`MAX_FRAME_GAP_S`] either way is held: if the next frame
        /// continues it, the clock has moved and guiding goes on from there.
        bad_time,
        /// Input not finite or beyond `max_input`: handled as a frame without a
        /// star.
        bad_input,
        /// The Gram matrix did not factor: the frame fell back to hysteresis.
        inference_failures,
        /// The clock moved (a held frame confirmed, see `bad_time`) by more
        /// than the grid's window, or back: the data was dropped and learning
        /// started again (the periods are kept).
        grid_restarts,
        /// A dither refused: a non-finite amount, a zero or non-finite rate, or
        /// a gear-time shift beyond [`MAX_DITHER_OFFSET_S`].
        bad_dithers,
    }
}

/// The guider state for `N` periodic stages (2 by default: the worm and one
/// more; 1 is the single-kernel model), on static storage.
pub struct Guider<S: Scalar, const N: usize = 2> {
    config: GuiderConfig<S>,
    grid: Grid<S>,
    /// Work buffer shared by the spectrum and the inference (16 KiB in
    /// `f32`): the spectrum's peaks are read as soon as it is computed.
    scratch: [S; FFT_LEN],
    /// A cell has completed since the peaks were last read.
    peaks_stale: bool,
    gp: Gp<S>,
    kernel: Kernel<S, N>,
    trackers: [PeriodTracker; N],
    gates: [f64; N],
    discovery: Discovery<N>,
    /// The worm peak of the current spectrum (recomputed when a cell
    /// completes, observed by the tracker on every frame).
    worm_peak_s: Option<f64>,
    /// Gear time from which the grid's data was learned in one piece:
    /// where a restore or a jump placed what came before (`None`: all of
    /// it). Across a placement the stages' phases are only as right as the
    /// placement, so a line there shows as a split peak.
    one_piece_from_s: Option<f64>,
    frames: u32,
    /// Frames before the model is consulted: [`WARM_UP_FRAMES`], or none
    /// for a model restored at a known phase (its data is already there).
    warm_up_frames: u32,
    start_time: f64,
    last_time: f64,
    /// The time of a held frame that did not continue the clock (see
    /// [`Faults::bad_time`]).
    held_time: Option<f64>,
    /// Sum of the controls of all earlier frames.
    sum_control: f64,
    /// Controls of the last two frames, newest first. The hysteresis term
    /// reads the older one: in the reference implementation each frame's
    /// record carries the control of the frame before it, and the term reads
    /// the previous record.
    recent_controls: [S; 2],
    /// Where the last prediction ended (s since start), if any.
    last_prediction_end: Option<f64>,
    prediction: S,
    dither_offset: f64,
    dither_frames_left: u8,
    learning_progress: f64,
    blend: f64,
    /// With more than one stage, the weight of the reference blend as the
    /// model has earned it by measurement (`trust`).
    trust: Trust,
    /// The stages the trust's score measured: a model whose stages change
    /// is scored again.
    trusted_stages: StageWatch<N>,
    faults: Faults,
    /// What a restore (or a jump of the clock) leaves waiting for the new
    /// data: the first frame, the phase search.
    restore: Restore<N>,
}

// The model-state budget (docs/reference.md, Goals): the board's 128 KiB of
// RAM holds it twice at start-up, the static and its temporary on the stack.
const _: () = assert!(core::mem::size_of::<Guider<f32, 2>>() <= 64 * 1024);
// The same budget for three stages (issue 10).
const _: () = assert!(core::mem::size_of::<Guider<f32, 3>>() <= 64 * 1024);

/// Measurement variance from the star's SNR (single-kernel model).
fn measurement_variance(snr: f64) -> f64 {
    let snr = if snr.is_finite() && snr > 0.0 {
        snr
    } else {
        DEFAULT_SNR
    }
    .max(3.4);
    let sd = 2.1752 / (snr - 3.3) + 0.5;
    sd * sd
}

impl<S: Scalar, const N: usize> Guider<S, N> {
    pub fn new(config: GuiderConfig<S>) -> Self {
        build(|slot| Self::init(slot, config))
    }

    /// [`new`](Self::new) in place, e.g. into a static: no temporary copy
    /// of the ~55 KiB on the stack (`crate::model::in_place`).
    pub fn init(slot: &mut MaybeUninit<Self>, config: GuiderConfig<S>) -> &mut Self {
        let trackers = [PeriodTracker::new(config.prior_period_s); N];
        let mut gates = [0.0; N];
        gates[0] = 1.0;
        let periods = trackers.map(|t| t.period_s);
        let seeds = core::array::from_fn(|s| {
            s.checked_sub(1)
                .and_then(|i| config.stage_seeds_s.get(i).copied().flatten())
        });
        let averaging = averaging(&config);
        init_fields!(slot, Self {
            config = config,
            grid in |slot| Grid::init(slot, averaging),
            scratch in |f| fill(f, S::ZERO),
            peaks_stale = true,
            gp in Gp::init,
            kernel = Kernel::new(&periods, &gates),
            trackers = trackers,
            gates = gates,
            discovery = Discovery::new(seeds),
            worm_peak_s = None,
            one_piece_from_s = None,
            frames = 0,
            warm_up_frames = WARM_UP_FRAMES,
            start_time = 0.0,
            last_time = 0.0,
            held_time = None,
            sum_control = 0.0,
            recent_controls = [S::ZERO; 2],
            last_prediction_end = None,
            prediction = S::ZERO,
            dither_offset = 0.0,
            dither_frames_left = 0,
            learning_progress = 0.0,
            blend = 0.0,
            trust = Trust::new(),
            trusted_stages = StageWatch::NEW,
            faults = Faults::default(),
            restore in |slot| Restore::init(slot, config.additions),
        })
    }

    /// Forget the data (not the learned periods, nor the fault counters).
    pub fn reset(&mut self) {
        self.grid.clear();
        self.worm_peak_s = None;
        self.discovery.clear();
        self.gates[1..].fill(0.0);
        self.learning_progress = 0.0;
        self.trust = Trust::new();
        for t in &mut self.trackers {
            t.disagreement = 1.0;
        }
        self.restart_frames();
        self.restore.clear();
    }

    /// The per-frame state as before a first frame: the clock starts again
    /// with the next frame. The data, the periods and the trust stay.
    fn restart_frames(&mut self) {
        self.peaks_stale = true;
        self.gp.clear();
        self.frames = 0;
        self.warm_up_frames = WARM_UP_FRAMES;
        self.held_time = None;
        self.sum_control = 0.0;
        self.recent_controls = [S::ZERO; 2];
        self.last_prediction_end = None;
        self.prediction = S::ZERO;
        self.dither_offset = 0.0;
        self.dither_frames_left = 0;
        self.blend = 0.0;
    }

    pub fn config(&self) -> &GuiderConfig<S> {
        &self.config
    }

    /// Tracked period of a stage, seconds (NaN for a stage not found yet).
    pub fn period_s(&self, stage: usize) -> f64 {
        self.trackers.get(stage).map_or(f64::NAN, |t| t.period_s)
    }

    /// Tracked periods of all stages, seconds.
    pub fn periods_s(&self) -> [f64; N] {
        self.trackers.map(|t| t.period_s)
    }

    /// Evidence gate of a stage, 0..=1 (the worm's is 1).
    pub fn gate(&self, stage: usize) -> f64 {
        self.gates.get(stage).copied().unwrap_or(0.0)
    }

    /// Progress shown to the user, 0..=1: the mean of the data ramp and the
    /// period convergence (the blend weight is their product).
    pub fn learning_progress(&self) -> f64 {
        self.learning_progress
    }

    /// Weight of the predictive term in the last frame's control.
    pub fn blend_weight(&self) -> f64 {
        self.blend
    }

    /// The last predicted change of the gear error over the next frame.
    pub fn prediction(&self) -> S {
        self.prediction
    }

    pub fn faults(&self) -> Faults {
        self.faults
    }

    /// One guide frame with a star. `time_s`: the guider's clock in seconds
    /// (any origin; the first frame after construction or reset is the
    /// start). `snr` <= 0 or not finite means unknown. `time_step`: the
    /// time to the next frame, seconds, at most [`MAX_TIME_STEP_S`].
    /// Returns the control.
    pub fn frame(&mut self, time_s: f64, input: S, snr: S, time_step: S) -> S {
        if !self.accept_time(time_s) {
            return S::ZERO;
        }
        let settling = self.settle_one_frame();
        let good = self.is_guide_error(input.to_f64());
        if self.frames == 0 {
            self.start_clock(time_s, (good && !settling).then(|| input.to_f64()));
        }
        let reactive = self.config.control_gain * input;
        if settling {
            // Settling after a dither: the measurement is not gear error,
            // and a prediction would span the dither's shift of gear time.
            // Proportional control (none for a bad input), and the frame is
            // learned as dark.
            self.dark_step(time_s, time_step);
            return if good && reactive.is_finite() {
                reactive
            } else {
                S::ZERO
            };
        }
        if !good {
            return self.dark_step(time_s, time_step);
        }
        let gear = self.sum_control + input.to_f64();
        let variance = measurement_variance(snr.to_f64());
        let law = self.law();
        let (timestamp, prediction) = self.model_step(time_s, time_step);
        if N > 1 {
            if self.trusted_stages.changed(self.periods_s()) {
                self.trust.stages_changed(&self.config.additions);
            }
            let weight = self.trust.measured(
                gear,
                &law.to_f64(),
                prediction.map(|p| (p.to_f64(), self.blend)),
                Self::sanitize_step(time_step),
                &self.config.additions,
            );
            self.blend *= weight;
        }
        // The blend weight is 0 after a failed fit: hysteresis alone.
        let prediction = prediction.map(|p| (p, S::from_f64(self.blend)));
        let control = law.control(input, self.recent_controls[1], prediction);
        self.finish_frame(timestamp, input.to_f64(), variance, control)
    }

    /// Mount-side learning, for a caller that reconstructs the gear error
    /// itself (the corrections it applied plus the error the guider still
    /// reports) and wants the model's feed-forward rather than a control.
    /// Records the observation and returns the predicted change of the gear
    /// error from this frame to `time_s + time_step`, weighted by the blend
    /// weight: 0 until the model has earned trust, and whenever its fit
    /// fails. `gear_error: None` means nothing was measured this frame (the
    /// guider was silent): the frame is kept with a variance that makes it
    /// count for nothing, at the estimate `unmeasured_estimate`. Frames while
    /// settling after [`dithered`](Self::dithered) are not learned either,
    /// nor, counted in [`Faults::bad_input`], an observation whose measured
    /// part (`gear_error - unmeasured_estimate`, what the guider reported)
    /// is not finite or beyond `max_input`.
    /// Use either this or [`frame`](Self::frame) on one guider, not both.
    pub fn observe(
        &mut self,
        time_s: f64,
        gear_error: Option<f64>,
        unmeasured_estimate: f64,
        snr: S,
        time_step: S,
    ) -> S {
        if !self.accept_time(time_s) {
            return S::ZERO;
        }
        let settling = self.settle_one_frame();
        let measured = gear_error.filter(|g| self.is_guide_error(g - unmeasured_estimate));
        let measured = measured.filter(|_| !settling);
        if self.frames == 0 {
            self.start_clock(time_s, measured);
        } else if let Some(g) = measured {
            self.match_placed_level(time_s, g);
        }
        let (gear, variance) = match measured {
            Some(g) => (g, measurement_variance(snr.to_f64())),
            None => (unmeasured_estimate, DARK_VARIANCE),
        };
        let (timestamp, prediction) = self.model_step(time_s, time_step);
        // 0 until the model has earned trust and after a failed fit (the
        // blend weight).
        let mut feed_forward = prediction.map_or(S::ZERO, |p| S::from_f64(self.blend) * p);
        if !feed_forward.is_finite() {
            feed_forward = S::ZERO;
        }
        self.record(timestamp, gear, variance);
        self.frames = self.frames.saturating_add(1);
        feed_forward
    }

    /// One guide frame without a star (clouds, a lost star): the model's
    /// prediction alone is applied once it has enough data.
    pub fn dark_frame(&mut self, time_s: f64, time_step: S) -> S {
        if !self.accept_time(time_s) {
            return S::ZERO;
        }
        if self.frames == 0 {
            self.start_clock(time_s, None);
        }
        self.dark_step(time_s, time_step)
    }

    /// The guider dithered by `amount` (px or arcsec) at `rate` (the same
    /// units per second of gear time): shift gear time and settle for
    /// [`DITHER_FRAMES`] frames without learning. An offset `amount / rate`
    /// that is not finite or beyond [`MAX_DITHER_OFFSET_S`] is no dither:
    /// refused, counted in [`Faults::bad_dithers`], nothing changes.
    pub fn dithered(&mut self, amount: S, rate: S) {
        let (amount, rate) = (amount.to_f64(), rate.to_f64());
        let offset = amount / rate;
        if !(offset.abs() <= MAX_DITHER_OFFSET_S) {
            self.faults.bad_dithers = self.faults.bad_dithers.saturating_add(1);
            return;
        }
        self.dither_offset += offset;
        self.dither_frames_left = DITHER_FRAMES;
    }

    /// Write the learned state (see [`crate::model::snapshot`]) into `out`,
    /// at most [`SNAPSHOT_MAX`](crate::model::snapshot::SNAPSHOT_MAX)
    /// bytes for three stages; returns the length written. Not a per-frame
    /// call: it reads the newest
    /// [`SNAPSHOT_CELLS`](crate::model::snapshot::SNAPSHOT_CELLS) cells.
    /// Refused ([`SnapshotError::Placing`]) while restored data waits for
    /// its phase: a phase search pending, or with the phase unknown the
    /// first frame.
    pub fn snapshot(&self, out: &mut [u8]) -> Result<usize, SnapshotError> {
        let stages = Stages {
            trackers: &self.trackers,
            gates: &self.gates,
        };
        self.restore
            .snapshot(&self.grid, stages, &self.discovery, self.clock(), out)
    }

    /// Take the learned state back from `snapshot` (checked by
    /// [`Snapshot::parse`]): the periods, stages and gates, and the cells,
    /// placed at the first frame as `phase` allows and, unless every
    /// stage's phase is known, again by the phase search a little later
    /// (half a worm period; with the worm's phase known, a quarter, or a
    /// twentieth once the other stages are fitted apart). The
    /// fault counters stay. A snapshot of another stage count, or one
    /// outside the bounds this configuration learns within, is refused and
    /// nothing changes.
    pub fn restore(&mut self, snapshot: &Snapshot<'_>, phase: Phase) -> Result<(), SnapshotError> {
        restore::check::<S, N>(&self.config, snapshot)?;
        self.reset();
        self.restore.take_back(
            snapshot,
            phase,
            &mut self.grid,
            &mut self.trackers,
            &mut self.gates,
            &mut self.discovery,
        );
        Ok(())
    }

    /// The clock is about to jump ahead with nothing measured in between
    /// (the port slews the axis: the gears turn, no frame is taken). What
    /// was learned is kept and placed before the next frame as a restore
    /// at a known phase places a snapshot: where the clock puts it if that
    /// is within eight worm periods, else as near as every
    /// stage's phase allows, the gap left dark; its level then meets the
    /// first measured frame. Pushed across the jump instead, the cells
    /// would be filled by interpolating the last frame to the next (as
    /// measured data), or, frame by frame through a long slew, push the
    /// learned data out of the ring. While the phase search after a
    /// restore waits for data, the frames before the jump are dropped and
    /// the restored data waits to be placed after it as the restore would
    /// have placed it. Does nothing while a restored model waits for its
    /// first frame or before anything was learned.
    pub fn jumped(&mut self) {
        if self.frames == 0 {
            return;
        }
        let clock = self.clock();
        if self
            .restore
            .jumped(&mut self.grid, &mut self.scratch, clock)
        {
            self.restart_frames();
        }
    }

    /// The caller's clock at a gear time (s since the start, plus the
    /// dither offset): where a snapshot puts the saved data on the clock.
    /// A copy, so that the grid can be borrowed beside it.
    fn clock(&self) -> impl Fn(f64) -> f64 {
        let (start_time, dither_offset) = (self.start_time, self.dither_offset);
        move |t| t + start_time - dither_offset
    }

    /// The model's part of a frame with a measurement, shared by
    /// [`frame`](Self::frame) and [`observe`](Self::observe): returns the
    /// frame's gear time and, past the warm-up, the predicted change of the
    /// gear error to `time_s + time_step` (0 if the fit failed). Sets the
    /// blend weight (0 during the warm-up and after a failed fit) and the
    /// learning progress.
    fn model_step(&mut self, time_s: f64, time_step: S) -> (f64, Option<S>) {
        let dt = Self::sanitize_step(time_step);
        let timestamp = self.timestamp(time_s);
        self.last_prediction_end = Some(timestamp);
        self.blend = 0.0;
        let mut prediction = None;
        if self.frames >= self.warm_up_frames {
            let now = time_s - self.start_time;
            let failed = self.track_and_fit(now + 0.5 * dt, timestamp);
            self.prediction = self.predict(now, dt);
            prediction = Some(self.prediction);
            if !failed {
                self.blend = self.blend_weight_at(timestamp);
            }
        }
        self.learning_progress = self.progress_at(timestamp);
        (timestamp, prediction)
    }

    fn dark_step(&mut self, time_s: f64, time_step: S) -> S {
        let dt = Self::sanitize_step(time_step);
        let timestamp = self.timestamp(time_s);
        let mut control = S::ZERO;
        self.blend = 0.0;
        if self.frames >= self.warm_up_frames
            && timestamp > self.config.periods_for_inference * self.trackers[0].period_s
        {
            let now = time_s - self.start_time;
            if !self.track_and_fit(now + 0.5 * dt, timestamp) {
                self.prediction = self.predict(now, dt);
                control = self.prediction;
            }
        }
        if !control.is_finite() {
            control = S::ZERO;
        }
        self.learning_progress = self.progress_at(timestamp);
        let control = self.finish_frame(timestamp, 0.0, DARK_VARIANCE, control);
        let [c0, c1] = self.recent_controls;
        self.trust
            .follow(self.sum_control, [c0.to_f64(), c1.to_f64()]);
        control
    }

    /// The time the grid's cells span, s.
    fn grid_span_s(&self) -> f64 {
        self.grid.len() as f64 * CELL_S
    }

    /// The spans of data that resolve the spectrum's lines from each
    /// other: the grid's, or for a new line with `one_piece` the part
    /// learned in one piece (a restored or re-pointed grid's split lines
    /// are no stage of their own; a stage's own line is followed across
    /// the whole grid).
    fn resolving_spans(&self, timestamp: f64) -> Spans {
        let grid_s = self.grid_span_s();
        let new_s = match self.one_piece_from_s {
            Some(from) if self.config.additions.one_piece => grid_s.min(timestamp - from).max(0.0),
            _ => grid_s,
        };
        Spans {
            own_s: grid_s,
            new_s,
        }
    }

    /// What the worm's tracker observes when the spectrum's strongest line
    /// lies at `peak_s`: that line, or the worm's own period where the
    /// caller knows it (`configured_worm`), unless the line is a faster
    /// one the grid's span resolves from the worm's (a belt or
    /// a motor gear louder than the worm, which the paper's model takes as
    /// its base). Measured, the worm's line moves by up to 1 % as gaps,
    /// re-pointings and a ghost stage beside it reshape the data, and a
    /// long slew multiplies that into the worm's phase; a slower line is
    /// no stage of the train (bumps, drift).
    fn worm_period_observed(&self, peak_s: f64) -> f64 {
        let known = self.config.prior_period_s;
        let faster_stage = (1.0 / peak_s - 1.0 / known) * self.grid_span_s() > 1.0;
        if self.config.worm_period_known && self.config.additions.configured_worm && !faster_stage {
            known
        } else {
            peak_s
        }
    }

    /// The control law of [`frame`](Self::frame) and of the shadows of
    /// `trust`.
    fn law(&self) -> Law<S> {
        Law {
            control_gain: self.config.control_gain,
            prediction_gain: self.config.prediction_gain,
            min_move: self.config.min_move,
            // HYSTERESIS unless the shadows measured the proportional law
            // better (N > 1 only: the single-kernel guider never asks them).
            hysteresis: self.trust.hysteresis(&self.config.additions),
        }
    }

    /// The time step in 0..=[`MAX_TIME_STEP_S`]; not finite or not
    /// positive is 0.
    fn sanitize_step(time_step: S) -> f64 {
        let dt = time_step.to_f64();
        if dt.is_finite() && dt > 0.0 {
            dt.min(MAX_TIME_STEP_S)
        } else {
            0.0
        }
    }

    /// Counts one frame of the settling after a dither; true while settling.
    fn settle_one_frame(&mut self) -> bool {
        let settling = self.dither_frames_left > 0;
        if settling {
            self.dither_frames_left -= 1;
        }
        settling
    }

    /// Whether a measured error is one the guider could mean: finite and
    /// within `max_input`. A frame whose error is not is refused.
    pub fn accepts_input(&self, error: f64) -> bool {
        error.abs() <= self.config.max_input.to_f64()
    }

    /// [`accepts_input`](Self::accepts_input), a refusal counted in
    /// [`Faults::bad_input`].
    fn is_guide_error(&mut self, error: f64) -> bool {
        let ok = self.accepts_input(error);
        if !ok {
            self.faults.bad_input = self.faults.bad_input.saturating_add(1);
        }
        ok
    }

    /// Whether the frame at `time_s` may be used. A frame that continues
    /// the clock (0 to [`MAX_FRAME_GAP_S`] after the previous one) is
    /// accepted. One that does not is refused (counted in
    /// [`Faults::bad_time`]); if it is off by more than [`MAX_FRAME_GAP_S`]
    /// it is held, and a next frame that continues it rather than the old
    /// clock moves the clock there (one glitch costs one frame; a clock
    /// that really jumped, one frame too).
    fn accept_time(&mut self, time_s: f64) -> bool {
        let held = self.held_time.take();
        if !time_s.is_finite() {
            self.faults.bad_time = self.faults.bad_time.saturating_add(1);
            return false;
        }
        if self.frames == 0 || continues(self.last_time, time_s) {
            return true;
        }
        if let Some(held) = held.filter(|&h| continues(h, time_s) && h < time_s) {
            self.move_clock(held);
            return true;
        }
        if self.config.additions.clock_hold && (time_s - self.last_time).abs() > MAX_FRAME_GAP_S {
            self.held_time = Some(time_s);
        }
        self.faults.bad_time = self.faults.bad_time.saturating_add(1);
        false
    }

    /// The clock moved to `held_time` (a held frame, confirmed by the next
    /// one): a gap within the grid's window is bridged; a longer one, or a
    /// clock that went back, starts learning again.
    fn move_clock(&mut self, held_time: f64) {
        let gap = held_time - self.last_time;
        if (0.0..=GRID_CELLS as f64 * CELL_S).contains(&gap) {
            self.last_time = held_time;
        } else {
            self.reset();
            self.faults.grid_restarts = self.faults.grid_restarts.saturating_add(1);
        }
    }

    /// The first frame after construction or a reset starts the clock
    /// (gear time 0), or continues a restored model (`restore`).
    /// `gear`: the frame's gear error, if measured.
    fn start_clock(&mut self, time_s: f64, gear: Option<f64>) {
        self.last_time = time_s;
        let stages = Stages {
            trackers: &self.trackers,
            gates: &self.gates,
        };
        let fit = Fit {
            gp: &mut self.gp,
            kernel: &mut self.kernel,
            measured_only: self.config.additions.measured_subset,
        };
        let resumed = self.restore.resume_restored(
            time_s,
            gear,
            &mut self.grid,
            &mut self.scratch,
            stages,
            fit,
        );
        let mut gear_time = 0.0;
        self.one_piece_from_s = None;
        if let Some(resumed) = resumed {
            self.one_piece_from_s = Some(resumed.gear_time_s);
            // Placed at a known phase, the restored data predicts from this
            // frame on: no warm-up (its 20 s of the guider alone were a
            // fifth of the excess over settled of a parked night's first
            // 30 min).
            if resumed.placed {
                self.warm_up_frames = 0;
            }
            gear_time = resumed.gear_time_s;
        }
        self.start_time = time_s - gear_time;
    }

    /// The first measured frame after placed data whose first frame had
    /// no measurement: the placed data meets its level
    /// ([`Restore::match_level`]).
    fn match_placed_level(&mut self, time_s: f64, gear: f64) {
        if !self.restore.level_pending() {
            return;
        }
        let at = time_s - self.start_time - self.grid.origin().unwrap_or(0.0);
        let fit = Fit {
            gp: &mut self.gp,
            kernel: &mut self.kernel,
            measured_only: self.config.additions.measured_subset,
        };
        self.restore
            .match_level(gear, at, &mut self.grid, &mut self.scratch, fit);
    }

    /// Gear time of the current frame: the midpoint of the interval since
    /// the previous frame, plus the dither offset.
    fn timestamp(&mut self, time_s: f64) -> f64 {
        let delta = time_s - self.last_time;
        self.last_time = time_s;
        (time_s - self.start_time) - 0.5 * delta + self.dither_offset
    }

    /// Record the frame in the grid and remember its control.
    fn finish_frame(&mut self, timestamp: f64, measurement: f64, variance: f64, control: S) -> S {
        let control = if control.is_finite() {
            control
        } else {
            S::ZERO
        };
        self.record(timestamp, self.sum_control + measurement, variance);
        self.sum_control += control.to_f64();
        self.recent_controls = [control, self.recent_controls[0]];
        self.frames = self.frames.saturating_add(1);
        control
    }

    /// Add a frame's gear error to the grid.
    fn record(&mut self, timestamp: f64, gear: f64, variance: f64) {
        match self.grid.push(timestamp, gear, variance) {
            Push::Accepted { new_cells: 0 } | Push::Rejected => {}
            Push::Accepted { .. } => self.peaks_stale = true,
            Push::Restarted => {
                self.peaks_stale = true;
                self.faults.grid_restarts = self.faults.grid_restarts.saturating_add(1);
            }
        }
    }

    /// Track the periods and fit the model around `centre` (s since start).
    /// Returns true if the fit failed (the frame then falls back to the
    /// reactive term); with too little data the last fit, if any, is kept.
    fn track_and_fit(&mut self, centre: f64, timestamp: f64) -> bool {
        let stages = Stages {
            trackers: &self.trackers,
            gates: &self.gates,
        };
        if self
            .restore
            .phase_search_pending(&mut self.grid, &mut self.scratch, stages)
        {
            return true;
        }
        let Some(origin) = self.grid.origin() else {
            return false;
        };
        if self.grid.len() < 2 {
            return false;
        }
        // The clock counts the periods of data as the reference does
        // (INDIGO's agreement holds it); but where the grid lost its data
        // (a restore's saved data dropped) the clock runs on, and a grid
        // shorter than a worm period holds no worm line to track.
        let holds_a_worm = self.grid_span_s() >= self.trackers[0].period_s;
        if self.config.compute_period
            && timestamp > self.config.periods_for_estimation * self.trackers[0].period_s
            && holds_a_worm
            && !self.restore.searching()
        {
            if self.peaks_stale {
                self.peaks_stale = false;
                let spans = self.resolving_spans(timestamp);
                if let Some(spectrum) = Spectrum::compute(&self.grid, &mut self.scratch) {
                    let spectrum = spectrum.log_power_peak(self.config.additions.log_power_peak);
                    let worm = spectrum.strongest(0, NYQUIST_BIN, |_| true);
                    self.worm_peak_s = worm.map(|p| p.period_s);
                    if N > 1 {
                        // The noise floor is the exact grid's: the
                        // reference's averaging smooths the seeing noise
                        // across cells, and a PC guider keeps its figures.
                        let adds = Additions {
                            noise_floor: self.config.additions.noise_floor
                                && self.grid.averaging() != Averaging::Reference,
                            ..self.config.additions
                        };
                        self.discovery
                            .scan(&spectrum, &mut self.trackers, worm, spans, &adds);
                    }
                }
            }
            if let Some(p) = self.worm_peak_s {
                self.trackers[0].observe(self.worm_period_observed(p));
            }
            self.discovery
                .step(&mut self.trackers, &mut self.gates, &self.config.additions);
        }
        let periods = self.trackers.map(|t| t.period_s);
        self.kernel = Kernel::new(&periods, &self.restore.fit_gates(&self.gates));
        let failed = self
            .gp
            .infer(
                &self.grid,
                &self.kernel,
                centre - origin,
                &mut self.scratch,
                self.config.additions.measured_subset,
            )
            .is_err();
        if failed {
            self.faults.inference_failures = self.faults.inference_failures.saturating_add(1);
        }
        failed
    }

    /// Predicted change of the gear error from the end of the last
    /// prediction to `now + dt` (s since start, plus the dither offset),
    /// on the grid's time axis.
    fn predict(&mut self, now: f64, dt: f64) -> S {
        let x1 = now + dt + self.dither_offset;
        let x0 = self.last_prediction_end.unwrap_or(now);
        self.last_prediction_end = Some(x1);
        let Some(origin) = self.grid.origin() else {
            return S::ZERO;
        };
        let (from, to) = (x0 - origin, x1 - origin);
        let change = self.gp.predict_change(&self.grid, &self.kernel, from, to);
        let bound = self.config.max_gear_rate * (x1 - x0).max(0.0);
        if bound.is_finite() {
            S::from_f64(clamp(change.to_f64(), -bound, bound))
        } else {
            change
        }
    }

    /// The least settled period among the stages that carry weight.
    fn convergence(&self) -> f64 {
        if !self.config.compute_period {
            return 1.0;
        }
        self.trackers
            .iter()
            .zip(&self.gates)
            .filter(|(_, &g)| g > 0.0)
            .map(|(t, _)| t.convergence())
            .fold(1.0, f64::min)
    }

    fn data_ramp(&self, timestamp: f64) -> f64 {
        let span = self.config.periods_for_inference * self.trackers[0].period_s;
        if !(span > 0.0) {
            return 0.0;
        }
        (timestamp / span).clamp(0.0, 1.0)
    }

    fn blend_weight_at(&self, timestamp: f64) -> f64 {
        if self.frames < self.warm_up_frames {
            return 0.0;
        }
        self.data_ramp(timestamp) * self.convergence()
    }

    fn progress_at(&self, timestamp: f64) -> f64 {
        if self.frames < self.warm_up_frames {
            return 0.0;
        }
        let ramp = self.data_ramp(timestamp);
        if !self.config.compute_period {
            return ramp;
        }
        0.5 * ramp + 0.5 * self.convergence()
    }
}

/// The grid's averaging for a guider of this configuration: exact for the
/// mount's (`GuiderConfig::prediction_at_gear_time`) unless `exact_cells`
/// is off, over pairs of long frames unless `paired_frames` is off.
fn averaging<S>(config: &GuiderConfig<S>) -> Averaging {
    if config.prediction_at_gear_time && config.additions.exact_cells {
        if config.additions.paired_frames {
            Averaging::Paired
        } else {
            Averaging::Exact
        }
    } else {
        Averaging::Reference
    }
}

/// Whether a frame at `time_s` continues a clock whose last frame was at
/// `last_s`.
fn continues(last_s: f64, time_s: f64) -> bool {
    (0.0..=MAX_FRAME_GAP_S).contains(&(time_s - last_s))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gear(t: f64) -> f64 {
        9.0 * libm::sin(2.0 * core::f64::consts::PI * t / 432.0) + 0.0008 * t
    }

    #[test]
    fn observe_predicts_the_gear_error_change() {
        let mut g: Guider<f64, 1> = Guider::new(GuiderConfig::default());
        let (mut sq_err, mut sq_true, mut n) = (0.0, 0.0, 0);
        let mut t = 0.0;
        while t < 6000.0 {
            let ff = g.observe(t, Some(gear(t)), 0.0, 10.0, 2.0);
            if t >= 2000.0 {
                // From this frame's timestamp (the midpoint since the last
                // frame) to the next frame.
                let truth = gear(t + 2.0) - gear(t - 1.0);
                sq_err += (ff - truth) * (ff - truth);
                sq_true += truth * truth;
                n += 1;
            }
            t += 2.0;
        }
        let (rms_err, rms_true) = ((sq_err / n as f64).sqrt(), (sq_true / n as f64).sqrt());
        assert!(g.blend_weight() > 0.99);
        // Measured: 0.016 px against a true change of 0.275 px RMS (5.7 %).
        assert!(rms_err < 0.08 * rms_true, "{rms_err} vs {rms_true}");
        assert!((g.period_s(0) - 432.0).abs() < 1.0, "{}", g.period_s(0));
    }

    #[test]
    fn without_exact_cells_the_mounts_grid_is_the_references() {
        // The mount's feed-forward on 2 s frames: with the addition its
        // grid averages exactly, without it as a PC guider's, frame for
        // frame.
        let run = |prediction_at_gear_time: bool, additions: Additions| {
            let mut g: Guider<f64, 1> = Guider::new(GuiderConfig {
                prediction_at_gear_time,
                additions,
                ..GuiderConfig::default()
            });
            let ff: [f64; 1500] = core::array::from_fn(|k| {
                let t = 2.0 * k as f64;
                g.observe(t, Some(gear(t)), 0.0, 10.0, 2.0)
            });
            ff
        };
        let mut off = Additions::ALL;
        off.set("exact_cells", false).unwrap();
        let reference = run(false, Additions::ALL);
        assert!(reference.iter().any(|&f| f != 0.0));
        assert_ne!(run(true, Additions::ALL), reference);
        assert_eq!(run(true, off), reference);
    }

    #[test]
    fn the_mounts_grid_pairs_long_frames_unless_paired_frames_is_off() {
        let mount = |additions| GuiderConfig::<f64> {
            prediction_at_gear_time: true,
            additions,
            ..GuiderConfig::default()
        };
        assert_eq!(averaging(&mount(Additions::ALL)), Averaging::Paired);
        let mut unpaired = Additions::ALL;
        unpaired.set("paired_frames", false).unwrap();
        assert_eq!(averaging(&mount(unpaired)), Averaging::Exact);
        assert_eq!(
            averaging(&GuiderConfig::<f64>::default()),
            Averaging::Reference
        );
    }

    #[test]
    fn without_clock_hold_a_clock_that_jumped_is_refused() {
        // Ten frames, then the clock jumps 5,000 s ahead and goes on there.
        for (hold, refused) in [(true, 1), (false, 10)] {
            let mut additions = Additions::ALL;
            additions.clock_hold = hold;
            let mut g: Guider<f64, 1> = Guider::new(GuiderConfig {
                additions,
                ..GuiderConfig::default()
            });
            for t in (0..10).map(|k| 2.0 * k as f64) {
                g.observe(t, Some(gear(t)), 0.0, 10.0, 2.0);
            }
            for t in (0..10).map(|k| 5000.0 + 2.0 * k as f64) {
                g.observe(t, Some(gear(t)), 0.0, 10.0, 2.0);
            }
            assert_eq!(g.faults().bad_time, refused, "{hold}");
        }
    }

    #[test]
    fn a_known_worm_period_is_kept_unless_a_faster_line_is_louder() {
        // The caller says 432 s. A worm turning at 436 s (within the
        // spectrum's resolution) or at 520 s (a slower line, no faster
        // stage's): a guess follows the data, a known period (the mount's)
        // is kept, unless `configured_worm` is off. A line at 360 s, a
        // faster one resolved from 432 s, is followed either way.
        let period = |true_s: f64, known: bool, on: bool| {
            let worm = |t: f64| 9.0 * libm::sin(2.0 * core::f64::consts::PI * t / true_s);
            let mut additions = Additions::ALL;
            additions.configured_worm = on;
            let mut g: Guider<f64, 2> = Guider::new(GuiderConfig {
                prior_period_s: 432.0,
                worm_period_known: known,
                additions,
                ..GuiderConfig::default()
            });
            for t in (0..3000).map(|k| 2.0 * k as f64) {
                g.observe(t, Some(worm(t)), 0.0, 10.0, 2.0);
            }
            g.period_s(0)
        };
        for true_s in [436.0, 520.0] {
            assert_eq!(period(true_s, true, true), 432.0, "{true_s} s");
        }
        let followed = [
            (436.0, false, true),
            (436.0, true, false),
            (520.0, true, false),
            (360.0, true, true),
        ];
        for (true_s, known, on) in followed {
            let p = period(true_s, known, on);
            assert!(
                (p - true_s).abs() < 0.5,
                "{true_s} s, known {known}, on {on}: {p}"
            );
        }
    }

    #[test]
    fn after_a_jump_new_lines_are_resolved_by_the_data_since() {
        // 4,000 s learned, a jump, 300 s more: the span that resolves a new
        // line is the 300 s (to a frame), or without `one_piece` the
        // grid's; a stage's own line is followed across the whole grid.
        for one_piece in [true, false] {
            let mut additions = Additions::ALL;
            additions.one_piece = one_piece;
            let mut g: Guider<f64, 2> = Guider::new(GuiderConfig {
                additions,
                ..GuiderConfig::default()
            });
            let mut t = 0.0;
            while t < 4000.0 {
                g.observe(t, Some(gear(t)), 0.0, 10.0, 2.0);
                t += 2.0;
            }
            let grid_span = g.grid_span_s();
            assert_eq!(g.resolving_spans(t - 2.0), Spans::whole(grid_span));
            g.jumped();
            t += 2700.0;
            let from = t;
            while t < from + 300.0 {
                g.observe(t, Some(gear(t)), 0.0, 10.0, 2.0);
                t += 2.0;
            }
            let grid_span = g.grid_span_s();
            // The spans at the last frame's gear time.
            let spans = g.resolving_spans(t - 2.0 - g.start_time);
            assert_eq!(spans.own_s, grid_span);
            if one_piece {
                assert!((spans.new_s - 300.0).abs() <= 2.0, "{spans:?}");
            } else {
                assert_eq!(spans.new_s, grid_span);
            }
            assert!(grid_span > 4000.0, "{grid_span}");
        }
    }

    #[test]
    fn observe_without_measurements_predicts_nothing_new() {
        let mut g: Guider<f64, 1> = Guider::new(GuiderConfig::default());
        for k in 0..2000 {
            let ff = g.observe(2.0 * k as f64, None, 0.0, 10.0, 2.0);
            assert!(ff.abs() < 1e-6, "frame {k}: {ff}");
        }
        let ff = g.observe(4000.0, Some(f64::NAN), 0.0, 10.0, 2.0);
        assert_eq!(ff, 0.0);
        assert_eq!(g.faults().bad_input, 1);
    }
}
