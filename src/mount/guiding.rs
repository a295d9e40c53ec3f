//! From ST4 pulses and time to step rates, and the learning of the gear error
//! from what the mount did (docs/reference.md section 1).
//!
//! Two parts, for two priorities:
//!
//! - [`Guiding`], the fast part: runs in the high-priority task on every ST4
//!   event and every rate update. Constant time, a few dozen floating-point
//!   operations (some in `f64`, software-emulated on the Cortex-M4F: a few
//!   microseconds at 96 MHz), never the model. It turns the active pulses and
//!   the installed feed-forward into step rates, and forms the guide
//!   [`Frame`]s (gear-error observations) for the learner.
//! - [`Learner`], the slow part: owns the model (`Guider<f32, N>`, about
//!   55 KiB: the firmware keeps it in a static) and runs in a task of lower
//!   priority than ST4 and stepping, once per frame; it returns the
//!   [`FeedForward`] that the fast part applies until the next one.
//!
//! # Units and signs
//!
//! - Angles are arcseconds of RA on the sky; rates of the motors are steps
//!   per second; the feed-forward is arcsec per second of gear time.
//! - A positive RA correction makes the RA axis run faster than sidereal:
//!   RA+ (west) pulses are positive, RA- negative. The gear error `g` is the
//!   amount by which the axis lags the sky because of the gears, so the
//!   correction that cancels it is `+g`. (In the simulator 1 px = 1 arcsec.)
//! - The applied correction `C(t)` is everything that is not tracking: the
//!   RA step count since the first [`Guiding::rates`] call minus the steps
//!   of exact sidereal tracking over the same wall-clock time, in arcsec
//!   (`(steps - sidereal steps) x arcsec per step`), pulses and feed-forward
//!   together, measured from the steps actually emitted (so a clamped or
//!   quantised rate is accounted for exactly), minus the moves of the dithers
//!   (a dither moves the guider's lock position together with the mount, so
//!   it is no gear error).
//! - Gear time is `ra_steps / sidereal steps per second` (seconds): the
//!   worm turns with the steps, so guide pulses and feed-forward advance the
//!   worm phase exactly as much as they advance the gear, and the phase is
//!   exact whatever the guiding did. A slew or a reset of the step counter
//!   is a jump in gear time (the model handles a long jump by starting its
//!   data again).
//!
//! # Frames: what the model learns
//!
//! A frame starts at each RA pulse start (the guider has just finished an
//! exposure and measured; ST4 gives the edge's own time). When the guider
//! sends no RA pulse for a guide cadence (`guide_cadence_s`, default 2 s),
//! a frame is filled at `previous frame + cadence` (emitted after a grace
//! of a quarter cadence, in case the pulse is just late). Its observation:
//!
//! `gear error = mean of C over the interval since the previous frame
//!               + the frame's RA pulse correction / aggressiveness`
//!
//! The pulse correction is duration x guide rate (arcsec, signed); the
//! guider asked for that much of the error it measured, so the error was
//! about correction / aggressiveness (`guider_aggressiveness`, default 0.7;
//! a filled frame has correction 0: the guider saw less than its minimum
//! move). The mean of C over the interval matches what the guider measured:
//! the exposure averages the star over about that interval, and the model
//! stamps a frame at the midpoint of the interval since the previous one.
//! The frame is emitted when its pulse ends (its duration is known only
//! then) and stamped with the gear time of the pulse start.
//!
//! # Feed-forward
//!
//! The model's [`Guider::observe`] returns the predicted change of the gear
//! error from the frame's timestamp (the midpoint of the last interval,
//! `t - d/2`) to `t + time_step`. The learner asks for `time_step = T + d/2`
//! with `T` the expected time to the next frame (the last interval, within
//! half to twice the cadence), so that the window `[t - d/2, t + T + d/2]`
//! is centred on the middle of the coming interval, and turns it into the
//! rate `change / (T + d)` (arcsec per second of gear time), which the fast
//! part adds to the RA rate from the moment it is installed until the next
//! one (at most until [`FeedForward::until_gear_s`], then 0). The model
//! weighs its prediction by its blend weight: 0 until it has earned trust.
//! The rate is limited to the guide rate: a gear error changing faster than
//! that is no gear error.
//!
//! # Dithers and silence
//!
//! - An RA pulse longer than `dither_threshold_us` is a dither: its move is
//!   taken out of C, the frame is not learned, and the model is told with
//!   [`Guider::dithered`] so that it settles for [`DITHER_FRAMES`] frames
//!   without learning. The amount passed is 0: the model's dither offset
//!   shifts its time axis by amount / rate, which for a PC guider stands for
//!   the worm phase the dither moved; here gear time comes from the steps,
//!   which already include the dither's steps, so passing the amount would
//!   shift the phase twice.
//! - Silence: after more than `silence_frames` filled frames in a row with
//!   no pulse on either axis, learning freezes: the frames are passed to the
//!   model as unmeasured (`None`), so the model keeps predicting from what
//!   it learned and the feed-forward is extrapolated. At most one worm
//!   period after the guider's last pulse the feed-forward is faded out
//!   linearly over [`FADE_FRAMES`] cadences, and stays 0 until the guider
//!   sends a pulse again.
//!
//! # Rates
//!
//! `RA = sidereal + guide rate x (+1 RA+, -1 RA-, 0) + feed-forward`, in
//! [0, max] (the RA axis never reverses: below 0 it is clamped, counted in
//! [`GuidingCounters::ra_clamped`]). `Dec = guide rate x (+1 Dec+ north,
//! -1 Dec-, 0)`: signed, the sign is the direction, and `|Dec| <= max`.
//! NaN never leaves: every input that could carry one is checked.
//!
//! # Latency on an ST4 edge (worst case)
//!
//! The edge is timestamped by the hal's interrupt; the ST4 logic confirms a
//! start after `glitch_us` (default 1 ms: the only deliberate delay, against
//! contact bounce) and a release at once. The high-priority task then runs
//! `St4::poll`, [`Guiding::on_event`] and [`Guiding::rates`] (about 3,200
//! instructions together, mostly the soft-float `f64` parts: ~45 us at
//! 96 MHz) and sets the step generator, whose next step follows within one
//! step period. The model runs in a lower-priority task (about 1.5 M
//! instructions, 20-30 ms at 96 MHz) and is preempted, so it never adds to
//! this: worst case `glitch_us + ~70 us + one timer tick (20 us at 50 kHz)`
//! from the edge to the new rate for a start, `~70 us + one tick` for an end
//! (the firmware's `main.rs` itemises it). The time a
//! confirmed start waited (the glitch time) is not made up, so a pulse moves
//! `glitch_us x guide rate` less than asked (7.5 milli-arcsec at 0.5x); C
//! counts the steps actually made, so the learning is not biased by it.

