//! From ST4 pulses and time to step rates and guide frames: what the mount
//! did, as observations of the gear error (docs/reference.md section 1).
//!
//! [`Guiding`] is the fast part of the controller: it runs in the
//! high-priority task (through `control_loop::ControlLoop`) on every ST4
//! event and every rate update, in constant time, never the model. It turns
//! the active pulses and the installed feed-forward into step rates, and
//! forms the guide [`Frame`]s for the slow part, the
//! [`Learner`](crate::mount::learner::Learner), which runs the model once
//! per frame at lower priority and returns the [`FeedForward`] that
//! `Guiding` applies until the next one.
//!
//! Its parts: `applied` (the applied correction C and the gear time),
//! `framer` (the frames and their queue), `feed_forward` (the
//! feed-forward in effect), and for the learner `earned_share` (the share of a
//! pulse carried out), `pulse_weight` (the part of a pulse learned) and
//! `bump` (a step of the star taken out of the observations).
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
//! sends no RA pulse for a guide cadence (`guide_cadence_s`, default 2 s;
//! the guider's own, measured from its pulses, where that is more than
//! half as long again: `framer`), a frame is filled at `previous frame +
//! cadence` (emitted after a grace of a quarter cadence, in case the pulse
//! is just late). Its observation:
//!
//! `gear error = mean of C over the interval since the previous frame
//!               + the frame's RA pulse correction / aggressiveness`
//!
//! The pulse correction is duration x guide rate (arcsec, signed); the
//! guider asked for that much of the error it measured, so the error was
//! about correction / aggressiveness (`guider_aggressiveness`, default 0.7;
//! a filled frame has correction 0: the guider saw less than its minimum
//! move). The learner weighs that pulse term down where the pulses show a
//! guider that overcorrects (`pulse_weight`). The mean of C over the
//! interval matches what the guider measured: the exposure averages the
//! star over about that interval, and the model stamps a frame at the
//! midpoint of the interval since the previous one.
//! The frame is emitted when its pulse ends (its duration is known only
//! then) and stamped with the gear time of the pulse start.
//!
//! # Feed-forward
//!
//! The model's `Guider::observe` returns the predicted change of the gear
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
//! # Dithers, calibrations and silence
//!
//! - An RA pulse longer than `dither_threshold_us` is a dither: its move is
//!   taken out of C, the frame is not learned, and the model is told with
//!   `Guider::dithered` so that it settles for `DITHER_FRAMES` frames
//!   without learning. The amount passed is 0: the model's dither offset
//!   shifts its time axis by amount / rate, which for a PC guider stands for
//!   the worm phase the dither moved; here gear time comes from the steps,
//!   which already include the dither's steps, so passing the amount would
//!   shift the phase twice.
//! - A calibration: equal pulses in a row, one way on one axis, as a guider
//!   calibrates (`calibration`). From the third to a hold after the last,
//!   the frames are `Calibration`: not learned, and the pulses are carried
//!   out in full (the guider measures their moves).
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

mod applied;
pub mod bump;
pub mod calibration;
pub mod earned_share;
mod feed_forward;
pub mod feed_forward_weight;
mod framer;
pub mod pulse_weight;
mod share;
#[cfg(test)]
mod tests;

use crate::model::additions::Additions;
use crate::model::numeric::clamp;
use crate::mount::config::{Mount, SIDEREAL_ARCSEC_PER_S};
use crate::mount::frame::{FeedForward, Frame, Rates};
use crate::mount::st4::{Axis, Direction, St4Event};
use applied::Applied;
use feed_forward::FeedForwardState;
use framer::Framer;
use share::SharedPulse;

/// Cadences over which the feed-forward is faded out after a silence.
pub const FADE_FRAMES: u32 = 5;
/// Frames the fast part keeps for the learner; when the learner falls this
/// far behind the oldest is dropped (counted in `frames_dropped`).
pub const FRAME_QUEUE: usize = 4;

