//! What the tasks hand each other: every static one task sends on and
//! another takes from, in one place, so that no task's module imports
//! another's (the guiding task, the learning task, the ports' and the
//! index input's, `super`).

use core::cell::{Cell, RefCell};
use core::sync::atomic::{AtomicU32, Ordering};

use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::channel::Channel;
use embassy_sync::signal::Signal;

use mkgp_mount::control_loop::port_mount::{LearnedFrame, StoreOutcome, StoreRequest};
use mkgp_mount::control_loop::storm::StormGuard;
use mkgp_mount::control_loop::FrameRecord;
use mkgp_mount::mount::guiding::FRAME_QUEUE;
use mkgp_mount::mount::st4::St4Counters;
use mkgp_mount::persist::StoreCounters;
use mkgp_mount::port::mount_port::ModelOrigin;

/// Command ports on every board: 0 to the PC (USB, or the Nucleo's
/// ST-LINK), 1 a plain UART.
pub const PORTS: usize = 2;

/// Bytes arrived on a port: wakes the guiding task.
pub static RECEIVED: Signal<CriticalSectionRawMutex, ()> = Signal::new();

/// Frames learned so far (wrapping), for the liveness check.
pub static FRAMES_LEARNED: AtomicU32 = AtomicU32::new(0);

pub fn frames_learned() -> u32 {
    FRAMES_LEARNED.load(Ordering::Relaxed)
}

/// The ST4 counters, for the status log.
pub static ST4_COUNTERS: Mutex<CriticalSectionRawMutex, Cell<Option<St4Counters>>> =
    Mutex::new(Cell::new(None));

/// Guide frames, from the guiding task to the learning task. The loop keeps
/// the frames there is no room for here, and drops its oldest when the
/// learner falls further behind (counted).
pub static FRAMES: Channel<CriticalSectionRawMutex, FrameRecord, FRAME_QUEUE> = Channel::new();

/// The newest learned frame with its feed-forward, from the learning task
/// to the guiding task (an older one not yet taken is replaced).
pub static LEARNED: Signal<CriticalSectionRawMutex, LearnedFrame> = Signal::new();

/// A model reset asked on a command port, for the learning task.
pub static RESET_MODEL: Signal<CriticalSectionRawMutex, ()> = Signal::new();

/// What the ports asked of the store, for the learning task (which owns
/// it).
pub static STORE_REQUESTS: Channel<CriticalSectionRawMutex, StoreRequest, 4> = Channel::new();

/// What became of the store's saves, from the learning task: each port's
/// outcome waiting for its reply, and the store's newest counters. A cell,
/// not a queue: a port has one save at a time, and only the newest
/// counters matter (a `Cell` of `Copy` values also brings no panic path).
pub static STORE_DONE: Mutex<CriticalSectionRawMutex, Cell<StoreDone>> =
    Mutex::new(Cell::new(StoreDone {
        replies: [None; PORTS],
        counters: StoreCounters {
            rewrites: 0,
            unverified: 0,
        },
    }));

/// See [`STORE_DONE`].
#[derive(Clone, Copy)]
pub struct StoreDone {
    /// Per port: saved (`true`) or not, waiting for its reply.
    pub replies: [Option<bool>; PORTS],
    pub counters: StoreCounters,
}

impl StoreDone {
    /// The learning task's side: `outcome` for the port that asked, and
    /// the counters.
    pub fn report(outcome: StoreOutcome) {
        STORE_DONE.lock(|cell| {
            let mut done = cell.get();
            if let Some(reply) = outcome.reply_to.and_then(|p| done.replies.get_mut(p)) {
                *reply = Some(outcome.saved);
            }
            done.counters = outcome.counters;
            cell.set(done);
        });
    }

    /// The guiding task's side: the outcomes waiting (taken) and the
    /// counters.
    pub fn take() -> StoreDone {
        STORE_DONE.lock(|cell| {
            let done = cell.get();
            cell.set(StoreDone {
                replies: [None; PORTS],
                ..done
            });
            done
        })
    }
}

/// Where the model came from, set by the learning task when it restores
/// it (at start-up, or at the worm index's first pass).
pub static MODEL_ORIGIN: Mutex<CriticalSectionRawMutex, Cell<ModelOrigin>> =
    Mutex::new(Cell::new(ModelOrigin::Cold));

/// The RA step count at the worm-index sensor's latest edge, for the
/// learning task.
pub static INDEX_EDGE: Signal<CriticalSectionRawMutex, i64> = Signal::new();

/// The ST4 edge budgets: asked by the EXTI interrupt before it queues an
/// edge, polled by the guiding task for masked lines. Borrowed only inside
/// its lock and never across one, so a borrow cannot fail: `try_borrow*`
/// keeps the borrow panics out of the firmware.
pub static STORM: Mutex<CriticalSectionRawMutex, RefCell<StormGuard>> =
    Mutex::new(RefCell::new(StormGuard::new()));

/// ST4 edge storms caught since start, for the status log.
pub fn storms() -> u32 {
    STORM.lock(|g| g.try_borrow().map_or(0, |g| g.storms()))
}