use crate::model::guider::{Guider, GuiderConfig, DITHER_FRAMES};
use crate::mount::config::{Mount, SIDEREAL_ARCSEC_PER_S};
use crate::mount::st4::{Axis, Direction, St4Event};

/// Cadences over which the feed-forward is faded out after a silence.
pub const FADE_FRAMES: u32 = 5;
/// Frames the fast part keeps for the learner; when the learner falls this
/// far behind the oldest is dropped (counted in `frames_dropped`).
pub const FRAME_QUEUE: usize = 4;

/// The step rates to set now.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Rates {
    /// RA motor, steps/s, in [0, max]; forward (the tracking direction).
    pub ra_steps_per_s: f32,
    /// Dec motor, steps/s, signed: positive = north; |rate| <= max.
    pub dec_steps_per_s: f32,
}

/// What a frame tells the model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FrameKind {
    /// The guider was heard: [`Frame::gear_error_arcsec`] is an observation.
    Measured,
    /// The guider has been silent for more than `silence_frames`: nothing
    /// was measured; the model only keeps its clock.
    Unmeasured,
    /// The frame's RA pulse was a dither of this many arcsec (signed); not
    /// learned, and the model settles.
    Dither { amount_arcsec: f32 },
}

/// One guide frame: a gear-error observation for the learner.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// Gear time of the frame (seconds; see the module doc): the RA pulse's
    /// start, or `previous frame + cadence` for a filled frame.
    pub gear_time_s: f64,
    /// Gear time since the previous frame, seconds (0 for the first).
    pub interval_s: f32,
    pub kind: FrameKind,
    /// The observation, arcsec: `applied_arcsec + pulse_arcsec /
    /// aggressiveness` for a measured frame; `applied_arcsec` otherwise.
    pub gear_error_arcsec: f32,
    /// Mean applied correction C over the interval since the previous frame
    /// (arcsec; the first frame: C at the frame).
    pub applied_arcsec: f32,
    /// Signed correction the frame's RA pulse asked for (duration x guide
    /// rate, arcsec; RA+ positive); 0 for a filled frame.
    pub pulse_arcsec: f32,
    /// Made by the cadence, not by a pulse.
    pub filled: bool,
}

/// The learner's feed-forward: an extra RA rate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FeedForward {
    /// Arcsec of RA per second of gear time; positive = faster.
    pub rate_arcsec_per_s: f32,
    /// Gear time of the frame it was computed for (seconds).
    pub from_gear_s: f64,
    /// Not applied beyond this gear time (seconds) unless replaced.
    pub until_gear_s: f64,
}

impl FeedForward {
    /// No feed-forward.
    pub const NONE: FeedForward = FeedForward {
        rate_arcsec_per_s: 0.0,
        from_gear_s: 0.0,
        until_gear_s: 0.0,
    };
}

/// What the fast part saw and did, counted since construction.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GuidingCounters {
    /// Pulse starts per axis.
    pub ra_pulses: u32,
    pub dec_pulses: u32,
    /// Frames made (all kinds), and of them: filled by the cadence, in
    /// silence (unmeasured), dithers.
    pub frames: u32,
    pub filled_frames: u32,
    pub unmeasured_frames: u32,
    pub dithers: u32,
    /// Times learning froze because the guider fell silent.
    pub silences: u32,
    /// Times the feed-forward was faded out completely after a silence.
    pub feed_forward_faded: u32,
    /// Feed-forwards refused (non-finite) or limited to the guide rate.
    pub feed_forward_rejected: u32,
    pub feed_forward_limited: u32,
    /// Feed-forwards that ran out (no newer one by `until_gear_s`).
    pub feed_forward_expired: u32,
    /// Frames dropped because the learner was [`FRAME_QUEUE`] behind.
    pub frames_dropped: u32,
    /// `rates` calls whose RA or Dec rate had to be clamped into range.
    pub ra_clamped: u32,
    pub dec_clamped: u32,
    /// `rates` calls with a time earlier than the previous one (ignored).
    pub time_backwards: u32,
    /// Pulse ends for an axis without a pulse (ignored).
    pub stray_ends: u32,
}