crate::counters! {
    /// What the fast part saw and did, counted since construction.
    pub struct GuidingCounters {
        /// Pulse starts per axis.
        ra_pulses,
        dec_pulses,
        /// Frames made (all kinds), and of them: filled by the cadence, not
        /// measured (in silence, while the port moved the axis, during a
        /// calibration), dithers.
        frames,
        filled_frames,
        unmeasured_frames,
        dithers,
        /// Times learning froze because the guider fell silent, and because
        /// its RA pulses ran back to back (`framer`).
        silences,
        backlogs,
        /// Calibrations recognised from the guider's pulses (`calibration`).
        calibrations,
        /// Times the feed-forward was faded out completely after a silence.
        feed_forward_faded,
        /// Feed-forwards refused (non-finite) or limited to the guide rate.
        feed_forward_rejected,
        feed_forward_limited,
        /// Feed-forwards that ran out (no newer one by `until_gear_s`).
        feed_forward_expired,
        /// Frames dropped because the learner was [`FRAME_QUEUE`] behind.
        frames_dropped,
        /// `rates` calls whose RA or Dec rate had to be clamped into range.
        ra_clamped,
        dec_clamped,
        /// `rates` calls with a time earlier than the previous one (ignored).
        time_backwards,
        /// Pulse ends for an axis without a pulse (ignored).
        stray_ends,
        /// RA pulses carried out in part (`earned_share`), and of those that
        /// started so, the ones that turned out long and were made up in full.
        ra_pulses_held_back,
        ra_pulses_made_up,
    }
}

/// The motion the command port asks for besides guide pulses: tracking on
/// or off, and a manual rate per axis. None of it is gear correction: while
/// the port moves the RA axis or has stopped its tracking, C holds (the RA
/// rate's whole departure from sidereal is taken out as it is made, like a
/// dither's move) and the frames are unmeasured, so the model never learns
/// from it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Motion {
    pub tracking: bool,
    /// Manual RA rate added, steps/s, signed (west positive).
    pub manual_ra_sps: f32,
    /// Manual Dec rate, steps/s, signed (north positive); replaces the Dec
    /// pulse's rate while not 0.
    pub manual_dec_sps: f32,
}

impl Motion {
    /// Tracking, no manual motion: the mount as it starts.
    pub const TRACKING: Motion = Motion {
        tracking: true,
        manual_ra_sps: 0.0,
        manual_dec_sps: 0.0,
    };
}

