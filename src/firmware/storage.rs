//! The store on the board: opened at boot, where the configuration comes
//! from, and the saves the command port asks for. The learning task owns
//! it after boot (thread mode: a save never delays a pulse or a step; an
//! erase, which stalls every flash read for 1-2 s, happens only on a save
//! that allows it).

use static_cell::StaticCell;

use hal::storage::StorageFlash;
use mkgp_mount::mount::config::MountConfig;
use mkgp_mount::persist::{Erase, LoadError, SaveError, Store};

use crate::firmware::log;

pub type FirmwareStore = Store<StorageFlash>;

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
/// user asked). Logs the outcome.
pub async fn save_config(store: &mut FirmwareStore, config: MountConfig) {
    let Ok(mount) = config.validate() else {
        defmt::error!("configuration save: refused by validation (the port checked it)");
        return;
    };
    report(
        "configuration",
        store.save_config(&mount, Erase::Allow).await,
    );
}

/// Logs a save's outcome.
pub fn report<E>(what: &str, result: Result<(), SaveError<E>>) {
    match result {
        Ok(()) => defmt::info!("{} saved", what),
        Err(SaveError::EraseDeferred) => {
            defmt::info!("{} save deferred: it needs a sector erase", what)
        }
        Err(SaveError::TooLarge { len }) => {
            defmt::error!("{} not saved: {} bytes is too large", what, len)
        }
        Err(SaveError::Geometry(_)) | Err(SaveError::Flash(_)) => {
            defmt::error!("{} not saved: the flash failed", what)
        }
    }
}
