//! The board's store for the simulated learning task (`st4_sim::Rig`): the
//! firmware's own `Store` on a simulated STM32F4 flash of two 128 KiB
//! sectors, written as the board's learning task writes it
//! (`src/firmware/storage.rs`) when the library's `LearningPolicy` asks:
//! the model with the worm index's last pass, the park, the configuration.
//! The flash outlives the rig, so a later rig (the next night) boots from
//! it.

use embassy_futures::block_on;
use mkgp_mount::control_loop::port_mount::{StoreOutcome, StoreRequest};
use mkgp_mount::mount::learner::RECORD_FORMAT;
use mkgp_mount::persist::sim_flash::SimFlash;
use mkgp_mount::persist::{Erase, Park, Store, StoreCounters};

/// A storage sector of the F411's store, bytes.
const SECTOR: usize = 128 * 1024;

/// The store's flash (erased at first) and the counters of its saves.
#[derive(Clone)]
pub struct SimStore {
    flash: Vec<u8>,
    counters: StoreCounters,
}

impl Default for SimStore {
    fn default() -> Self {
        SimStore {
            flash: vec![0xFF; 2 * SECTOR],
            counters: StoreCounters::default(),
        }
    }
}

/// The firmware's store on the simulated flash.
type FlashStore<'a> = Store<SimFlash<'a, SECTOR>>;

impl SimStore {
    /// `op` on the firmware's store over the flash. The store keeps
    /// nothing between operations but its counters (added up here), so
    /// one per operation is the board's one store.
    fn with_store<T>(&mut self, op: impl FnOnce(&mut FlashStore<'_>) -> T) -> T {
        let range = 0..self.flash.len() as u32;
        let mut store = Store::new(SimFlash::new(&mut self.flash), range);
        let out = op(&mut store);
        let c = store.counters();
        self.counters.rewrites += c.rewrites;
        self.counters.unverified += c.unverified;
        out
    }

    /// The park the next boot reads, if one was saved.
    pub fn load_park(&mut self) -> Option<Park> {
        self.with_store(|s| block_on(s.load_park()).ok())
    }

    /// The model the next boot loads, if one was saved.
    pub fn load_model(&mut self) -> Option<Vec<u8>> {
        self.with_store(|s| {
            block_on(s.load_model(RECORD_FORMAT))
                .ok()
                .map(<[u8]>::to_vec)
        })
    }

    /// Saves the learner's `model` (none: no learner, or its snapshot
    /// refused), and with it the worm index's last pass if there was one;
    /// whether the model was saved.
    pub fn save_model(
        &mut self,
        model: Option<&[u8]>,
        erase: Erase,
        index_pass: Option<i64>,
    ) -> bool {
        let Some(model) = model else {
            return false;
        };
        self.with_store(|s| {
            let saved = block_on(s.save_model(RECORD_FORMAT, model, erase)).is_ok();
            if let (true, Some(pass)) = (saved, index_pass) {
                // As on the board: a pass not saved leaves the model saved.
                let _ = block_on(s.save_index(pass, erase));
            }
            saved
        })
    }

    /// Serves what a port asked of the store, the learner's `model` saved
    /// with `index_pass`; what became of it.
    pub fn serve(
        &mut self,
        model: Option<&[u8]>,
        request: StoreRequest,
        index_pass: Option<i64>,
    ) -> StoreOutcome {
        let saved = match request {
            StoreRequest::Config { config, .. } => config.validate().is_ok_and(|mount| {
                self.with_store(|s| block_on(s.save_config(&mount, Erase::Allow)).is_ok())
            }),
            StoreRequest::Model { .. } => self.save_model(model, Erase::Allow, index_pass),
            StoreRequest::Park(counts) => {
                // The model first: the park says whether it went with it
                // (as the firmware's `storage::serve`).
                let model_saved = self.save_model(model, Erase::Allow, index_pass);
                let park = Park {
                    ra_steps: counts.ra,
                    dec_steps: counts.dec,
                    carries_model: model_saved,
                };
                let parked = self.with_store(|s| block_on(s.save_park(park, Erase::Allow)).is_ok());
                parked & model_saved
            }
            StoreRequest::Unpark => {
                self.with_store(|s| block_on(s.clear_park(Erase::Allow)).is_ok())
            }
        };
        StoreOutcome {
            reply_to: request.reply_to(),
            saved,
            counters: self.counters,
        }
    }
}
