//! A mount that records what the port asked of it and answers with fixed
//! values, and a sink that keeps the replies.

use crate::mount::config::MountConfig;
use crate::port::coords::{Dec, Equatorial, Ra};
use crate::port::interpreter::Interpreter;
use crate::port::mount_port::{
    Axis, Counter, CounterGroup, GuidePulse, Identity, Learning, Line, ManualRate, ModelOrigin,
    MountPort, PecState, Stage, Status, StepCounts,
};
use crate::port::reply::ReplySink;
use crate::safety::reset_cause::ResetCause;
use std::vec::Vec;

/// What the port asked the mount to do.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Call {
    Sync(Equatorial),
    Guide(GuidePulse),
    MoveAt(Line, ManualRate),
    Stop(Axis),
    Tracking(bool),
    FeedForward(bool),
    ResetModel,
    SaveConfig,
    Park,
    Unpark,
    SaveModel,
}

pub struct DoubleMount {
    pub position: Equatorial,
    pub status: Status,
    pub calls: Vec<Call>,
    pub config: MountConfig,
    /// Whether saves can be asked (a store).
    pub store: bool,
}

pub const STAGES: [Stage; 2] = [
    Stage {
        period_ms: 600_000,
        amplitude_mas: 4_250,
        gate_permille: 1_000,
    },
    Stage {
        period_ms: 86_400,
        amplitude_mas: 730,
        gate_permille: 412,
    },
];

impl DoubleMount {
    pub fn new() -> Self {
        DoubleMount {
            position: Equatorial {
                ra: Ra::from_seconds(6 * 3600 + 30 * 60 + 45).unwrap(),
                dec: Dec::from_arcsec(-(5 * 3600 + 7 * 60 + 9)).unwrap(),
            },
            status: Status {
                tracking: true,
                parked: false,
                guiding: false,
                pec: PecState::Playing,
            },
            calls: Vec::new(),
            config: MountConfig::default(),
            store: true,
        }
    }
}

impl MountPort for DoubleMount {
    fn position(&mut self) -> Equatorial {
        self.position
    }
    fn sync(&mut self, to: Equatorial) {
        self.position = to;
        self.calls.push(Call::Sync(to));
    }
    fn guide(&mut self, pulse: GuidePulse) {
        self.calls.push(Call::Guide(pulse));
    }
    fn move_at(&mut self, line: Line, rate: ManualRate) {
        self.calls.push(Call::MoveAt(line, rate));
    }
    fn stop(&mut self, axis: Axis) {
        self.calls.push(Call::Stop(axis));
    }
    fn set_tracking(&mut self, on: bool) {
        self.status.tracking = on;
        self.calls.push(Call::Tracking(on));
    }
    fn status(&mut self) -> Status {
        self.status
    }
    fn identity(&self) -> Identity {
        Identity {
            product: "mkgp-mount",
            version: "0.1.0",
            date: "Nov 23 2026",
            time: "04:30:00",
        }
    }
    fn learning(&mut self) -> Learning {
        Learning {
            learned_permille: 423,
            feed_forward_mas_per_s: -1_250,
            feed_forward_on: true,
            origin: ModelOrigin::Relearn,
        }
    }
    fn stage(&mut self, index: usize) -> Option<Stage> {
        STAGES.get(index).copied()
    }
    fn counter(&mut self, group: CounterGroup, index: usize) -> Option<Counter> {
        // ST4: three counters; Faults: forty, more than one reply holds.
        let (name, count) = match group {
            CounterGroup::St4 => ("glitches", 3),
            CounterGroup::Guiding => ("pulses", 1),
            CounterGroup::Learner => ("frames", 1),
            CounterGroup::Faults => ("fault_counter_with_a_long_name", 40),
        };
        (index < count).then_some(Counter {
            name,
            value: 4_000_000_000 + index as u32,
        })
    }
    fn step_counts(&mut self) -> StepCounts {
        StepCounts {
            ra: 123_456_789,
            dec: -42,
        }
    }
    fn set_feed_forward(&mut self, on: bool) {
        self.calls.push(Call::FeedForward(on));
    }
    fn reset_model(&mut self) {
        self.calls.push(Call::ResetModel);
    }
    fn reset_cause(&mut self) -> ResetCause {
        ResetCause::Pin
    }
    fn pending_config(&mut self) -> MountConfig {
        self.config
    }
    fn set_pending_config(&mut self, config: MountConfig) {
        self.config = config;
    }
    fn save_config(&mut self) -> bool {
        self.calls.push(Call::SaveConfig);
        self.store
    }
    fn park(&mut self) {
        self.calls.push(Call::Park);
        self.status.parked = true;
    }
    fn unpark(&mut self) {
        self.calls.push(Call::Unpark);
        self.status.parked = false;
    }
    fn save_model(&mut self) -> bool {
        self.calls.push(Call::SaveModel);
        self.store
    }
}

/// The replies, each a whole.
#[derive(Default)]
pub struct Replies(pub Vec<Vec<u8>>);

impl ReplySink for Replies {
    fn send(&mut self, reply: &[u8]) -> bool {
        self.0.push(reply.to_vec());
        true
    }
}

/// An interpreter with a double, fed as one client would.
pub struct Bench {
    pub port: Interpreter,
    pub mount: DoubleMount,
    pub now_us: u64,
}

impl Bench {
    pub fn new() -> Self {
        Bench {
            port: Interpreter::new(),
            mount: DoubleMount::new(),
            now_us: 0,
        }
    }

    /// Feeds `bytes` at the bench's time; the replies, concatenated.
    pub fn feed(&mut self, bytes: &[u8]) -> Vec<u8> {
        let mut replies = Replies::default();
        self.port
            .feed(bytes, self.now_us, &mut self.mount, &mut replies);
        replies.0.concat()
    }

    /// The reply to `bytes` as text.
    pub fn ask(&mut self, bytes: &str) -> std::string::String {
        std::string::String::from_utf8(self.feed(bytes.as_bytes())).unwrap()
    }

    /// The store's outcome of the save waiting; the reply it sends.
    pub fn stored(&mut self, saved: bool) -> std::string::String {
        let mut replies = Replies::default();
        self.port.store_done(saved, &mut replies);
        std::string::String::from_utf8(replies.0.concat()).unwrap()
    }
}
