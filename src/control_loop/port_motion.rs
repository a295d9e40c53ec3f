//! What the command port makes the axes do: guide pulses that take the ST4
//! pulse's path (the same [`St4Event`]s into [`Guiding`], so the same
//! frames and learning follow), manual motion at the slew rates (not
//! learned from), tracking on and off.
//!
//! **One owner per axis.** An ST4 pulse and a port pulse or manual motion
//! on the same axis at the same time: the first keeps the axis, the other
//! is refused and counted ([`PortMotionCounters::port_refused`],
//! [`PortMotionCounters::st4_refused`]). A refused ST4 pulse is ignored up
//! to its end; a refused port command does nothing. Both sources are
//! guiders that want the axis for themselves: mixing them would make a
//! frame of two guiders' pulses, and neither could tell what it moved.

use crate::mount::config::Mount;
use crate::mount::guiding::{Guiding, Motion};
use crate::mount::st4::{Axis, Direction, Line, St4Event};
use crate::port::mount_port::{GuidePulse, ManualRate};

crate::counters! {
    /// What the port's motion did and what was refused, since start-up.
    pub struct PortMotionCounters {
        /// Port guide pulses started.
        port_pulses,
        /// Manual motions started.
        manual_moves,
        /// Port pulses and manual motions refused: an ST4 pulse held the axis.
        port_refused,
        /// ST4 pulses refused: the port held the axis.
        st4_refused,
    }
}

/// What the port runs on one axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum PortAxis {
    Idle,
    /// A guide pulse, ending at `end_us` unless stopped first.
    Pulse {
        direction: Direction,
        end_us: u64,
    },
    /// Manual motion until a stop.
    Manual {
        direction: Direction,
        rate: ManualRate,
    },
}

/// Per axis: the port's motion and the ST4 pulse's state.
#[derive(Clone, Copy, Debug)]
struct AxisOwner {
    port: PortAxis,
    /// An accepted ST4 pulse runs.
    st4: bool,
    /// A refused ST4 pulse runs (its end is dropped too).
    st4_refused: bool,
}

impl AxisOwner {
    const IDLE: AxisOwner = AxisOwner {
        port: PortAxis::Idle,
        st4: false,
        st4_refused: false,
    };
}

/// The port's side of the loop: both axes' owners, the manual rates.
pub(super) struct PortMotion {
    axes: [AxisOwner; 2],
    tracking: bool,
    /// The axes' highest rates, steps/s (manual rates are fractions).
    max_ra_sps: f32,
    max_dec_sps: f32,
    counters: PortMotionCounters,
}

fn index(axis: Axis) -> usize {
    match axis {
        Axis::Ra => 0,
        Axis::Dec => 1,
    }
}

const AXES: [Axis; 2] = [Axis::Ra, Axis::Dec];

/// A manual rate as a fraction of the axis's highest rate
/// (`max_rate_sidereal`): a quarter, a half, all of it. Never beyond the
/// maximum, whatever the configuration.
fn fraction(rate: ManualRate) -> f32 {
    match rate {
        ManualRate::Centering => 0.25,
        ManualRate::Find => 0.5,
        ManualRate::Max => 1.0,
    }
}

impl PortMotion {
    pub fn new(mount: &Mount) -> Self {
        PortMotion {
            axes: [AxisOwner::IDLE; 2],
            tracking: true,
            max_ra_sps: mount.max_ra_steps_per_s(),
            max_dec_sps: mount.max_dec_steps_per_s(),
            counters: PortMotionCounters::default(),
        }
    }

    pub fn counters(&self) -> PortMotionCounters {
        self.counters
    }

    pub fn tracking(&self) -> bool {
        self.tracking
    }

    /// The earliest end of a port pulse, µs.
    pub fn next_deadline_us(&self) -> Option<u64> {
        self.axes
            .iter()
            .filter_map(|a| match a.port {
                PortAxis::Pulse { end_us, .. } => Some(end_us),
                _ => None,
            })
            .min()
    }

    /// Ends the port pulses due at or before `at_us`, oldest first.
    pub fn expire(&mut self, at_us: u64, on_event: &mut impl FnMut(St4Event)) {
        while let Some(end_us) = self.next_deadline_us().filter(|&e| e <= at_us) {
            for axis in AXES {
                let a = &mut self.axes[index(axis)];
                if matches!(a.port, PortAxis::Pulse { end_us: e, .. } if e == end_us) {
                    a.port = PortAxis::Idle;
                    on_event(St4Event::PulseEnd {
                        axis,
                        at_us: end_us,
                    });
                }
            }
        }
    }

