//! The store on the board: opened at boot, where the configuration, the
//! park and the model come from, and the saves. The learning task owns it
//! after boot (thread mode: a save never delays a pulse or a step). An
//! erase stalls every flash read, the step tick's included, for 1-2 s: the
//! periodic model saves never erase ([`Erase::Defer`]); only the boot, a
//! park, an unpark and the saves a user asks for may.

use core::future::Future;
use core::mem::MaybeUninit;
use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use static_cell::StaticCell;

use hal::storage::StorageFlash;
use mkgp_mount::control_loop::learning::IndexPass;
use mkgp_mount::control_loop::port_mount::{StoreOutcome, StoreRequest};
use mkgp_mount::model::snapshot::{Phase, SnapshotError};
use mkgp_mount::mount::config::MountConfig;
use mkgp_mount::mount::learner::{Learner, RECORD_FORMAT, RECORD_MAX};
use mkgp_mount::persist::store::SAVE_ATTEMPTS;
use mkgp_mount::persist::{Erase, LoadError, Park, SaveError, Store};
use mkgp_mount::port::mount_port::ModelOrigin;

use crate::firmware::log;
use crate::STAGES;

pub type FirmwareStore = Store<StorageFlash>;

/// Store operations begun and ended (odd while one runs), for the
/// liveness check: a sector erase stalls the step tick for up to 2 s.
static FLASH_OPERATIONS: AtomicU32 = AtomicU32::new(0);

pub fn flash_operations() -> u32 {
    FLASH_OPERATIONS.load(Ordering::Relaxed)
}

/// Runs a store operation with [`FLASH_OPERATIONS`] odd meanwhile.
async fn flash_operation<T>(operation: impl Future<Output = T>) -> T {
    FLASH_OPERATIONS.fetch_add(1, Ordering::Relaxed);
    let out = operation.await;
    FLASH_OPERATIONS.fetch_add(1, Ordering::Relaxed);
    out
}

/// The store and its 8 KiB buffer, in a static.
static STORE: StaticCell<FirmwareStore> = StaticCell::new();

/// Opens the store on the storage sectors; `None` if it was opened before.
pub fn open(
    flash: embassy_stm32::Peri<'static, embassy_stm32::peripherals::FLASH>,
) -> Option<&'static mut FirmwareStore> {
    let flash = hal::storage::storage_flash(flash);
    STORE
        .try_uninit()
        .map(|slot| slot.write(Store::new(flash, hal::storage::storage_range())))
}

/// The configuration to start with: the stored one if there is a valid
/// one, else the defaults (and the log says why).
pub async fn boot_config(store: &mut FirmwareStore) -> MountConfig {
    match store.load_config().await {
        Ok(mount) => {
            defmt::info!("configuration: the stored one");
            *mount.config()
        }
        Err(e) => {
            match e {
                LoadError::NothingStored => {
                    defmt::info!("configuration: none stored, the defaults")
                }
                LoadError::Format { found, expected } => defmt::warn!(
                    "configuration: stored by another firmware (format {}, this one reads {}); the defaults",
                    found,
                    expected
                ),
                LoadError::Malformed => {
                    defmt::warn!("configuration: the stored one is malformed; the defaults")
                }
                LoadError::Invalid(e) => {
                    log::config_refused(&e);
                    defmt::warn!("configuration: the stored one is refused; the defaults")
                }
                LoadError::Geometry(_) | LoadError::Flash(_) => {
                    defmt::error!("configuration: the store cannot be read; the defaults")
                }
            }
            MountConfig::default()
        }
    }
}

/// Saves a configuration the port validated, now (an erase allowed: the
/// user asked). Logs the outcome; whether it was saved.
pub async fn save_config(store: &mut FirmwareStore, config: MountConfig) -> bool {
    let Ok(mount) = config.validate() else {
        defmt::error!("configuration save: refused by validation (the port checked it)");
        return false;
    };
    let saved = flash_operation(store.save_config(&mount, Erase::Allow)).await;
    report("configuration", saved)
}