/// The state of C (applied correction) at one instant.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Mark {
    at_us: u64,
    gear_s: f64,
    /// C at the instant, arcsec.
    c: f64,
    /// Integral of C over wall time since the origin, arcsec s.
    integral: f64,
}

#[derive(Clone, Copy, Debug, PartialEq)]
struct OpenFrame {
    mark: Mark,
    direction: Direction,
}

/// The fast part: pulses and time to rates, and the guide frames.
pub struct Guiding {
    // Constants from the mount.
    sidereal_sps: f64,
    arcsec_per_step: f64,
    ra_guide_sps: f32,
    dec_guide_sps: f32,
    max_ra_sps: f32,
    max_dec_sps: f32,
    guide_arcsec_per_s: f32,
    aggressiveness: f32,
    cadence_us: u64,
    dither_threshold_us: u64,
    silence_frames: u32,
    worm_period_us: u64,

    ra_pulse: Option<(Direction, u64)>,
    dec_pulse: Option<(Direction, u64)>,

    /// Wall time and step count of the first `rates` call.
    origin: Option<(u64, i64)>,
    last_us: u64,
    last_steps: i64,
    last_c: f64,
    integral: f64,
    last_ra_sps: f32,
    /// Sum of the dithers' moves, arcsec, taken out of C.
    dither_offset: f64,

    open: Option<OpenFrame>,
    last_frame: Option<Mark>,
    /// Where the next filled frame goes (if the guider stays quiet) and its
    /// mark once the time has passed.
    fill_due_us: Option<u64>,
    fill_mark: Option<Mark>,
    /// Filled frames since the guider was last heard.
    quiet_fills: u32,
    last_activity_us: Option<u64>,
    faded: bool,

    queue: [Option<Frame>; FRAME_QUEUE],
    head: usize,
    len: usize,

    feed_forward: FeedForward,
    ff_active: bool,
    counters: GuidingCounters,
}

fn sign(d: Direction) -> f32 {
    match d {
        Direction::Plus => 1.0,
        Direction::Minus => -1.0,
    }
}

/// Signed difference a - b of two microsecond times, in seconds.
fn secs_between(a: u64, b: u64) -> f64 {
    if a >= b {
        (a - b) as f64 * 1e-6
    } else {
        -((b - a) as f64 * 1e-6)
    }
}

fn finite_or_zero(x: f32) -> f32 {
    if x.is_finite() {
        x
    } else {
        0.0
    }
}

impl Guiding {
    pub fn new(mount: &Mount) -> Self {
        let c = mount.config();
        let sidereal_sps = mount.sidereal_ra_steps_per_s_f64();
        let arcsec_per_step = SIDEREAL_ARCSEC_PER_S / sidereal_sps;
        let guide_arcsec_per_s = mount.guide_rate_arcsec_per_s();
        let worm_us = c.worm_period_s as f64 * 1e6;
        Guiding {
            sidereal_sps,
            arcsec_per_step,
            ra_guide_sps: finite_or_zero(mount.guide_ra_steps_per_s()),
            dec_guide_sps: finite_or_zero(mount.guide_dec_steps_per_s()),
            max_ra_sps: finite_or_zero(mount.max_ra_steps_per_s()),
            max_dec_sps: finite_or_zero(mount.max_dec_steps_per_s()),
            guide_arcsec_per_s,
            aggressiveness: c.guider_aggressiveness,
            cadence_us: (c.guide_cadence_s as f64 * 1e6) as u64,
            dither_threshold_us: c.dither_threshold_us as u64,
            silence_frames: c.silence_frames,
            worm_period_us: worm_us as u64,
            ra_pulse: None,
            dec_pulse: None,
            origin: None,
            last_us: 0,
            last_steps: 0,
            last_c: 0.0,
            integral: 0.0,
            last_ra_sps: 0.0,
            dither_offset: 0.0,
            open: None,
            last_frame: None,
            fill_due_us: None,
            fill_mark: None,
            quiet_fills: 0,
            last_activity_us: None,
            faded: false,
            queue: [None; FRAME_QUEUE],
            head: 0,
            len: 0,
            feed_forward: FeedForward::NONE,
            ff_active: false,
            counters: GuidingCounters::default(),
        }
    }

    pub fn counters(&self) -> GuidingCounters {
        self.counters
    }

    /// Gear time now (seconds), from the last `rates` call's step count.
    pub fn gear_time_s(&self) -> f64 {
        self.last_steps as f64 / self.sidereal_sps
    }

    /// The applied correction C at the last `rates` call, arcsec.
    pub fn applied_arcsec(&self) -> f64 {
        self.last_c
    }

