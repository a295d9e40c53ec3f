//! The learning task, in thread mode below everything else: runs the model
//! once per guide frame and signals the feed-forward to the guiding task.

use core::sync::atomic::Ordering;

use static_cell::StaticCell;

use mkgp_mount::control_loop::learning::{LearningPolicy, StoreStep};
use mkgp_mount::control_loop::port_mount::{LearnedFrame, StoreOutcome, StoreRequest};
use mkgp_mount::control_loop::FrameRecord;
use mkgp_mount::mount::config::Mount;
use mkgp_mount::mount::learner::Learner;
use mkgp_mount::mount::worm_index::WormIndex;

use embassy_futures::select::{select3, Either3};
use embassy_time::Instant;

use crate::firmware::log;
use crate::firmware::shared::{
    StoreDone, FRAMES, FRAMES_LEARNED, INDEX_EDGE, LEARNED, MODEL_ORIGIN, RECEIVED, RESET_MODEL,
    STORE_REQUESTS,
};
use crate::firmware::storage::{self, FirmwareStore, SnapshotBuffer};
use crate::STAGES;

/// The store and what the learning task needs to save into it.
pub struct Storage {
    pub store: &'static mut FirmwareStore,
    pub buf: &'static mut SnapshotBuffer,
    /// Parked at power-off with the model saved at the park: the
    /// counters, and the model's phase, carried over.
    pub parked: bool,
    /// The worm-index sensor's passes (none if no sensor is fitted).
    pub index: WormIndex,
}

/// What the learning task's policy lends back for each save or restore.
struct Flash {
    store: &'static mut FirmwareStore,
    buf: &'static mut SnapshotBuffer,
}

/// The monotonic clock the policy's saves are timed on, µs.
fn now_us() -> u64 {
    Instant::now().as_micros()
}

/// With the test-only feature `inject-model-fault` (never for a board): the
/// learned frame at which this task panics, so that host-tests/tests/board.rs
/// sees the fault path as wired (the pins, the record, the next boot's log).
#[cfg(feature = "inject-model-fault")]
const INJECTED_FAULT_AT_FRAME: u32 = 3;

/// The model's storage: a static, handed out once.
static LEARNER: StaticCell<Learner<STAGES>> = StaticCell::new();

/// Builds the model in [`LEARNER`], in place (`Learner::init`: no
/// temporary copy on the stack). Not inlined, so that its stack frame is
/// its own and can be read in the disassembly (`docs/firmware.md`).
#[inline(never)]
pub fn make_learner(mount: &Mount) -> Option<&'static mut Learner<STAGES>> {
    LEARNER.try_uninit().map(|slot| Learner::init(slot, mount))
}

/// What can wake the learning task.
enum Event {
    Frame(FrameRecord),
    Store(StoreRequest),
    /// The worm-index sensor's edge, at this RA step count.
    Index(i64),
}

/// Restores the saved model, then runs the model once per guide frame
/// (the longest thing that runs here) and hands the learned frame with its
/// feed-forward to the guiding task. When to reset, save and restore the
/// model and what to do with a port's request to the store is the
/// library's [`LearningPolicy`]; this task carries it out (the flash, the
/// channels). Everything else preempts it.
#[embassy_executor::task]
pub async fn learning_task(learner: &'static mut Learner<STAGES>, storage: Option<Storage>) {
    let mut policy = match storage {
        Some(Storage {
            store,
            buf,
            parked,
            index,
        }) => {
            let origin = storage::restore_model(store, learner, parked).await;
            MODEL_ORIGIN.lock(|o| o.set(origin));
            LearningPolicy::with_store(Flash { store, buf }, parked, index, now_us())
        }
        None => LearningPolicy::without_store(),
    };
    let mut logged = log::Logged::NONE;
    loop {
        let event = match select3(
            FRAMES.receive(),
            STORE_REQUESTS.receive(),
            INDEX_EDGE.wait(),
        )
        .await
        {
            Either3::First(msg) => Event::Frame(msg),
            Either3::Second(request) => Event::Store(request),
            Either3::Third(ra_steps) => Event::Index(ra_steps),
        };
        let msg = match event {
            Event::Frame(msg) => msg,
            Event::Store(request) => {
                let outcome = match policy.store_request(request) {
                    StoreStep::Serve {
                        storage: flash,
                        request,
                        index_pass,
                    } => storage::serve(flash.store, learner, flash.buf, request, index_pass).await,
                    StoreStep::Refuse(outcome) => outcome,
                };
                StoreDone::report(outcome);
                RECEIVED.signal(());
                continue;
            }
            Event::Index(ra_steps) => {
                if let Some(restore) = policy.index_edge(ra_steps) {
                    let flash = restore.storage;
                    if let Some(origin) =
                        storage::restore_at_index(flash.store, learner, restore.pass).await
                    {
                        MODEL_ORIGIN.lock(|o| o.set(origin));
                    }
                }
                continue;
            }
        };
        if RESET_MODEL.try_take().is_some() {
            policy.ask_reset();
        }
        if policy.frame().reset_first {
            learner.reset();
            defmt::warn!("model reset, as asked on the command port");
        }
        let ff = learner.learn(msg.frame);
        let _learned = FRAMES_LEARNED.fetch_add(1, Ordering::Relaxed) + 1;
        #[cfg(feature = "inject-model-fault")]
        if _learned == INJECTED_FAULT_AT_FRAME {
            panic!("fault injected in the model's task");
        }
        LEARNED.signal(LearnedFrame::of(learner, &msg.frame, ff));
        log::frame(learner, &msg, &ff, &mut logged);
        if let Some(save) = policy.learned(now_us()) {
            let flash = save.storage;
            let saved =
                storage::save_model(flash.store, learner, flash.buf, save.erase, save.index_pass)
                    .await;
            // For the store's counters on the ports.
            StoreDone::report(StoreOutcome {
                reply_to: None,
                saved,
                counters: flash.store.counters(),
            });
        }
        // The command port shares this executor: with frames queued, the
        // next receive would not yield, and the port would wait for the
        // whole backlog rather than one frame.
        embassy_futures::yield_now().await;
    }
}