/// Logs a save's outcome; whether it was saved.
pub fn report<E>(what: &str, result: Result<(), SaveError<E>>) -> bool {
    let saved = result.is_ok();
    match result {
        Ok(()) => defmt::info!("{} saved", what),
        Err(SaveError::EraseDeferred) => {
            defmt::info!("{} save deferred: it needs a sector erase", what)
        }
        Err(SaveError::TooLarge { len }) => {
            defmt::error!("{} not saved: {} bytes is too large", what, len)
        }
        Err(SaveError::Unverified) => defmt::error!(
            "{} not saved: it read back wrong {} times (flash not erased where it wrote); the previous one stays",
            what,
            SAVE_ATTEMPTS
        ),
        Err(SaveError::Geometry(_)) | Err(SaveError::Flash(_)) => {
            defmt::error!("{} not saved: the flash failed", what)
        }
    }
    saved
}

/// The park the mount was switched off in, if any: its step counts, which
/// the axes start from so that the gear's phase carries over (and the
/// model's, if it was saved with the park: [`Park::carries_model`]).
/// Cleared once read, so that a later start does not take it for a park
/// again.
pub async fn boot_park(store: &mut FirmwareStore) -> Option<Park> {
    match store.load_park().await {
        Ok(park) => {
            defmt::info!(
                "parked at RA {} Dec {} steps: the gear's phase carries over (the model's: {})",
                park.ra_steps,
                park.dec_steps,
                park.carries_model
            );
            report("park cleared", store.clear_park(Erase::Allow).await);
            Some(park)
        }
        Err(LoadError::NothingStored) => None,
        Err(_) => {
            defmt::warn!("park record unreadable: the gear's phase will be found again");
            None
        }
    }
}

/// Takes the saved model back at start-up, with the phase from a park or
/// unknown; returns where the model came from.
pub async fn restore_model(
    store: &mut FirmwareStore,
    learner: &mut Learner<STAGES>,
    parked: bool,
) -> ModelOrigin {
    let (phase, origin) = if parked {
        // The counters continue the saved ones: so does gear time.
        (
            Phase::Known {
                gear_time_offset_s: 0.0,
            },
            ModelOrigin::Park,
        )
    } else {
        (Phase::Unknown, ModelOrigin::Relearn)
    };
    match flash_operation(store.load_model(RECORD_FORMAT)).await {
        Ok(bytes) => match learner.restore(bytes, RECORD_FORMAT, phase) {
            Ok(()) => {
                defmt::info!("model restored ({} bytes)", bytes.len());
                origin
            }
            Err(e) => {
                defmt::warn!(
                    "stored model refused ({}): learning from the start",
                    e.reason()
                );
                ModelOrigin::Cold
            }
        },
        Err(LoadError::NothingStored) => {
            defmt::info!("no stored model: learning from the start");
            ModelOrigin::Cold
        }
        Err(_) => {
            defmt::warn!("stored model unreadable or of another firmware: learning from the start");
            ModelOrigin::Cold
        }
    }
}

/// At the worm-index sensor's first `pass`: the saved model again, with
/// the worm's phase from the pass saved with it. `None` (and the model as
/// it is) if there is no saved pass or model.
pub async fn restore_at_index(
    store: &mut FirmwareStore,
    learner: &mut Learner<STAGES>,
    pass: IndexPass,
) -> Option<ModelOrigin> {
    // Loads may repair a page a power cut left (an erase): counted too.
    let saved_pass = flash_operation(store.load_index()).await.ok()?;
    let phase = pass.phase(saved_pass);
    let bytes = flash_operation(store.load_model(RECORD_FORMAT))
        .await
        .ok()?;
    match learner.restore(bytes, RECORD_FORMAT, phase) {
        Ok(()) => {
            defmt::info!("model restored at the worm index's first pass");
            Some(ModelOrigin::Index)
        }
        Err(e) => {
            defmt::warn!(
                "stored model refused at the worm index's pass ({})",
                e.reason()
            );
            None
        }
    }
}