/// The fast part: pulses and time to rates, and the guide frames.
pub struct Guiding {
    ra_guide_sps: f32,
    dec_guide_sps: f32,
    max_ra_sps: f32,
    max_dec_sps: f32,
    /// The active pulse per axis: direction and start.
    ra_pulse: Option<(Direction, u64)>,
    dec_pulse: Option<(Direction, u64)>,
    /// The active RA pulse's share, when it is not carried out in full, and
    /// an ended one still making up what it held back.
    ra_share: Option<SharedPulse>,
    ra_finishing: Option<SharedPulse>,
    /// Extra guide rate (multiple of it) that keeps the RA rate in range
    /// while a pulse makes up, RA+ and RA-.
    make_up: [f32; 2],
    guide_arcsec_per_s: f32,
    /// What the command port asked beyond guide pulses (none by default).
    motion: Motion,
    applied: Applied,
    frames: Framer,
    feed_forward: FeedForwardState,
    counters: GuidingCounters,
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
        Self::with_additions(mount, Additions::ALL)
    }

    /// [`new`](Self::new) with some of its `additions` switched off.
    pub fn with_additions(mount: &Mount, additions: Additions) -> Self {
        let c = mount.config();
        let sidereal_sps = mount.sidereal_ra_steps_per_s_f64();
        let guide_arcsec_per_s = mount.guide_rate_arcsec_per_s();
        let cadence_us = (c.guide_cadence_s as f64 * 1e6) as u64;
        let worm_period_us = (c.worm_period_s as f64 * 1e6) as u64;
        // Half the headroom each way, at most the guide rate again: the
        // feed-forward (at most the guide rate) rarely meets the clamp.
        let guide = mount.guide_ra_steps_per_s() as f64;
        let headroom = |room: f64| (0.5 * room / guide).clamp(0.0, 1.0) as f32;
        let make_up = [
            headroom(mount.max_ra_steps_per_s() as f64 - sidereal_sps - guide),
            headroom(sidereal_sps - guide),
        ];
        Guiding {
            ra_guide_sps: finite_or_zero(mount.guide_ra_steps_per_s()),
            dec_guide_sps: finite_or_zero(mount.guide_dec_steps_per_s()),
            max_ra_sps: finite_or_zero(mount.max_ra_steps_per_s()),
            max_dec_sps: finite_or_zero(mount.max_dec_steps_per_s()),
            ra_pulse: None,
            dec_pulse: None,
            ra_share: None,
            ra_finishing: None,
            make_up,
            guide_arcsec_per_s: finite_or_zero(guide_arcsec_per_s),
            motion: Motion::TRACKING,
            applied: Applied::new(sidereal_sps, SIDEREAL_ARCSEC_PER_S / sidereal_sps),
            frames: Framer::new(
                c.guider_aggressiveness,
                cadence_us,
                c.dither_threshold_us as u64,
                c.silence_frames,
                guide_arcsec_per_s,
                additions.calibration_watch,
            ),
            feed_forward: FeedForwardState::new(guide_arcsec_per_s, worm_period_us, cadence_us),
            counters: GuidingCounters::default(),
        }
    }

    pub fn counters(&self) -> GuidingCounters {
        self.counters
    }

    /// Gear time now (seconds), from the last `rates` call's step count.
    pub fn gear_time_s(&self) -> f64 {
        self.applied.gear_time_s()
    }

    /// The applied correction C at the last `rates` call, arcsec.
    pub fn applied_arcsec(&self) -> f64 {
        self.applied.c()
    }

    /// The feed-forward rate in effect at the last `rates` call, after the
    /// fade, arcsec/s.
    pub fn feed_forward_now(&self) -> f32 {
        self.feed_forward_at(self.applied.last_us())
    }

    /// The feed-forward rate at `now_us`, arcsec/s: none while the
    /// guider's pulses queue (it has lost its loop: add nothing to it).
    fn feed_forward_at(&self, now_us: u64) -> f32 {
        if self.frames.backlogged() {
            return 0.0;
        }
        self.feed_forward
            .rate(now_us, self.frames.last_activity_us())
    }

    /// The start of the pulse running on `axis`, µs.
    pub fn pulse_start_us(&self, axis: Axis) -> Option<u64> {
        match axis {
            Axis::Ra => self.ra_pulse,
            Axis::Dec => self.dec_pulse,
        }
        .map(|(_, start)| start)
    }

    /// Sets the port's motion, in effect from the next `rates` call.
    pub fn set_motion(&mut self, motion: Motion) {
        self.motion = motion;
    }

    pub fn motion(&self) -> Motion {
        self.motion
    }

    /// Learning is frozen: the guider has been silent for too long.
    pub fn silent(&self) -> bool {
        self.frames.silent()
    }

    fn heard(&mut self, at_us: u64) {
        self.frames.heard(at_us);
        self.feed_forward.heard();
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
                self.ra_share = self.share_for(direction, at_us);
                let mark = self.applied.mark_at(at_us);
                self.frames.open(mark, direction, &mut self.counters);
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
                let Some((direction, start_us)) = self.dec_pulse.take() else {
                    self.counters.stray_ends = self.counters.stray_ends.saturating_add(1);
                    return;
                };
                self.heard(at_us);
                self.frames.pulse_ended(
                    Axis::Dec,
                    direction,
                    at_us.saturating_sub(start_us),
                    at_us,
                    &mut self.counters,
                );
            }
        }
    }

    /// The share of an RA pulse starting at `at_us`: shared only while the
    /// learner's feed-forward is in full effect, the port adds no motion
    /// and the guider does not calibrate (it measures its pulses' moves).
    fn share_for(&self, direction: Direction, at_us: u64) -> Option<SharedPulse> {
        if self.motion != Motion::TRACKING
            || self.frames.backlogged()
            || self.frames.calibrating(at_us)
        {
            return None;
        }
        let share = self
            .feed_forward
            .share(at_us, self.frames.last_activity_us());
        let make_up = match direction {
            Direction::Plus => self.make_up[0],
            Direction::Minus => self.make_up[1],
        };
        SharedPulse::start(direction, at_us, share, self.guide_arcsec_per_s, make_up)
    }

    /// The next time a shared RA pulse changes its rate, µs.
    pub fn next_change_us(&self) -> Option<u64> {
        let now = self.applied.last_us();
        [self.ra_share, self.ra_finishing]
            .into_iter()
            .flatten()
            .filter_map(|s| s.next_change_us(now))
            .min()
    }

    /// The RA pulse ended at `at_us`: complete its frame.
    fn end_ra(&mut self, at_us: u64) {
        let Some((_, start_us)) = self.ra_pulse.take() else {
            return;
        };
        if let Some(mut share) = self.ra_share.take() {
            let goes_on = share.end(at_us);
            if share.held_back() {
                self.counters.ra_pulses_held_back =
                    self.counters.ra_pulses_held_back.saturating_add(1);
            } else {
                self.counters.ra_pulses_made_up = self.counters.ra_pulses_made_up.saturating_add(1);
            }
            if goes_on {
                self.ra_finishing = Some(share);
            }
        }
        self.frames
            .close(start_us, at_us, &mut self.applied, &mut self.counters);
    }

    /// The next completed frame for the learner, oldest first.
    pub fn take_frame(&mut self) -> Option<Frame> {
        self.frames.take()
    }

    /// Install the learner's newest feed-forward. A non-finite one is
    /// refused (no feed-forward until the next); the rate is limited to the
    /// guide rate.
    pub fn set_feed_forward(&mut self, ff: FeedForward) {
        self.feed_forward.install(ff, &mut self.counters);
    }

    /// The RA step count (signed, as emitted by the stepper) and the time:
    /// returns the rates to set now. Also makes the filled frames.
    pub fn rates(&mut self, now_us: u64, ra_steps: i64) -> Rates {
        let ra_pulse = self.ra_pulse.is_some();
        if !self.applied.started() {
            self.applied.start(now_us, ra_steps);
        } else if now_us < self.applied.last_us() {
            self.counters.time_backwards = self.counters.time_backwards.saturating_add(1);
            self.applied.take_steps(ra_steps);
        } else {
            self.frames.keep_fill_mark(&self.applied, now_us, ra_pulse);
            self.applied.advance(now_us, ra_steps);
        }
        self.frames
            .fill(now_us, ra_pulse, &self.applied, &mut self.counters);

        let heard = self.frames.last_activity_us();
        self.feed_forward.update(
            self.applied.gear_time_s(),
            now_us,
            heard,
            &mut self.counters,
        );
        let ff_sps = self.feed_forward_at(now_us) as f64 / self.applied.arcsec_per_step();

        let sidereal_sps = self.applied.sidereal_sps();
        if self.ra_finishing.is_some_and(|s| !s.running(now_us)) {
            self.ra_finishing = None;
        }
        let pulse = match (self.ra_pulse, self.ra_share) {
            (Some(_), Some(share)) => share.guide(now_us),
            (Some((d, _)), None) => d.sign(),
            (None, _) => 0.0,
        };
        let finishing = self.ra_finishing.map_or(0.0, |s| s.guide(now_us));
        let guide = (pulse + finishing) * self.ra_guide_sps;
        let ra = (sidereal_sps + guide as f64 + ff_sps) as f32;
        let clamp_ra = |ra: f32| {
            if ra.is_finite() {
                clamp(ra, 0.0, self.max_ra_sps)
            } else {
                clamp(sidereal_sps as f32, 0.0, self.max_ra_sps)
            }
        };
        let m = self.motion;
        let port_motion = !(m.tracking && m.manual_ra_sps == 0.0);
        let (ra, ra_clamped, excluded) = if !port_motion {
            (ra, clamp_ra(ra), 0.0)
        } else {
            // While the port moves the axis or has stopped its tracking,
            // none of its motion is gear correction, the guide pulses' and
            // the feed-forward's included (the clamp may take them away):
            // C holds, and the frames meanwhile are not learned.
            let tracking = if m.tracking { sidereal_sps } else { 0.0 };
            let with_port =
                (tracking + guide as f64 + ff_sps + finite_or_zero(m.manual_ra_sps) as f64) as f32;
            let set = clamp_ra(with_port);
            (with_port, set, set - sidereal_sps as f32)
        };
        if ra_clamped != ra {
            self.counters.ra_clamped = self.counters.ra_clamped.saturating_add(1);
        }
        let dec = if m.manual_dec_sps != 0.0 {
            m.manual_dec_sps
        } else {
            self.dec_pulse.map_or(0.0, |(d, _)| d.sign()) * self.dec_guide_sps
        };
        let dec_clamped = if dec.is_finite() {
            clamp(dec, -self.max_dec_sps, self.max_dec_sps)
        } else {
            0.0
        };
        if dec_clamped != dec {
            self.counters.dec_clamped = self.counters.dec_clamped.saturating_add(1);
        }
        self.applied.set_ra_rate(ra_clamped, excluded, port_motion);
        Rates {
            ra_steps_per_s: ra_clamped,
            dec_steps_per_s: dec_clamped,
        }
    }
}
