//! The guide frames: one per RA pulse, or filled at the guide cadence when
//! the guider sends none, queued for the learner.
//!
//! A filled frame says "the guider measured less than its minimum move".
//! That holds only if the guider exposed in its interval: a guider slower
//! than the configured cadence (8 s exposures against 2 s) would get three
//! filled frames per exposure that each claim no error where there is
//! some, and the model would learn its own feed-forward as gear error (a
//! runaway measured at 4.8 x the guider alone). So the cadence the frames
//! are filled at is the guider's own, as its pulses show it, whenever that
//! is clearly slower than the configured one.
//!
//! A guider whose pulses no longer fit in its cycle (each RA pulse starts as
//! the one before it ends) has lost its loop: its pulses queue, and each
//! one answers an exposure taken long before. Such a frame tells nothing
//! about the gear, so learning freezes ([`Backlog`]) until the pulses fit
//! again. Meanwhile the firmware adds nothing to the guider's loop: no
//! feed-forward, and its pulses carried out in full (`super`).

use heapless::Deque;

use super::applied::{secs_between, Applied, Mark};
use super::calibration::{CalibrationWatch, HOLD_CADENCES};
use super::{GuidingCounters, FRAME_QUEUE};
use crate::mount::frame::{Frame, FrameKind};
use crate::mount::st4::{Axis, Direction};

/// The frame an RA pulse opened: C at its start, and its direction.
#[derive(Clone, Copy, Debug, PartialEq)]
struct OpenFrame {
    mark: Mark,
    direction: Direction,
}

/// Intervals between RA pulse starts the guider's cadence is measured over.
const CADENCE_WINDOW: usize = 8;
/// Intervals needed before the measured cadence is used.
const CADENCE_MIN_INTERVALS: usize = 3;

/// The guider's cadence as its RA pulses show it: the shortest of the last
/// [`CADENCE_WINDOW`] intervals between pulse starts (a guider that skips
/// an exposure below its minimum move makes an interval of two cadences,
/// never a shorter one).
#[derive(Clone, Copy, Debug, Default)]
struct PulseCadence {
    last_start_us: Option<u64>,
    intervals_us: [u64; CADENCE_WINDOW],
    count: usize,
    next: usize,
}

impl PulseCadence {
    fn pulse_started(&mut self, at_us: u64) {
        if let Some(prev) = self.last_start_us {
            if let Some(slot) = self.intervals_us.get_mut(self.next) {
                *slot = at_us.saturating_sub(prev);
            }
            self.next = (self.next + 1) % CADENCE_WINDOW;
            self.count = (self.count + 1).min(CADENCE_WINDOW);
        }
        self.last_start_us = Some(at_us);
    }

    /// The measured cadence, once enough intervals are known.
    fn measured_us(&self) -> Option<u64> {
        if self.count < CADENCE_MIN_INTERVALS {
            return None;
        }
        self.intervals_us.iter().take(self.count).copied().min()
    }
}

/// Pulses in a row that start as the one before ends before learning
/// freezes, and that fit in their cycle before it resumes: a bump's or a
/// dither's few long pulses never reach it.
pub(super) const BACKLOG_PULSES: u8 = 8;

/// Whether the guider's RA pulses run back to back: a pulse that starts
/// within a sixteenth of its cycle (start to start) of the previous one's
/// end leaves no time for an exposure between them.
#[derive(Clone, Copy, Debug, Default)]
struct Backlog {
    last_end_us: Option<u64>,
    /// Pulses in a row on the other side of the present state.
    run: u8,
    on: bool,
}

impl Backlog {
    /// An RA pulse started at `at_us`, the one before it at
    /// `previous_start_us`: true when this begins a backlog.
    fn pulse_started(&mut self, at_us: u64, previous_start_us: Option<u64>) -> bool {
        let back_to_back = match (previous_start_us, self.last_end_us) {
            (Some(start), Some(end)) if end >= start => {
                let gap = at_us.saturating_sub(end);
                gap.saturating_mul(16) < at_us.saturating_sub(start)
            }
            _ => false,
        };
        self.run = if back_to_back != self.on {
            self.run.saturating_add(1)
        } else {
            0
        };
        if self.run >= BACKLOG_PULSES {
            self.on = !self.on;
            self.run = 0;
            return self.on;
        }
        false
    }

    fn pulse_ended(&mut self, at_us: u64) {
        self.last_end_us = Some(at_us);
    }
}

pub(super) struct Framer {
    aggressiveness: f32,
    /// The configured guide cadence (`guide_cadence_s`).
    cadence_us: u64,
    pulse_cadence: PulseCadence,
    backlog: Backlog,
    calibration: CalibrationWatch,
    dither_threshold_us: u64,
    silence_frames: u32,
    guide_arcsec_per_s: f32,

