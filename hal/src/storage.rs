//! The flash the `persist` store keeps its records in: embassy-stm32's
//! flash driver (interrupt-driven writes and erases) and the storage range
//! of [`crate::flash_map`], as offsets from the flash base the driver takes.
//! On the L475, whose flash erases in 2 KiB pages, the driver is wrapped so
//! that the store sees [`STORAGE_SECTOR_SIZE`] sectors (a model record is
//! larger than a page).

use core::ops::Range;

use embassy_stm32::flash::{Async, Flash, InterruptHandler};
use embassy_stm32::{bind_interrupts, peripherals, Peri};

use crate::flash_map::{STORAGE_OFFSET, STORAGE_SECTORS, STORAGE_SECTOR_SIZE};

bind_interrupts!(struct Irqs {
    FLASH => InterruptHandler;
});

/// The whole flash, as the store reaches it (it only ever touches
/// [`storage_range`]).
#[cfg(not(feature = "stm32l475vg"))]
pub type StorageFlash = Flash<'static, Async>;

/// The flash driver.
#[cfg(not(feature = "stm32l475vg"))]
pub fn storage_flash(flash: Peri<'static, peripherals::FLASH>) -> StorageFlash {
    Flash::new(flash, Irqs)
}

/// The whole flash, as the store reaches it (it only ever touches
/// [`storage_range`]), erased in [`STORAGE_SECTOR_SIZE`] sectors.
#[cfg(feature = "stm32l475vg")]
pub struct StorageFlash(Flash<'static, Async>);

/// The flash driver.
#[cfg(feature = "stm32l475vg")]
pub fn storage_flash(flash: Peri<'static, peripherals::FLASH>) -> StorageFlash {
    StorageFlash(Flash::new(flash, Irqs))
}

#[cfg(feature = "stm32l475vg")]
mod sectors {
    use super::StorageFlash;
    use crate::flash_map::STORAGE_SECTOR_SIZE;
    use embassy_stm32::flash::Error;
    use embedded_storage_async::nor_flash::{ErrorType, NorFlash, ReadNorFlash};

    impl ErrorType for StorageFlash {
        type Error = Error;
    }

    impl ReadNorFlash for StorageFlash {
        const READ_SIZE: usize = 1;

        async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Error> {
            self.0.read(offset, bytes).await
        }

        fn capacity(&self) -> usize {
            self.0.capacity()
        }
    }

    impl NorFlash for StorageFlash {
        const WRITE_SIZE: usize = embassy_stm32::flash::WRITE_SIZE;
        const ERASE_SIZE: usize = STORAGE_SECTOR_SIZE as usize;

        async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Error> {
            self.0.write(offset, bytes).await
        }

        /// Erases every page of the range, one after the other.
        async fn erase(&mut self, from: u32, to: u32) -> Result<(), Error> {
            self.0.erase(from, to).await
        }
    }
}

/// The storage sectors, as offsets from the flash base.
pub fn storage_range() -> Range<u32> {
    STORAGE_OFFSET..STORAGE_OFFSET + STORAGE_SECTORS * STORAGE_SECTOR_SIZE
}
