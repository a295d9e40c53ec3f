//! The firmware's loop as a sans-IO step: what the board's guiding task and
//! step tick decide, without the hardware. The board (`src/main.rs`) and the
//! simulator (`host-tests`' `guide-sim st4`) drive the same code.
//!
//! - [`ControlLoop::wake`]: raw ST4 edges, the time, the RA step count, the
//!   edge queue's loss counter and the newest feed-forward in; the step
//!   rates to set, the events to log and the counters out. Completed guide
//!   frames wait in the loop until the caller has room for them
//!   ([`ControlLoop::take_frame`]): a learner that falls behind loses the
//!   oldest frames, counted, and never blocks the loop.
//! - [`ControlLoop::next_wake_us`]: when to wake next if no edge comes (an
//!   ST4 deadline, or the periodic rate update).
//! - [`stepping::AxisStepper`]: the step tick of one axis.
//! - [`storm::StormGuard`]: each ST4 line's edge budget, which the board's
//!   interrupt asks before it queues an edge.
//! - [`learning::LearningPolicy`]: the learning task's policy (the model's
//!   reset, its periodic saves, its restore at the worm index's first pass,
//!   the ports' requests to the store), which the board's learning task and
//!   the simulator's carry out.
//!
//! The learner (the model) runs elsewhere, at lower priority: it takes the
//! frames and returns a [`FeedForward`], which the next wake-up installs.

pub mod learning;
pub mod port_motion;
pub mod port_mount;
pub mod st4_feed;
pub mod stepping;
pub mod storm;

use heapless::Vec;

use crate::model::additions::Additions;
use crate::mount::config::Mount;
use crate::mount::frame::{FeedForward, Frame, Rates};
use crate::mount::guiding::{Guiding, GuidingCounters};
use crate::mount::st4::{Axis, Line, St4Counters, St4Event};
use crate::port::mount_port::{GuidePulse, ManualRate};
use port_motion::{PortMotion, PortMotionCounters};
use st4_feed::{EdgeSource, St4Feed};

/// The rates are recomputed and set at least this often (µs): the
/// feed-forward and the applied correction change continuously.
pub const RATE_UPDATE_US: u64 = 10_000;
/// Events one wake-up reports for logging (the rest are counted).
pub const LOG_EVENTS: usize = 4;

/// A completed guide frame for the learner, with the guiding's counters at
/// the time it was taken (logged with it; the ST4 counters are logged as
/// they change, `Wake::st4_counters`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameRecord {
    pub frame: Frame,
    pub guiding: GuidingCounters,
}

/// What one wake-up decided.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Wake {
    /// Set these rates now (on an event, a new feed-forward, or the periodic
    /// update).
    pub rates: Option<Rates>,
    /// The first [`LOG_EVENTS`] ST4 events, to log after the rates are set.
    pub events: Vec<St4Event, LOG_EVENTS>,
    /// Events beyond those.
    pub more_events: usize,
    /// Edges newly lost to a full queue (the levels were resynchronised).
    pub lost_edges: u32,
    /// The ST4 counters, when they changed or an event came.
    pub st4_counters: Option<St4Counters>,
}

/// The guiding side of the firmware: ST4 in, rates and frames out.
pub struct ControlLoop {
    feed: St4Feed,
    guiding: Guiding,
    next_update_us: u64,
    last_counters: St4Counters,
    port: PortMotion,
    /// A port command changed the motion: the next wake-up sets rates.
    rates_due: bool,
    /// The learner's feed-forwards are installed (`:~F1#`).
    feed_forward_on: bool,
    /// Edges lost to a full queue, since start-up.
    lost_edges: u32,
}

impl ControlLoop {
    /// The loop for `mount`, at time `now_us` with the RA axis at
    /// `ra_steps`; returns it and the rates to start with (tracking).
    pub fn start(mount: &Mount, now_us: u64, ra_steps: i64) -> (Self, Rates) {
        Self::start_with(mount, Additions::ALL, now_us, ra_steps)
    }

    /// [`start`](Self::start) with some of the fast part's `additions`
    /// switched off (a simulator's).
    pub fn start_with(
        mount: &Mount,
        additions: Additions,
        now_us: u64,
        ra_steps: i64,
    ) -> (Self, Rates) {
        let c = mount.config();
        let mut guiding = Guiding::with_additions(mount, additions);
        let rates = guiding.rates(now_us, ra_steps);
        let lp = ControlLoop {
            feed: St4Feed::new(c.glitch_us, c.pulse_cap_us),
            guiding,
            next_update_us: now_us.saturating_add(RATE_UPDATE_US),
            last_counters: St4Counters::default(),
            port: PortMotion::new(mount),
            rates_due: false,
            feed_forward_on: true,
            lost_edges: 0,
        };
        (lp, rates)
    }

    /// When to wake if no edge arrives first, µs.
    /// Now (0) after a port command changed the motion.
    pub fn next_wake_us(&self) -> u64 {
        if self.rates_due {
            return 0;
        }
        [
            self.feed.st4().next_deadline_us(),
            self.port.next_deadline_us(),
            self.guiding.next_change_us(),
        ]
        .into_iter()
        .flatten()
        .fold(self.next_update_us, u64::min)
    }

