//! The learning task, in thread mode below everything else: runs the model
//! once per guide frame and signals the feed-forward to the guiding task.

use core::sync::atomic::Ordering;

use static_cell::StaticCell;

use mkgp_mount::control_loop::port_mount::{LearnedFrame, StoreOutcome, StoreRequest};
use mkgp_mount::control_loop::FrameRecord;
use mkgp_mount::mount::config::Mount;
use mkgp_mount::mount::learner::Learner;
use mkgp_mount::mount::worm_index::WormIndex;

use embassy_futures::select::{select3, Either3};
use embassy_time::{Duration, Instant};
use mkgp_mount::persist::{Erase, StoreCounters};

use crate::firmware::log;
use crate::firmware::shared::{
    StoreDone, FRAMES, FRAMES_LEARNED, INDEX_EDGE, LEARNED, MODEL_ORIGIN, RECEIVED, RESET_MODEL,
    STORE_REQUESTS,
};
use crate::firmware::storage::{self, FirmwareStore, SnapshotBuffer};
use crate::STAGES;

/// How often the model is saved while it learns. With the three-stage
/// model's 8 KiB snapshot a storage page takes 14 saves: 2.3 hours of
/// guiding before a save would need an erase, which these saves never do
/// (docs/persistence.md has the wear arithmetic at this cadence).
const SAVE_EVERY: Duration = Duration::from_secs(600);

/// The store and what the learning task needs to save into it.
pub struct Storage {
    pub store: &'static mut FirmwareStore,
    pub buf: &'static mut SnapshotBuffer,
    /// Parked at power-off: the counters, and the model's phase, carried over.
    pub parked: bool,
    /// The worm-index sensor's passes (none if no sensor is fitted).
    pub index: WormIndex,
}

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
/// feed-forward to the guiding task. A model reset asked on a port is
/// carried out before the next frame; what a port asks of the store, at
/// once; every [`SAVE_EVERY`] of learning the model is saved without
/// erasing. At the worm-index sensor's first pass, unless a park gave the
/// phase, the saved model is restored again with the worm's phase from
/// the sensor. Everything else preempts it.
#[embassy_executor::task]
pub async fn learning_task(learner: &'static mut Learner<STAGES>, mut storage: Option<Storage>) {
    if let Some(s) = storage.as_mut() {
        let origin = storage::restore_model(s.store, learner, s.parked).await;
        MODEL_ORIGIN.lock(|o| o.set(origin));
    }
    let mut last_save = Instant::now();
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
                let outcome = match storage.as_mut() {
                    Some(s) => {
                        let pass = s.index.last_pass();
                        storage::serve(s.store, learner, s.buf, request, pass).await
                    }
                    // Not asked without a store (`PortState::store`).
                    None => StoreOutcome {
                        reply_to: request.reply_to(),
                        saved: false,
                        counters: StoreCounters::default(),
                    },
                };
                StoreDone::report(outcome);
                RECEIVED.signal(());
                continue;
            }
            Event::Index(ra_steps) => {
                if let Some(s) = storage.as_mut() {
                    if s.index.edge(ra_steps) && s.index.passes() == 1 && !s.parked {
                        if let Some(origin) =
                            storage::restore_at_index(s.store, learner, &s.index, ra_steps).await
                        {
                            MODEL_ORIGIN.lock(|o| o.set(origin));
                        }
                    }
                }
                continue;
            }
        };
        if RESET_MODEL.try_take().is_some() {
            learner.reset();
            defmt::warn!("model reset, as asked on the command port");
        }
        let ff = learner.learn(msg.frame);
        FRAMES_LEARNED.fetch_add(1, Ordering::Relaxed);
        LEARNED.signal(LearnedFrame::of(learner, &msg.frame, ff));
        log::frame(learner, &msg, &ff, &mut logged);
        if let Some(s) = storage.as_mut() {
            if last_save.elapsed() >= SAVE_EVERY {
                last_save = Instant::now();
                let pass = s.index.last_pass();
                let saved = storage::save_model(s.store, learner, s.buf, Erase::Defer, pass).await;
                // For the store's counters on the ports.
                StoreDone::report(StoreOutcome {
                    reply_to: None,
                    saved,
                    counters: s.store.counters(),
                });
            }
        }
    }
}
