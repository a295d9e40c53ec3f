//! What the command port asks of the mount: the one trait the firmware and
//! the simulator implement, and the bounded values that cross it. Every
//! value that can move a motor is a type that cannot hold an unsafe one: a
//! guide pulse is at most [`GuidePulse::MAX_MS`], a manual rate is one of
//! three.

use super::coords::Equatorial;
use crate::mount::config::MountConfig;
pub use crate::mount::st4::{Axis, Line};
use crate::safety::reset_cause::ResetCause;

/// A guide pulse asked for on the port: the same as an ST4 line held for
/// the duration, so it takes the ST4 pulse's path through the guiding and
/// the learner. A pulse ends at its duration or at a stop on its axis,
/// whichever comes first.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GuidePulse {
    line: Line,
    duration_ms: u16,
}

impl GuidePulse {
    /// The longest pulse (`:Mg...#` takes up to 60000 ms); also the limit
    /// of a guide-rate `:Mn#` that no `:Qn#` follows.
    pub const MAX_MS: u16 = 60_000;

    /// `None` beyond [`GuidePulse::MAX_MS`].
    pub fn new(line: Line, duration_ms: u32) -> Option<Self> {
        let duration_ms = u16::try_from(duration_ms).ok()?;
        (duration_ms <= Self::MAX_MS).then_some(GuidePulse { line, duration_ms })
    }

    /// The longest pulse on a line.
    pub fn longest(line: Line) -> Self {
        GuidePulse {
            line,
            duration_ms: Self::MAX_MS,
        }
    }

    pub fn line(self) -> Line {
        self.line
    }

    pub fn duration_ms(self) -> u16 {
        self.duration_ms
    }
}

/// The manual rates above the guide rate (`:RC# :RM# :RS#`). What each is in
/// arcseconds per second is the mount's configuration, bounded by its
/// maximum step rate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ManualRate {
    Centering,
    Find,
    Max,
}

/// OnStep's periodic-error-correction states, as the model's feed-forward
/// maps onto them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PecState {
    /// Feed-forward off (OnStep's "ignore", `/`).
    Off,
    /// On, but the model has not learned enough to apply it (OnStep's
    /// "recording", `^`).
    Learning,
    /// On and applied (OnStep's "playing", `~`).
    Playing,
}

/// The state `:GU#` reports.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Status {
    pub tracking: bool,
    pub parked: bool,
    /// A guide pulse (ST4 or port) is running on either axis.
    pub guiding: bool,
    pub pec: PecState,
}

/// The firmware's name and build, for `:GVP# :GVN# :GVD# :GVT#`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Identity {
    pub product: &'static str,
    pub version: &'static str,
    /// Build date, `Mmm DD YYYY` as the LX200 handbox writes it.
    pub date: &'static str,
    /// Build time, `HH:MM:SS`.
    pub time: &'static str,
}

/// The model's learning and its feed-forward now, in fixed point.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Learning {
    /// Learning progress, 0..=1000 (per mille).
    pub learned_permille: u16,
    /// The feed-forward rate now, milliarcseconds per second.
    pub feed_forward_mas_per_s: i32,
    /// Whether the feed-forward is switched on.
    pub feed_forward_on: bool,
    /// Where the model came from at start-up.
    pub origin: ModelOrigin,
}

/// Where the model came from at start-up, and how its gear phase was
/// found after the power cycle.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ModelOrigin {
    /// Nothing restored: learning from the prior.
    #[default]
    Cold,
    /// Restored; the phase unknown (no park, no index), found again from
    /// the first half worm period of data.
    Relearn,
    /// Restored from a park: the step counters, hence the phase, carried
    /// over.
    Park,
    /// Restored at the worm-index sensor's first pass: the worm's phase
    /// from the sensor, the other stages' found again.
    Index,
}

impl ModelOrigin {
    /// The name `:~L#` gives it.
    pub fn name(self) -> &'static str {
        match self {
            ModelOrigin::Cold => "cold",
            ModelOrigin::Relearn => "relearn",
            ModelOrigin::Park => "park",
            ModelOrigin::Index => "index",
        }
    }
}

/// One stage of the model (a gear), in fixed point.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Stage {
    pub period_ms: u32,
    /// Amplitude of the stage's error, milliarcseconds.
    pub amplitude_mas: u32,
    /// How much of the stage's prediction is let through, 0..=1000.
    pub gate_permille: u16,
}

/// The groups of counters the mount keeps (the port's own are the
/// interpreter's, [`super::PortCounters`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CounterGroup {
    St4,
    Guiding,
    Learner,
    Faults,
}

/// One named counter.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Counter {
    /// Lower case, digits and `_` only: the name is a key in a reply.
    pub name: &'static str,
    pub value: u32,
}

/// The axes' step counters.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StepCounts {
    pub ra: i64,
    pub dec: i64,
}

/// The mount as the command port sees it.
pub trait MountPort {
    /// Where the mount points now: the last sync moved by the step counters
    /// since (tracking holds RA constant).
    fn position(&mut self) -> Equatorial;
    /// From now on the mount points at `to` (`:CM#`).
    fn sync(&mut self, to: Equatorial);
    /// Starts a guide pulse, replacing any pulse or manual motion on its
    /// axis. What happens when an ST4 pulse runs on the same axis is the
    /// mount's to define and count.
    fn guide(&mut self, pulse: GuidePulse);
    /// Starts manual motion on a line's axis and direction, until a stop.
    fn move_at(&mut self, line: Line, rate: ManualRate);
    /// Stops the guide pulse or manual motion on an axis (tracking goes on).
    fn stop(&mut self, axis: Axis);
    fn set_tracking(&mut self, on: bool);
    fn status(&mut self) -> Status;
    fn identity(&self) -> Identity;

    // Our own namespace (`:~...#`, docs/port.md).
    fn learning(&mut self) -> Learning;
    /// Stage `index` of the model, `None` past the last.
    fn stage(&mut self, index: usize) -> Option<Stage>;
    /// Counter `index` of a group, `None` past the last.
    fn counter(&mut self, group: CounterGroup, index: usize) -> Option<Counter>;
    fn step_counts(&mut self) -> StepCounts;
    fn set_feed_forward(&mut self, on: bool);
    /// Forgets everything the model learned.
    fn reset_model(&mut self);
    fn reset_cause(&mut self) -> ResetCause;
    /// The configuration a save stores and the next start uses (at start,
    /// the one running).
    fn pending_config(&mut self) -> MountConfig;
    /// Replaces it (the port has validated it).
    fn set_pending_config(&mut self, config: MountConfig);
    /// Asks for the pending configuration to be saved; `false` if no save
    /// can be asked now (no store, or too many under way). The outcome
    /// comes back through [`Interpreter::store_done`](super::Interpreter::store_done).
    fn save_config(&mut self) -> bool;
    /// Parks where the mount points: motion and tracking stop, the step
    /// counters and the model are saved, so that a mount not moved while
    /// powered off keeps its gear's phase.
    fn park(&mut self);
    /// Tracking again after a park.
    fn unpark(&mut self);
    /// Asks for the learned model to be saved now; `false` if it cannot be
    /// (no store). The outcome comes back as for
    /// [`save_config`](Self::save_config).
    fn save_model(&mut self) -> bool;
}