    /// One wake-up at `now_us` (every edge stamped before it is in
    /// `edges`), with the RA axis at `ra_steps` and the learner's newest
    /// feed-forward, if one came since the last wake-up.
    pub fn wake(
        &mut self,
        now_us: u64,
        ra_steps: i64,
        edges: &mut impl EdgeSource,
        feed_forward: Option<FeedForward>,
    ) -> Wake {
        let mut wake = Wake::default();
        let guiding = &mut self.guiding;
        let mut n_events = 0usize;
        let port = &mut self.port;
        let mut on_event = |ev: St4Event| {
            // ST4 events pass the port's ownership check; the port's own
            // (its pulses' ends) come out of it the same way.
            port.st4_event(ev, &mut |ev| {
                guiding.on_event(ev);
                if wake.events.push(ev).is_err() {
                    wake.more_events += 1;
                }
                n_events += 1;
            });
        };
        while let Some(edge) = edges.next_edge() {
            self.feed.edge(edge, &mut on_event);
        }
        let lost = self.feed.resync(edges.queue(), now_us, &mut on_event);
        self.feed.poll(now_us, &mut on_event);
        let now_us = now_us.max(self.feed.last_us());
        self.port.expire(now_us, &mut |ev| {
            self.guiding.on_event(ev);
            if wake.events.push(ev).is_err() {
                wake.more_events += 1;
            }
            n_events += 1;
        });
        wake.lost_edges = lost;
        self.lost_edges = self.lost_edges.wrapping_add(lost);
        if let Some(ff) = feed_forward.filter(|_| self.feed_forward_on) {
            self.guiding.set_feed_forward(ff);
        }

        // A pulse carried out in part changes its rate (`guiding`'s share).
        let share_due = self.guiding.next_change_us().is_some_and(|t| t <= now_us);
        let changed = n_events > 0 || core::mem::take(&mut self.rates_due) || share_due;
        self.port.apply(&mut self.guiding);
        if changed || feed_forward.is_some() || now_us >= self.next_update_us {
            wake.rates = Some(self.guiding.rates(now_us, ra_steps));
        }
        let counters = self.feed.st4().counters();
        if changed || counters != self.last_counters {
            self.last_counters = counters;
            wake.st4_counters = Some(counters);
        }
        if now_us >= self.next_update_us {
            self.next_update_us += RATE_UPDATE_US;
            if self.next_update_us <= now_us {
                self.next_update_us = now_us + RATE_UPDATE_US;
            }
        }
        wake
    }

    /// The oldest completed frame, for a caller with room for it.
    pub fn take_frame(&mut self) -> Option<FrameRecord> {
        let frame = self.guiding.take_frame()?;
        Some(FrameRecord {
            frame,
            guiding: self.guiding.counters(),
        })
    }

    pub fn guiding(&self) -> &Guiding {
        &self.guiding
    }

    pub fn st4_counters(&self) -> St4Counters {
        self.feed.st4().counters()
    }

    /// Edges lost to a full queue since start-up.
    pub fn lost_edges(&self) -> u32 {
        self.lost_edges
    }

    // The command port's motion (`port_motion`): each takes effect at
    // `now_us` (never before the loop's latest time) and makes the next
    // wake-up ([`ControlLoop::next_wake_us`] returns 0) set the rates.

    /// The port's time: never before what the loop has decided.
    fn port_time(&self, now_us: u64) -> u64 {
        now_us.max(self.feed.last_us())
    }

    /// A port guide pulse: the same pulse events as an ST4 pulse. `false`
    /// if an ST4 pulse holds the axis (counted).
    pub fn port_guide(&mut self, pulse: GuidePulse, now_us: u64) -> bool {
        let at = self.port_time(now_us);
        let guiding = &mut self.guiding;
        let ok = self.port.guide(pulse, at, &mut |ev| guiding.on_event(ev));
        self.rates_due = true;
        ok
    }

    /// Manual motion on a line's axis and direction, until a stop; not
    /// learned from. `false` if an ST4 pulse holds the axis (counted).
    pub fn port_move(&mut self, line: Line, rate: ManualRate, now_us: u64) -> bool {
        let at = self.port_time(now_us);
        let guiding = &mut self.guiding;
        let ok = self
            .port
            .move_at(line, rate, at, &mut |ev| guiding.on_event(ev));
        self.rates_due = true;
        ok
    }

    /// Stops the port's pulse or manual motion on `axis`.
    pub fn port_stop(&mut self, axis: Axis, now_us: u64) {
        let at = self.port_time(now_us);
        let guiding = &mut self.guiding;
        self.port.stop(axis, at, &mut |ev| guiding.on_event(ev));
        self.rates_due = true;
    }

    /// Tracking on or off (off: RA stops, the sky drifts by; not learned).
    pub fn set_tracking(&mut self, on: bool) {
        self.port.set_tracking(on);
        self.rates_due = true;
    }

    pub fn tracking(&self) -> bool {
        self.port.tracking()
    }

    /// Switches the learner's feed-forward on or off; off removes the one
    /// in effect and refuses the next ones.
    pub fn set_feed_forward_on(&mut self, on: bool) {
        self.feed_forward_on = on;
        if !on {
            self.guiding.set_feed_forward(FeedForward::NONE);
        }
        self.rates_due = true;
    }

    pub fn feed_forward_on(&self) -> bool {
        self.feed_forward_on
    }

    pub fn port_counters(&self) -> PortMotionCounters {
        self.port.counters()
    }
}

#[cfg(test)]
mod tests;

#[cfg(test)]
mod port_tests;