    /// The feed-forward rate in effect at the last `rates` call, after the
    /// fade, arcsec/s.
    pub fn feed_forward_now(&self) -> f32 {
        self.ff_rate(self.last_us)
    }

    /// Learning is frozen: the guider has been silent for too long.
    pub fn silent(&self) -> bool {
        self.quiet_fills > self.silence_frames
    }

    /// C, its integral and the gear time at `at_us`, extrapolated from the
    /// last `rates` call with the rate set then (exact between calls).
    fn mark_at(&self, at_us: u64) -> Mark {
        if self.origin.is_none() {
            return Mark {
                at_us,
                gear_s: 0.0,
                c: 0.0,
                integral: 0.0,
            };
        }
        let dt = secs_between(at_us, self.last_us);
        let extra_sps = self.last_ra_sps as f64 - self.sidereal_sps;
        let c = self.last_c + extra_sps * self.arcsec_per_step * dt;
        Mark {
            at_us,
            gear_s: (self.last_steps as f64 + self.last_ra_sps as f64 * dt) / self.sidereal_sps,
            c,
            integral: self.integral + 0.5 * (self.last_c + c) * dt,
        }
    }

    fn heard(&mut self, at_us: u64) {
        if self.fill_due_us.is_none() {
            self.fill_due_us = Some(at_us.saturating_add(self.cadence_us));
        }
        self.quiet_fills = 0;
        self.faded = false;
        self.last_activity_us = Some(at_us);
    }

    pub fn on_event(&mut self, ev: St4Event) {
        match ev {
            St4Event::PulseStart {
                axis: Axis::Ra,
                direction,
                at_us,
            } => {
                self.counters.ra_pulses = self.counters.ra_pulses.saturating_add(1);
                if self.ra_pulse.is_some() {
                    // A start without an end: end the old pulse here.
                    self.end_ra(at_us);
                }
                self.heard(at_us);
                self.ra_pulse = Some((direction, at_us));
                self.fill_mark = None;
                self.open = Some(OpenFrame {
                    mark: self.mark_at(at_us),
                    direction,
                });
            }
            St4Event::PulseStart {
                axis: Axis::Dec,
                direction,
                at_us,
            } => {
                self.counters.dec_pulses = self.counters.dec_pulses.saturating_add(1);
                self.heard(at_us);
                self.dec_pulse = Some((direction, at_us));
            }
            St4Event::PulseEnd {
                axis: Axis::Ra,
                at_us,
            } => {
                if self.ra_pulse.is_none() {
                    self.counters.stray_ends = self.counters.stray_ends.saturating_add(1);
                    return;
                }
                self.heard(at_us);
                self.end_ra(at_us);
            }
            St4Event::PulseEnd {
                axis: Axis::Dec,
                at_us,
            } => {
                if self.dec_pulse.take().is_none() {
                    self.counters.stray_ends = self.counters.stray_ends.saturating_add(1);
                    return;
                }
                self.heard(at_us);
            }
        }
    }

    /// The RA pulse ended at `at_us`: complete its frame.
    fn end_ra(&mut self, at_us: u64) {
        let Some((_, start_us)) = self.ra_pulse.take() else {
            return;
        };
        let Some(open) = self.open.take() else {
            return;
        };
        let duration_us = at_us.saturating_sub(start_us);
        let correction = sign(open.direction) * duration_us as f32 * 1e-6 * self.guide_arcsec_per_s;
        let kind = if duration_us > self.dither_threshold_us {
            self.dither_offset += correction as f64;
            self.counters.dithers = self.counters.dithers.saturating_add(1);
            FrameKind::Dither {
                amount_arcsec: correction,
            }
        } else {
            FrameKind::Measured
        };
        self.emit(open.mark, kind, correction, false);
        // The next filled frame: a cadence after this one, but not before
        // the pulse ended (the guider was busy with it).
        let due = open.mark.at_us.saturating_add(self.cadence_us).max(at_us);
        self.fill_due_us = Some(due);
    }

    /// Queue the frame that ends at `mark`.
    fn emit(&mut self, mark: Mark, kind: FrameKind, pulse_arcsec: f32, filled: bool) {
        let (applied, interval) = match self.last_frame {
            Some(prev) if mark.at_us > prev.at_us => (
                (mark.integral - prev.integral) / secs_between(mark.at_us, prev.at_us),
                (mark.gear_s - prev.gear_s).max(0.0),
            ),
            Some(prev) => (mark.c, (mark.gear_s - prev.gear_s).max(0.0)),
            None => (mark.c, 0.0),
        };
        let applied = applied as f32;
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
        let c = &mut self.counters;
        c.frames = c.frames.saturating_add(1);
        if filled {
            c.filled_frames = c.filled_frames.saturating_add(1);
        }
        if kind == FrameKind::Unmeasured {
            c.unmeasured_frames = c.unmeasured_frames.saturating_add(1);
        }
        if self.len == FRAME_QUEUE {
            self.head = (self.head + 1) % FRAME_QUEUE;
            self.len -= 1;
            c.frames_dropped = c.frames_dropped.saturating_add(1);
        }
        let tail = (self.head + self.len) % FRAME_QUEUE;
        if let Some(slot) = self.queue.get_mut(tail) {
            *slot = Some(frame);
            self.len += 1;
        }
    }