/// The learner's record being written, for the store (`RECORD_MAX` bytes).
pub type SnapshotBuffer = [u8; RECORD_MAX];

/// The snapshot buffer's memory. On the L475 it lies in SRAM2 (memory.x,
/// section `.sram2`, not zeroed at reset), which leaves the stack in SRAM1
/// 8 KiB more: the first frame after a restore at the worm index took the
/// stack there to its last word (docs/firmware.md).
#[cfg_attr(feature = "stm32l475vg", link_section = ".sram2.SNAPSHOT")]
static mut SNAPSHOT: MaybeUninit<SnapshotBuffer> = MaybeUninit::uninit();
/// Whether [`snapshot_buffer`] has handed the buffer out.
static SNAPSHOT_TAKEN: AtomicBool = AtomicBool::new(false);

/// The snapshot buffer, once. Zeroed where it lies: `try_init([0; ..])`
/// built the 8 KiB on the stack first, the deepest the stack went.
pub fn snapshot_buffer() -> Option<&'static mut SnapshotBuffer> {
    if SNAPSHOT_TAKEN.swap(true, Ordering::Relaxed) {
        return None;
    }
    // SAFETY: the flag hands the buffer out once, so this is its only
    // reference; zero bytes are a valid `[u8; N]`, written before it is
    // read.
    Some(unsafe {
        let slot = &mut *core::ptr::addr_of_mut!(SNAPSHOT);
        slot.as_mut_ptr().write_bytes(0, 1);
        slot.assume_init_mut()
    })
}

/// Saves the learned model, and with it the worm index's last pass if
/// there was one; `erase` says whether a sector may be erased (which stops
/// tracking for 1-2 s). Whether the model was saved.
pub async fn save_model(
    store: &mut FirmwareStore,
    learner: &Learner<STAGES>,
    buf: &mut SnapshotBuffer,
    erase: Erase,
    index_pass: Option<i64>,
) -> bool {
    match learner.snapshot(buf) {
        Ok(n) => {
            let bytes = buf.get(..n).unwrap_or(&[]);
            let saved = flash_operation(store.save_model(RECORD_FORMAT, bytes, erase)).await;
            let model_saved = report("model", saved);
            if let (true, Some(pass)) = (model_saved, index_pass) {
                let saved = flash_operation(store.save_index(pass, erase)).await;
                report("worm index pass", saved);
            }
            model_saved
        }
        Err(SnapshotError::Placing) => {
            defmt::info!("model not saved yet: its restored data awaits its phase");
            false
        }
        Err(_) => {
            defmt::error!("model not saved: its snapshot failed");
            false
        }
    }
}

/// Serves what a port asked of the store; what became of it.
pub async fn serve(
    store: &mut FirmwareStore,
    learner: &Learner<STAGES>,
    buf: &mut SnapshotBuffer,
    request: StoreRequest,
    index_pass: Option<i64>,
) -> StoreOutcome {
    let saved = match request {
        StoreRequest::Config { config, .. } => save_config(store, config).await,
        StoreRequest::Model { .. } => {
            save_model(store, learner, buf, Erase::Allow, index_pass).await
        }
        StoreRequest::Park(counts) => {
            // The model first: the park says whether it went with it.
            let model_saved = save_model(store, learner, buf, Erase::Allow, index_pass).await;
            let park = Park {
                ra_steps: counts.ra,
                dec_steps: counts.dec,
                carries_model: model_saved,
            };
            let saved = flash_operation(store.save_park(park, Erase::Allow)).await;
            report("park", saved) & model_saved
        }
        StoreRequest::Unpark => {
            let saved = flash_operation(store.clear_park(Erase::Allow)).await;
            report("unpark", saved)
        }
    };
    StoreOutcome {
        reply_to: request.reply_to(),
        saved,
        counters: store.counters(),
    }
}
