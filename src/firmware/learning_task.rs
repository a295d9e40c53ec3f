//! The learning task, in thread mode below everything else: runs the model
//! once per guide frame and signals the feed-forward to the guiding task.

use static_cell::StaticCell;

use mkgp_mount::mount::config::Mount;
use mkgp_mount::mount::learner::Learner;

use crate::firmware::guiding_task::{FEED_FORWARD, FRAMES};
use crate::firmware::log;
use crate::STAGES;

/// The model's storage: a static, handed out once.
static LEARNER: StaticCell<Learner<STAGES>> = StaticCell::new();

/// Builds the model in [`LEARNER`]. Not inlined, so that its stack frame is
/// its own and can be read in the disassembly: `Learner::new` returns by
/// value, and LLVM builds most of it in a temporary on the stack
/// (`docs/firmware.md`).
#[inline(never)]
pub fn make_learner(mount: &Mount) -> Option<&'static mut Learner<STAGES>> {
    LEARNER.try_init_with(|| Learner::new(mount))
}

/// Runs the model once per guide frame (the longest thing that runs here)
/// and hands the feed-forward to the guiding task. Everything else preempts
/// it.
#[embassy_executor::task]
pub async fn learning_task(learner: &'static mut Learner<STAGES>) {
    loop {
        let msg = FRAMES.receive().await;
        let ff = learner.learn(msg.frame);
        FEED_FORWARD.signal(ff);
        log::frame(learner, &msg, &ff);
    }
}