    /// The next completed frame for the learner, oldest first.
    pub fn take_frame(&mut self) -> Option<Frame> {
        if self.len == 0 {
            return None;
        }
        let f = self.queue.get_mut(self.head).and_then(Option::take);
        self.head = (self.head + 1) % FRAME_QUEUE;
        self.len -= 1;
        f
    }

    /// Install the learner's newest feed-forward. A non-finite one is
    /// refused (no feed-forward until the next); the rate is limited to the
    /// guide rate.
    pub fn set_feed_forward(&mut self, ff: FeedForward) {
        if !(ff.rate_arcsec_per_s.is_finite()
            && ff.from_gear_s.is_finite()
            && ff.until_gear_s.is_finite())
        {
            self.counters.feed_forward_rejected =
                self.counters.feed_forward_rejected.saturating_add(1);
            self.feed_forward = FeedForward::NONE;
            self.ff_active = false;
            return;
        }
        let limit = self.guide_arcsec_per_s;
        let mut ff = ff;
        if ff.rate_arcsec_per_s.abs() > limit {
            self.counters.feed_forward_limited =
                self.counters.feed_forward_limited.saturating_add(1);
            ff.rate_arcsec_per_s = ff.rate_arcsec_per_s.clamp(-limit, limit);
        }
        self.feed_forward = ff;
        self.ff_active = true;
    }

    /// Fade factor of the feed-forward at `now_us`: 1 until one worm period
    /// after the guider was last heard, then down to 0 over FADE_FRAMES
    /// cadences.
    fn fade(&self, now_us: u64) -> f32 {
        let Some(last) = self.last_activity_us else {
            return 1.0;
        };
        let quiet = now_us.saturating_sub(last);
        if quiet <= self.worm_period_us {
            return 1.0;
        }
        let fade_us = self.cadence_us.saturating_mul(FADE_FRAMES as u64).max(1);
        let over = (quiet - self.worm_period_us) as f64 / fade_us as f64;
        (1.0 - over).max(0.0) as f32
    }

    fn ff_rate(&self, now_us: u64) -> f32 {
        if !self.ff_active {
            return 0.0;
        }
        self.feed_forward.rate_arcsec_per_s * self.fade(now_us)
    }

    /// The RA step count (signed, as emitted by the stepper) and the time:
    /// returns the rates to set now. Also makes the filled frames.
    pub fn rates(&mut self, now_us: u64, ra_steps: i64) -> Rates {
        match self.origin {
            None => {
                self.origin = Some((now_us, ra_steps));
                self.last_us = now_us;
                self.last_steps = ra_steps;
                self.last_c = -self.dither_offset;
            }
            Some(_) if now_us < self.last_us => {
                self.counters.time_backwards = self.counters.time_backwards.saturating_add(1);
                self.last_steps = ra_steps;
            }
            Some((t0, s0)) => {
                if let Some(due) = self.fill_due_us {
                    if self.fill_mark.is_none() && due <= now_us && self.ra_pulse.is_none() {
                        self.fill_mark = Some(self.mark_at(due.max(self.last_us)));
                    }
                }
                let dt = secs_between(now_us, self.last_us);
                let not_tracking =
                    ra_steps.wrapping_sub(s0) as f64 - self.sidereal_sps * secs_between(now_us, t0);
                let c = not_tracking * self.arcsec_per_step - self.dither_offset;
                self.integral += 0.5 * (self.last_c + c) * dt;
                self.last_c = c;
                self.last_us = now_us;
                self.last_steps = ra_steps;
            }
        }
        self.fill(now_us);

        // Feed-forward, expired or faded.
        let gear_now = self.gear_time_s();
        if self.ff_active && gear_now > self.feed_forward.until_gear_s {
            self.ff_active = false;
            self.counters.feed_forward_expired =
                self.counters.feed_forward_expired.saturating_add(1);
        }
        let fade = self.fade(now_us);
        if fade == 0.0 && !self.faded && self.ff_active {
            self.faded = true;
            self.counters.feed_forward_faded = self.counters.feed_forward_faded.saturating_add(1);
        }
        let ff_sps = self.ff_rate(now_us) as f64 / self.arcsec_per_step;

        let guide = self.ra_pulse.map_or(0.0, |(d, _)| sign(d)) * self.ra_guide_sps;
        let ra = (self.sidereal_sps + guide as f64 + ff_sps) as f32;
        let ra_clamped = if ra.is_finite() {
            ra.clamp(0.0, self.max_ra_sps)
        } else {
            (self.sidereal_sps as f32).clamp(0.0, self.max_ra_sps)
        };
        if ra_clamped != ra {
            self.counters.ra_clamped = self.counters.ra_clamped.saturating_add(1);
        }
        let dec = self.dec_pulse.map_or(0.0, |(d, _)| sign(d)) * self.dec_guide_sps;
        let dec_clamped = if dec.is_finite() {
            dec.clamp(-self.max_dec_sps, self.max_dec_sps)
        } else {
            0.0
        };
        if dec_clamped != dec {
            self.counters.dec_clamped = self.counters.dec_clamped.saturating_add(1);
        }
        self.last_ra_sps = ra_clamped;
        Rates {
            ra_steps_per_s: ra_clamped,
            dec_steps_per_s: dec_clamped,
        }
    }