    open: Option<OpenFrame>,
    last_frame: Option<Mark>,
    /// Where the next filled frame goes (if the guider stays quiet) and its
    /// mark once the time has passed.
    fill_due_us: Option<u64>,
    fill_mark: Option<Mark>,
    /// Filled frames since the guider was last heard.
    quiet_fills: u32,
    last_activity_us: Option<u64>,
    queue: Deque<Frame, FRAME_QUEUE>,
}

impl Framer {
    pub fn new(
        aggressiveness: f32,
        cadence_us: u64,
        dither_threshold_us: u64,
        silence_frames: u32,
        guide_arcsec_per_s: f32,
        calibration_watch: bool,
    ) -> Self {
        Framer {
            aggressiveness,
            cadence_us,
            pulse_cadence: PulseCadence::default(),
            backlog: Backlog::default(),
            calibration: CalibrationWatch::new(calibration_watch),
            dither_threshold_us,
            silence_frames,
            guide_arcsec_per_s,
            open: None,
            last_frame: None,
            fill_due_us: None,
            fill_mark: None,
            quiet_fills: 0,
            last_activity_us: None,
            queue: Deque::new(),
        }
    }

    /// When the guider was last heard (a pulse start or end).
    pub fn last_activity_us(&self) -> Option<u64> {
        self.last_activity_us
    }

    /// The guider's RA pulses run back to back ([`Backlog`]).
    pub fn backlogged(&self) -> bool {
        self.backlog.on
    }

    /// The guider calibrates at `at_us` ([`super::calibration`]).
    pub fn calibrating(&self, at_us: u64) -> bool {
        self.calibration.active(at_us)
    }

    /// A pulse on `axis` ended: watch it for a calibration's steps.
    pub fn pulse_ended(
        &mut self,
        axis: Axis,
        direction: Direction,
        length_us: u64,
        at_us: u64,
        counters: &mut GuidingCounters,
    ) {
        let hold_us = self.fill_cadence_us().saturating_mul(HOLD_CADENCES);
        if self
            .calibration
            .pulse(axis, direction, length_us, at_us, hold_us)
        {
            counters.calibrations = counters.calibrations.saturating_add(1);
        }
    }

    /// Learning is frozen: the guider has been silent for too long.
    pub fn silent(&self) -> bool {
        self.quiet_fills > self.silence_frames
    }

    /// The cadence frames are filled at: the configured one, or the
    /// guider's measured one where that is more than half as long again
    /// (pulses skipped below the minimum move can make the measure longer
    /// than the guider's true cadence, never shorter: the margin keeps
    /// those from stretching a right configuration).
    pub fn fill_cadence_us(&self) -> u64 {
        match self.pulse_cadence.measured_us() {
            Some(m) if m / 3 > self.cadence_us / 2 => m,
            _ => self.cadence_us,
        }
    }

    /// The guider was heard at `at_us`.
    pub fn heard(&mut self, at_us: u64) {
        if self.fill_due_us.is_none() {
            self.fill_due_us = Some(at_us.saturating_add(self.fill_cadence_us()));
        }
        self.quiet_fills = 0;
        self.last_activity_us = Some(at_us);
    }

    /// An RA pulse started: it opens a frame at `mark`.
    pub fn open(&mut self, mark: Mark, direction: Direction, counters: &mut GuidingCounters) {
        let previous_start_us = self.pulse_cadence.last_start_us;
        self.pulse_cadence.pulse_started(mark.at_us);
        if self.backlog.pulse_started(mark.at_us, previous_start_us) {
            counters.backlogs = counters.backlogs.saturating_add(1);
        }
        self.fill_mark = None;
        self.open = Some(OpenFrame { mark, direction });
    }

    /// The RA pulse that started at `start_us` ended at `at_us`: complete
    /// its frame (a dither's move is taken out of C).
    pub fn close(
        &mut self,
        start_us: u64,
        at_us: u64,
        applied: &mut Applied,
        counters: &mut GuidingCounters,
    ) {
        let Some(open) = self.open.take() else {
            return;
        };
        self.backlog.pulse_ended(at_us);
        let duration_us = at_us.saturating_sub(start_us);
        self.pulse_ended(Axis::Ra, open.direction, duration_us, at_us, counters);
        let correction =
            open.direction.sign() * duration_us as f32 * 1e-6 * self.guide_arcsec_per_s;
        let kind = if duration_us > self.dither_threshold_us {
            applied.add_dither(correction as f64);
            counters.dithers = counters.dithers.saturating_add(1);
            FrameKind::Dither {
                amount_arcsec: correction,
            }
        } else if self.backlog.on {
            FrameKind::Unmeasured
        } else {
            FrameKind::Measured
        };
        self.emit(open.mark, kind, correction, false, counters);
        // The next filled frame: a cadence after this one, but not before
        // the pulse ended (the guider was busy with it).
        let due = open
            .mark
            .at_us
            .saturating_add(self.fill_cadence_us())
            .max(at_us);
        self.fill_due_us = Some(due);
    }