    /// An ST4 event: passed on, or refused while the port holds its axis.
    /// Port pulses due before it end first.
    pub fn st4_event(&mut self, ev: St4Event, on_event: &mut impl FnMut(St4Event)) {
        let (axis, at_us, start) = match ev {
            St4Event::PulseStart { axis, at_us, .. } => (axis, at_us, true),
            St4Event::PulseEnd { axis, at_us } => (axis, at_us, false),
        };
        self.expire(at_us, on_event);
        let a = &mut self.axes[index(axis)];
        if start {
            if a.port != PortAxis::Idle {
                a.st4_refused = true;
                self.counters.st4_refused = self.counters.st4_refused.saturating_add(1);
                return;
            }
            a.st4 = true;
        } else if a.st4_refused {
            a.st4_refused = false;
            return;
        } else {
            a.st4 = false;
        }
        on_event(ev);
    }

    /// Ends whatever the port runs on `axis` at `at_us`.
    fn end(&mut self, axis: Axis, at_us: u64, on_event: &mut impl FnMut(St4Event)) {
        let a = &mut self.axes[index(axis)];
        if let PortAxis::Pulse { .. } = a.port {
            on_event(St4Event::PulseEnd { axis, at_us });
        }
        a.port = PortAxis::Idle;
    }

    /// A port guide pulse from `at_us`: `false` if refused (an ST4 pulse
    /// holds the axis). A pulse of 0 ms only stops the axis.
    pub fn guide(
        &mut self,
        pulse: GuidePulse,
        at_us: u64,
        on_event: &mut impl FnMut(St4Event),
    ) -> bool {
        let axis = pulse.line().axis();
        if self.axes[index(axis)].st4 {
            self.counters.port_refused = self.counters.port_refused.saturating_add(1);
            return false;
        }
        self.expire(at_us, on_event);
        self.end(axis, at_us, on_event);
        if pulse.duration_ms() == 0 {
            return true;
        }
        let direction = pulse.line().direction();
        self.axes[index(axis)].port = PortAxis::Pulse {
            direction,
            end_us: at_us.saturating_add(u64::from(pulse.duration_ms()) * 1000),
        };
        self.counters.port_pulses = self.counters.port_pulses.saturating_add(1);
        on_event(St4Event::PulseStart {
            axis,
            direction,
            at_us,
        });
        true
    }

    /// Manual motion from `at_us`: `false` if refused.
    pub fn move_at(
        &mut self,
        line: Line,
        rate: ManualRate,
        at_us: u64,
        on_event: &mut impl FnMut(St4Event),
    ) -> bool {
        let axis = line.axis();
        if self.axes[index(axis)].st4 {
            self.counters.port_refused = self.counters.port_refused.saturating_add(1);
            return false;
        }
        self.expire(at_us, on_event);
        self.end(axis, at_us, on_event);
        self.axes[index(axis)].port = PortAxis::Manual {
            direction: line.direction(),
            rate,
        };
        self.counters.manual_moves = self.counters.manual_moves.saturating_add(1);
        true
    }

    /// Stops the port's pulse or manual motion on `axis` (an ST4 pulse is
    /// the camera's, not the port's to stop).
    pub fn stop(&mut self, axis: Axis, at_us: u64, on_event: &mut impl FnMut(St4Event)) {
        self.expire(at_us, on_event);
        self.end(axis, at_us, on_event);
    }

    pub fn set_tracking(&mut self, on: bool) {
        self.tracking = on;
    }

    /// The motion for [`Guiding`]: tracking and the manual rates.
    pub fn motion(&self) -> Motion {
        let manual = |axis: Axis, max: f32| match self.axes[index(axis)].port {
            PortAxis::Manual { direction, rate } => direction.sign() * fraction(rate) * max,
            _ => 0.0,
        };
        Motion {
            tracking: self.tracking,
            manual_ra_sps: manual(Axis::Ra, self.max_ra_sps),
            manual_dec_sps: manual(Axis::Dec, self.max_dec_sps),
        }
    }

    /// Installs the motion in `guiding`.
    pub fn apply(&self, guiding: &mut Guiding) {
        guiding.set_motion(self.motion());
    }
}
