//! What the mount remembers across a power cycle: its configuration, the
//! learned model's snapshot and the axes' step counts at park, kept in the
//! flash sectors `memory.x` leaves to storage.
//!
//! The layer is hardware-free and allocation-free: a [`Store`] over any
//! NOR flash (the `embedded-storage-async` traits that embassy-stm32's
//! flash driver implements), and the records' byte layouts. The map under
//! it is sequential-storage's: a record is appended, never overwritten, and
//! a CRC tells a complete record from one a power cut interrupted, so a cut
//! loses at most the save in progress. Each record carries a format
//! version: one written by another firmware's layout is refused (a typed
//! error) and the caller uses its defaults. The store's methods are async
//! (the firmware calls them from its thread-mode task).
//!
//! - [`store`]: load and save each record; a save says whether it may erase
//!   a sector ([`Erase`]), since erasing stalls the CPU for 1-2 s;
//! - [`erase_gate`]: the flash wrapper that defers erases;
//! - `recovery`: finishes a sector erase a power cut interrupted, which
//!   sequential-storage alone can mistake for a page in use;
//! - [`record`]: the versioned envelope around every record;
//! - [`config_record`], [`park`]: the configuration's and the park's layouts
//!   (the model snapshot's layout is the model's, an opaque byte string
//!   here);
//! - [`wear`]: erase cycles per year for a save cadence, from the record
//!   sizes;
//! - `sim_flash` (feature `testing`): a simulated STM32F4 flash whose power
//!   can be cut at any operation, for the power-fail tests.
//!
//! docs/persistence.md has the flash map, the erase policy and the wear
//! arithmetic.

pub mod config_record;
pub mod erase_gate;
pub mod park;
pub mod record;
mod recovery;
#[cfg(any(test, feature = "testing"))]
pub mod sim_flash;
pub mod store;
pub mod wear;

#[cfg(test)]
mod power_fail_tests;

pub use erase_gate::Erase;
pub use park::Park;
pub use store::{LoadError, SaveError, Store, StoreCounters};

/// The largest model snapshot the store takes, in bytes. The store's buffer
/// holds one record of this size ([`store::BUFFER_LEN`], 8224 bytes of RAM).
pub const MODEL_RECORD_MAX: usize = 8192;
// The learner's largest record fits it.
const _: () = assert!(crate::mount::learner::RECORD_MAX <= MODEL_RECORD_MAX);