    /// Emit the filled frame once its grace has passed without an RA pulse.
    fn fill(&mut self, now_us: u64) {
        if self.ra_pulse.is_some() || self.open.is_some() {
            return;
        }
        let Some(due) = self.fill_due_us else {
            return;
        };
        let grace = self.cadence_us / 4;
        if now_us < due.saturating_add(grace) {
            return;
        }
        let mark = match self.fill_mark.take() {
            Some(m) => m,
            None => self.mark_at(due.max(self.last_us)),
        };
        self.quiet_fills = self.quiet_fills.saturating_add(1);
        let kind = if self.quiet_fills > self.silence_frames {
            if self.quiet_fills == self.silence_frames.saturating_add(1) {
                self.counters.silences = self.counters.silences.saturating_add(1);
            }
            FrameKind::Unmeasured
        } else {
            FrameKind::Measured
        };
        self.emit(mark, kind, 0.0, true);
        self.fill_due_us = Some(mark.at_us.saturating_add(self.cadence_us.max(1)));
    }
}

/// What the learner did, counted since construction.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LearnerCounters {
    /// Frames given to the model (one `observe` call each).
    pub frames: u32,
    /// Of them learned as observations of the gear error.
    pub learned: u32,
    /// Passed as unmeasured: silence, dithers and the frames settling after
    /// one.
    pub not_learned: u32,
    /// Dithers the model was told about.
    pub dithers: u32,
}

/// The slow part: the model. Call [`learn`](Self::learn) once per frame
/// from a task of lower priority than the ST4 and stepping task.
pub struct Learner<const N: usize> {
    guider: Guider<f32, N>,
    /// The SNR given to the model with each observation (<= 0: unknown,
    /// the model's default 10): sets the measurement variance.
    pub snr: f32,
    cadence_s: f32,
    last_gear_s: Option<f64>,
    settling: u8,
    counters: LearnerCounters,
}

impl<const N: usize> Learner<N> {
    /// The model with the library's defaults, the worm period of the mount
    /// as its prior period.
    pub fn new(mount: &Mount) -> Self {
        let c = mount.config();
        let config = GuiderConfig::<f32> {
            prior_period_s: c.worm_period_s as f64,
            control_gain: c.guider_aggressiveness,
            ..GuiderConfig::default()
        };
        Self::with_config(mount, config)
    }

    /// The model with another configuration (the control and prediction
    /// gains are not used: the learner only observes).
    pub fn with_config(mount: &Mount, config: GuiderConfig<f32>) -> Self {
        let c = mount.config();
        Learner {
            guider: Guider::new(config),
            snr: 0.0,
            cadence_s: c.guide_cadence_s,
            last_gear_s: None,
            settling: 0,
            counters: LearnerCounters::default(),
        }
    }

    pub fn guider(&self) -> &Guider<f32, N> {
        &self.guider
    }

    pub fn counters(&self) -> LearnerCounters {
        self.counters
    }

