//! The flash the `persist` store keeps its records in: embassy-stm32's
//! flash driver (interrupt-driven writes and erases) and the storage range
//! of [`crate::flash_map`], as offsets from the flash base the driver takes.

use core::ops::Range;

use embassy_stm32::flash::{Async, Flash, InterruptHandler};
use embassy_stm32::{bind_interrupts, peripherals, Peri};

use crate::flash_map::{STORAGE_OFFSET, STORAGE_SECTORS, STORAGE_SECTOR_SIZE};

bind_interrupts!(struct Irqs {
    FLASH => InterruptHandler;
});

/// The whole flash, as the store reaches it (it only ever touches
/// [`storage_range`]).
pub type StorageFlash = Flash<'static, Async>;

/// The flash driver.
pub fn storage_flash(flash: Peri<'static, peripherals::FLASH>) -> StorageFlash {
    Flash::new(flash, Irqs)
}

/// The storage sectors, as offsets from the flash base.
pub fn storage_range() -> Range<u32> {
    STORAGE_OFFSET..STORAGE_OFFSET + STORAGE_SECTORS * STORAGE_SECTOR_SIZE
}
