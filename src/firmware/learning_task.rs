//! The learning task, in thread mode below everything else: runs the model
//! once per guide frame and signals the feed-forward to the guiding task.

use core::sync::atomic::{AtomicU32, Ordering};

use static_cell::StaticCell;

use mkgp_mount::control_loop::port_mount::LearnedFrame;
use mkgp_mount::mount::config::Mount;
use mkgp_mount::mount::learner::Learner;

use embassy_futures::select::{select, Either};

use crate::firmware::guiding_task::{FRAMES, LEARNED, RESET_MODEL, SAVE_CONFIG};
use crate::firmware::log;
use crate::firmware::storage::{self, FirmwareStore};
use crate::STAGES;

/// The model's storage: a static, handed out once.
static LEARNER: StaticCell<Learner<STAGES>> = StaticCell::new();

/// Frames learned so far (wrapping), for the liveness check.
static FRAMES_LEARNED: AtomicU32 = AtomicU32::new(0);

pub fn frames_learned() -> u32 {
    FRAMES_LEARNED.load(Ordering::Relaxed)
}

/// Builds the model in [`LEARNER`], in place (`Learner::init`: no
/// temporary copy on the stack). Not inlined, so that its stack frame is
/// its own and can be read in the disassembly (`docs/firmware.md`).
#[inline(never)]
pub fn make_learner(mount: &Mount) -> Option<&'static mut Learner<STAGES>> {
    LEARNER.try_uninit().map(|slot| Learner::init(slot, mount))
}

/// Runs the model once per guide frame (the longest thing that runs here)
/// and hands the learned frame with its feed-forward to the guiding task.
/// A model reset asked on a port is carried out before the next frame; a
/// configuration save asked on a port goes to the store at once.
/// Everything else preempts it.
#[embassy_executor::task]
pub async fn learning_task(
    learner: &'static mut Learner<STAGES>,
    mut store: Option<&'static mut FirmwareStore>,
) {
    loop {
        let msg = match select(FRAMES.receive(), SAVE_CONFIG.wait()).await {
            Either::First(msg) => msg,
            Either::Second(config) => {
                if let Some(store) = store.as_deref_mut() {
                    storage::save_config(store, config).await;
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
        log::frame(learner, &msg, &ff);
    }
}