    /// Learn one frame and return the feed-forward for the time to the next.
    pub fn learn(&mut self, frame: Frame) -> FeedForward {
        let t = frame.gear_time_s;
        let d = match self.last_gear_s {
            Some(prev) if t >= prev => t - prev,
            _ => 0.0,
        };
        if t.is_finite() {
            self.last_gear_s = Some(t);
        }
        let cadence = self.cadence_s as f64;
        // Expected time to the next frame: the last interval, within half
        // to twice the cadence.
        let next = if d > 0.0 {
            d.clamp(0.5 * cadence, 2.0 * cadence)
        } else {
            cadence
        };
        if let FrameKind::Dither { .. } = frame.kind {
            // Settle without learning. Amount 0: see the module doc.
            self.guider.dithered(0.0, 1.0);
            self.settling = DITHER_FRAMES;
            self.counters.dithers = self.counters.dithers.saturating_add(1);
        }
        // The guider counts its settling frames itself (the dither frame is
        // the first); this mirror only feeds the counters.
        let settling = self.settling > 0;
        if settling {
            self.settling -= 1;
        }
        let observation = match frame.kind {
            FrameKind::Measured if !settling => Some(frame.gear_error_arcsec as f64),
            _ => None,
        };
        self.counters.frames = self.counters.frames.saturating_add(1);
        if observation.is_some() {
            self.counters.learned = self.counters.learned.saturating_add(1);
        } else {
            self.counters.not_learned = self.counters.not_learned.saturating_add(1);
        }
        let step = next + 0.5 * d;
        let change = self.guider.observe(
            t,
            observation,
            frame.applied_arcsec as f64,
            self.snr,
            step as f32,
        );
        let rate = change as f64 / (next + d);
        let rate = if rate.is_finite() { rate as f32 } else { 0.0 };
        FeedForward {
            rate_arcsec_per_s: rate,
            from_gear_s: t,
            until_gear_s: t + 3.0 * next.max(cadence),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mount::config::MountConfig;

    fn mount() -> Mount {
        MountConfig::default().validate().unwrap()
    }

    fn start(dir: Direction, at_us: u64) -> St4Event {
        St4Event::PulseStart {
            axis: Axis::Ra,
            direction: dir,
            at_us,
        }
    }

    fn end(at_us: u64) -> St4Event {
        St4Event::PulseEnd {
            axis: Axis::Ra,
            at_us,
        }
    }

    /// Drive `g` with the steps its own rates make, every `step_us`, up to
    /// `until_us`; returns the step position (fractional).
    fn track(g: &mut Guiding, from_us: u64, until_us: u64, pos: &mut f64) -> Rates {
        let mut t = from_us;
        let mut r = g.rates(t, pos.floor() as i64);
        while t < until_us {
            let next = (t + 10_000).min(until_us);
            *pos += r.ra_steps_per_s as f64 * (next - t) as f64 * 1e-6;
            t = next;
            r = g.rates(t, pos.floor() as i64);
        }
        r
    }

    #[test]
    fn rates_follow_pulses() {
        let m = mount();
        let mut g = Guiding::new(&m);
        let sid = m.sidereal_ra_steps_per_s();
        let guide = m.guide_ra_steps_per_s();
        assert!((g.rates(0, 0).ra_steps_per_s - sid).abs() < 1e-3);
        g.on_event(start(Direction::Plus, 1_000));
        let r = g.rates(2_000, 0);
        assert!((r.ra_steps_per_s - (sid + guide)).abs() < 1e-3);
        g.on_event(end(101_000));
        g.on_event(start(Direction::Minus, 200_000));
        let r = g.rates(201_000, 30);
        assert!((r.ra_steps_per_s - (sid - guide)).abs() < 1e-3);
        g.on_event(St4Event::PulseStart {
            axis: Axis::Dec,
            direction: Direction::Minus,
            at_us: 201_000,
        });
        let r = g.rates(202_000, 30);
        assert!((r.dec_steps_per_s + m.guide_dec_steps_per_s()).abs() < 1e-3);
        assert_eq!(g.counters().ra_pulses, 2);
        assert_eq!(g.counters().dec_pulses, 1);
    }

    #[test]
    fn feed_forward_is_checked_and_limited() {
        let m = mount();
        let mut g = Guiding::new(&m);
        g.rates(0, 0);
        g.set_feed_forward(FeedForward {
            rate_arcsec_per_s: f32::NAN,
            from_gear_s: 0.0,
            until_gear_s: 10.0,
        });
        assert_eq!(g.counters().feed_forward_rejected, 1);
        let r = g.rates(1_000, 0);
        assert!((r.ra_steps_per_s - m.sidereal_ra_steps_per_s()).abs() < 1e-3);
        g.set_feed_forward(FeedForward {
            rate_arcsec_per_s: -1e9,
            from_gear_s: 0.0,
            until_gear_s: 10.0,
        });
        assert_eq!(g.counters().feed_forward_limited, 1);
        g.on_event(start(Direction::Minus, 2_000));
        // Sidereal - guide - guide rate of feed-forward: 0 at 0.5x, never below.
        let r = g.rates(3_000, 0);
        assert!(r.ra_steps_per_s >= 0.0 && r.ra_steps_per_s <= m.max_ra_steps_per_s());
        assert!(r.ra_steps_per_s < 1e-3, "{}", r.ra_steps_per_s);
        // Expired after until_gear_s.
        let mut pos = 0.0;
        g.on_event(end(4_000));
        let r = track(&mut g, 4_000, 25_000_000, &mut pos);
        assert_eq!(g.counters().feed_forward_expired, 1);
        assert!((r.ra_steps_per_s - m.sidereal_ra_steps_per_s()).abs() < 1e-3);
    }

    #[test]
    fn a_pulse_makes_an_observation() {
        let m = mount();
        let mut g = Guiding::new(&m);
        let mut pos = 0.0;
        track(&mut g, 0, 2_000_000, &mut pos);
        g.on_event(start(Direction::Plus, 2_000_000));
        track(&mut g, 2_000_000, 2_400_000, &mut pos);
        g.on_event(end(2_400_000));
        let f = g.take_frame().expect("a frame");
        assert_eq!(f.kind, FrameKind::Measured);
        let want = 0.4 * m.guide_rate_arcsec_per_s();
        assert!((f.pulse_arcsec - want).abs() < 1e-4, "{f:?}");
        // Nothing but tracking before the pulse: C = 0 within a step.
        assert!(f.applied_arcsec.abs() < m.arcsec_per_ra_step(), "{f:?}");
        let obs = f.applied_arcsec + want / 0.7;
        assert!((f.gear_error_arcsec - obs).abs() < 1e-4);
        assert!((f.gear_time_s - 2.0).abs() < 0.01, "{f:?}");
        assert!(g.take_frame().is_none());
        // The next frame's applied correction is the mean of C over the
        // interval: the pulse's 0.4 s x guide rate ramp, then constant.
        track(&mut g, 2_400_000, 4_000_000, &mut pos);
        g.on_event(start(Direction::Minus, 4_000_000));
        g.on_event(end(4_100_000));
        let f = g.take_frame().expect("a frame");
        let c = want as f64;
        let mean = (0.5 * c * 0.4 + c * 1.6) / 2.0;
        assert!(
            (f.applied_arcsec as f64 - mean).abs() < 2.0 * m.arcsec_per_ra_step() as f64,
            "{f:?} vs {mean}"
        );
        // Gear time runs with the steps: the 0.4 s RA+ pulse at 0.5x moved
        // the worm 0.2 s ahead.
        assert!((f.interval_s - 2.2).abs() < 0.01, "{f:?}");
        assert!((f.gear_time_s - 4.2).abs() < 0.01, "{f:?}");
    }

    #[test]
    fn silence_fills_then_freezes_then_fades() {
        let m = mount();
        let cfg = m.config();
        let mut g = Guiding::new(&m);
        let mut pos = 0.0;
        track(&mut g, 0, 1_000_000, &mut pos);
        g.on_event(start(Direction::Plus, 1_000_000));
        g.on_event(end(1_050_000));
        g.set_feed_forward(FeedForward {
            rate_arcsec_per_s: 0.5,
            from_gear_s: 1.0,
            until_gear_s: 1e9,
        });
        // Up to just before one worm period after the pulse (its end, the
        // last the guider was heard): full feed-forward.
        let worm_us = (cfg.worm_period_s as f64 * 1e6) as u64;
        track(&mut g, 1_050_000, 1_050_000 + worm_us - 10_000, &mut pos);
        assert_eq!(g.feed_forward_now(), 0.5);
        let mut kinds = [0u32; 3];
        while let Some(f) = g.take_frame() {
            match f.kind {
                FrameKind::Measured => kinds[0] += 1,
                FrameKind::Unmeasured => kinds[1] += 1,
                FrameKind::Dither { .. } => kinds[2] += 1,
            }
        }
        // One pulse frame and fills every cadence; only the first
        // silence_frames fills are measured (the queue keeps the last 4).
        let c = g.counters();
        assert_eq!(c.silences, 1);
        assert!(c.filled_frames > cfg.silence_frames);
        assert_eq!(c.unmeasured_frames, c.filled_frames - cfg.silence_frames);
        assert!(g.silent());
        // Then faded out within FADE_FRAMES cadences.
        let fade_us = (FADE_FRAMES as f64 * cfg.guide_cadence_s as f64 * 1e6) as u64;
        let r = track(
            &mut g,
            1_050_000 + worm_us - 10_000,
            1_050_000 + worm_us + fade_us + 20_000,
            &mut pos,
        );
        assert_eq!(g.feed_forward_now(), 0.0);
        assert_eq!(g.counters().feed_forward_faded, 1);
        assert!((r.ra_steps_per_s - m.sidereal_ra_steps_per_s()).abs() < 1e-3);
        // A pulse brings it back and ends the silence.
        let t = 1_050_000 + worm_us + fade_us + 20_000;
        g.on_event(start(Direction::Plus, t));
        assert!(!g.silent());
        assert_eq!(g.feed_forward_now(), 0.5);
        assert_eq!(kinds[2], 0);
    }

    #[test]
    fn a_long_pulse_is_a_dither() {
        let m = mount();
        let mut g = Guiding::new(&m);
        let mut pos = 0.0;
        track(&mut g, 0, 1_000_000, &mut pos);
        g.on_event(start(Direction::Minus, 1_000_000));
        track(&mut g, 1_000_000, 5_000_000, &mut pos);
        g.on_event(end(5_000_000));
        let f = g.take_frame().unwrap();
        let amount = -4.0 * m.guide_rate_arcsec_per_s();
        assert_eq!(
            f.kind,
            FrameKind::Dither {
                amount_arcsec: amount
            }
        );
        assert_eq!(g.counters().dithers, 1);
        // The dither's move is not gear error: C is back near 0.
        track(&mut g, 5_000_000, 6_000_000, &mut pos);
        assert!(g.applied_arcsec().abs() < 2.0 * m.arcsec_per_ra_step() as f64);
    }

    #[test]
    fn learner_gives_a_finite_feed_forward() {
        let m = mount();
        let mut l: std::boxed::Box<Learner<1>> = std::boxed::Box::new(Learner::new(&m));
        for k in 0..50 {
            let t = 2.0 * k as f64;
            let ff = l.learn(Frame {
                gear_time_s: t,
                interval_s: if k == 0 { 0.0 } else { 2.0 },
                kind: FrameKind::Measured,
                gear_error_arcsec: (t * 0.01).sin() as f32,
                applied_arcsec: 0.0,
                pulse_arcsec: 0.0,
                filled: false,
            });
            assert!(ff.rate_arcsec_per_s.is_finite());
            assert!(ff.until_gear_s > t);
        }
        l.learn(Frame {
            gear_time_s: 100.0,
            interval_s: 2.0,
            kind: FrameKind::Dither { amount_arcsec: 5.0 },
            gear_error_arcsec: 0.0,
            applied_arcsec: 0.0,
            pulse_arcsec: 5.0,
            filled: false,
        });
        let c = l.counters();
        assert_eq!((c.frames, c.learned, c.dithers), (51, 50, 1));
    }
}