    /// Before C moves on to `now_us`: the mark of a filled frame that fell
    /// due meanwhile, taken while C still has the rate it had then.
    pub fn keep_fill_mark(&mut self, applied: &Applied, now_us: u64, ra_pulse: bool) {
        if let Some(due) = self.fill_due_us {
            if self.fill_mark.is_none() && due <= now_us && !ra_pulse {
                self.fill_mark = Some(applied.mark_at(due.max(applied.last_us())));
            }
        }
    }

    /// Emit the filled frame once its grace has passed without an RA pulse.
    pub fn fill(
        &mut self,
        now_us: u64,
        ra_pulse: bool,
        applied: &Applied,
        counters: &mut GuidingCounters,
    ) {
        if ra_pulse || self.open.is_some() {
            return;
        }
        let Some(due) = self.fill_due_us else {
            return;
        };
        let cadence_us = self.fill_cadence_us();
        let grace = cadence_us / 4;
        if now_us < due.saturating_add(grace) {
            return;
        }
        let mark = match self.fill_mark.take() {
            Some(m) => m,
            None => applied.mark_at(due.max(applied.last_us())),
        };
        self.quiet_fills = self.quiet_fills.saturating_add(1);
        let kind = if self.quiet_fills > self.silence_frames {
            if self.quiet_fills == self.silence_frames.saturating_add(1) {
                counters.silences = counters.silences.saturating_add(1);
            }
            FrameKind::Unmeasured
        } else {
            FrameKind::Measured
        };
        self.emit(mark, kind, 0.0, true, counters);
        self.fill_due_us = Some(mark.at_us.saturating_add(cadence_us.max(1)));
    }

    /// Queue the frame that ends at `mark`; a full queue drops its oldest.
    fn emit(
        &mut self,
        mark: Mark,
        kind: FrameKind,
        pulse_arcsec: f32,
        filled: bool,
        counters: &mut GuidingCounters,
    ) {
        let (applied, interval) = match self.last_frame {
            Some(prev) if mark.at_us > prev.at_us => (
                (mark.integral - prev.integral) / secs_between(mark.at_us, prev.at_us),
                (mark.gear_s - prev.gear_s).max(0.0),
            ),
            Some(prev) => (mark.c, (mark.gear_s - prev.gear_s).max(0.0)),
            None => (mark.c, 0.0),
        };
        let applied = applied as f32;
        // The port moved the axis (or stopped its tracking) meanwhile:
        // nothing of the gear was measured.
        let port_moved = self
            .last_frame
            .is_some_and(|prev| mark.port_us != prev.port_us);
        let kind = match kind {
            FrameKind::Measured | FrameKind::Unmeasured if port_moved => FrameKind::Moved,
            FrameKind::Measured | FrameKind::Unmeasured if self.calibrating(mark.at_us) => {
                FrameKind::Calibration
            }
            kind => kind,
        };
        let gear_error = match kind {
            FrameKind::Measured if self.aggressiveness > 0.0 => {
                applied + pulse_arcsec / self.aggressiveness
            }
            _ => applied,
        };
        let frame = Frame {
            gear_time_s: mark.gear_s,
            interval_s: interval as f32,
            kind,
            gear_error_arcsec: gear_error,
            applied_arcsec: applied,
            pulse_arcsec,
            filled,
        };
        self.last_frame = Some(mark);
        let c = counters;
        c.frames = c.frames.saturating_add(1);
        if filled {
            c.filled_frames = c.filled_frames.saturating_add(1);
        }
        if matches!(
            kind,
            FrameKind::Unmeasured | FrameKind::Moved | FrameKind::Calibration
        ) {
            c.unmeasured_frames = c.unmeasured_frames.saturating_add(1);
        }
        if self.queue.is_full() {
            self.queue.pop_front();
            c.frames_dropped = c.frames_dropped.saturating_add(1);
        }
        // Cannot fail: there is room now.
        let _ = self.queue.push_back(frame);
    }

    /// The next completed frame for the learner, oldest first.
    pub fn take(&mut self) -> Option<Frame> {
        self.queue.pop_front()
    }
}
