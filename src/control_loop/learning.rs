//! The learning task's policy as a sans-IO step: when the model is reset,
//! saved and restored, and what becomes of a port's request to the store.
//! The board's learning task (`src/firmware/learning_task.rs`) and the
//! simulator's (`host-tests`' `st4_sim::Rig`) drive the same
//! [`LearningPolicy`] and only carry out what it decides: the learning, the
//! flash and the channels are theirs. Each step that needs the store lends
//! the caller's handle on it (`S`), so that what is decided and what it is
//! done with cannot disagree.
//!
//! - [`LearningPolicy::ask_reset`]: a model reset asked on a port, carried
//!   out before the next frame ([`LearningPolicy::frame`]): the model is
//!   the learning task's alone, a port only asks.
//! - [`LearningPolicy::learned`]: after each frame learned, whether to save
//!   the model now ([`SAVE_EVERY_US`] after the last periodic save, never
//!   erasing).
//! - [`LearningPolicy::index_edge`]: at the worm-index sensor's first pass,
//!   unless a park gave the phase, restore the saved model with the
//!   worm's phase from the pass.
//! - [`LearningPolicy::store_request`]: serve what a port asked of the
//!   store, with the worm index's last pass saved beside a model.

use crate::control_loop::port_mount::{StoreOutcome, StoreRequest};
use crate::model::snapshot::Phase;
use crate::mount::worm_index::WormIndex;
use crate::persist::{Erase, StoreCounters};

/// How often the model is saved while it learns, µs. With the three-stage
/// model's 8 KiB snapshot a storage page takes 14 saves: 2.3 hours of
/// guiding before a save would need an erase, which these saves never do
/// (docs/persistence.md has the wear arithmetic at this cadence).
pub const SAVE_EVERY_US: u64 = 600_000_000;

/// What the learning task does with a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Learn {
    /// Reset the model first: a port asked for it since the last frame.
    pub reset_first: bool,
}

/// Save the model now into `storage`, and with it the worm index's last
/// pass if there was one.
#[derive(Debug, PartialEq, Eq)]
pub struct Save<'a, S> {
    pub storage: &'a mut S,
    /// Never [`Erase::Allow`] for the periodic saves: an erase stops
    /// tracking for 1-2 s, and nobody asked for this save.
    pub erase: Erase,
    pub index_pass: Option<i64>,
}

/// Restore the model saved in `storage` with the worm's phase from the
/// index `pass` (the model as it is if no pass was saved).
#[derive(Debug, PartialEq)]
pub struct RestoreAtIndex<'a, S> {
    pub storage: &'a mut S,
    pub pass: IndexPass,
}

/// The worm-index sensor's pass that restores the model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IndexPass {
    pub ra_steps: i64,
    /// The passes, for the gear time between this one and the saved one.
    index: WormIndex,
}

impl IndexPass {
    /// The phase to restore with, given the pass saved with the model.
    pub fn phase(&self, saved_pass: i64) -> Phase {
        Phase::Worm {
            gear_time_offset_s: self.index.offset_s(saved_pass, self.ra_steps),
        }
    }
}

/// What the learning task does with a port's request to the store.
#[derive(Debug, PartialEq)]
pub enum StoreStep<'a, S> {
    /// Carry it out on `storage`; a model saved goes with this worm-index
    /// pass.
    Serve {
        storage: &'a mut S,
        request: StoreRequest,
        index_pass: Option<i64>,
    },
    /// No store: report this outcome (not saved). The ports do not ask
    /// without one (`PortState::store`), but a port waiting for its reply
    /// must get one.
    Refuse(StoreOutcome),
}

/// The store's side of the policy, when there is a store.
#[derive(Debug)]
struct Stored<S> {
    /// The caller's handle on the store, lent with each step that uses it.
    storage: S,
    /// Parked at power-off: the boot's restore had the phase already, so
    /// the index pass brings nothing the model lacks.
    parked: bool,
    index: WormIndex,
    /// When the model was last saved by the policy, or the task started.
    last_save_us: u64,
}

/// The learning task's decisions, over the caller's store `S`: see the
/// module's documentation.
#[derive(Debug)]
pub struct LearningPolicy<S> {
    stored: Option<Stored<S>>,
    reset_asked: bool,
}

impl<S> LearningPolicy<S> {
    /// With `storage`, from `now_us` (a monotonic clock, µs; the first
    /// save comes [`SAVE_EVERY_US`] later): `parked` if the mount was
    /// parked at power-off, `index` the worm-index sensor's passes.
    pub fn with_store(storage: S, parked: bool, index: WormIndex, now_us: u64) -> Self {
        LearningPolicy {
            stored: Some(Stored {
                storage,
                parked,
                index,
                last_save_us: now_us,
            }),
            reset_asked: false,
        }
    }

    /// Without a store: the model is never saved nor restored, and the
    /// index sensor's edges change nothing.
    pub fn without_store() -> Self {
        LearningPolicy {
            stored: None,
            reset_asked: false,
        }
    }

    /// The caller's store, for what it does with it between the steps (a
    /// simulator reading back what was saved).
    pub fn storage(&mut self) -> Option<&mut S> {
        self.stored.as_mut().map(|s| &mut s.storage)
    }

    /// A port asked for a model reset (several before a frame are one).
    pub fn ask_reset(&mut self) {
        self.reset_asked = true;
    }

    /// A frame arrived: learn it, after the reset asked, if any.
    pub fn frame(&mut self) -> Learn {
        Learn {
            reset_first: core::mem::take(&mut self.reset_asked),
        }
    }

    /// The frame is learned, at `now_us` (the clock of
    /// [`with_store`](Self::with_store)): a periodic save, when one is due.
    pub fn learned(&mut self, now_us: u64) -> Option<Save<'_, S>> {
        let s = self.stored.as_mut()?;
        if now_us.saturating_sub(s.last_save_us) < SAVE_EVERY_US {
            return None;
        }
        s.last_save_us = now_us;
        Some(Save {
            storage: &mut s.storage,
            erase: Erase::Defer,
            index_pass: s.index.last_pass(),
        })
    }

    /// An edge of the worm-index sensor with the RA axis at `ra_steps`:
    /// at the first pass, unless parked, the saved model again with the
    /// worm's phase.
    pub fn index_edge(&mut self, ra_steps: i64) -> Option<RestoreAtIndex<'_, S>> {
        let s = self.stored.as_mut()?;
        let first = s.index.edge(ra_steps) && s.index.passes() == 1;
        (first && !s.parked).then_some(RestoreAtIndex {
            storage: &mut s.storage,
            pass: IndexPass {
                ra_steps,
                index: s.index,
            },
        })
    }

    /// A port's request to the store.
    pub fn store_request(&mut self, request: StoreRequest) -> StoreStep<'_, S> {
        match self.stored.as_mut() {
            Some(s) => StoreStep::Serve {
                storage: &mut s.storage,
                request,
                index_pass: s.index.last_pass(),
            },
            None => StoreStep::Refuse(StoreOutcome {
                reply_to: request.reply_to(),
                saved: false,
                counters: StoreCounters::default(),
            }),
        }
    }
}

#[cfg(test)]
mod tests;
