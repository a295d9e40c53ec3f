//! Where code ends and storage begins in each chip's flash: the constants
//! the flash driver hands to the `persist` store, and the same map as the
//! comment in `memory.x` (which cannot read these).
//!
//! Code is linked into the first 256 KiB from [`FLASH_BASE`] on every chip
//! (sectors 0-5 of the F4s). Storage is two 128 KiB sectors: the store
//! writes one while the other holds the records it still needs, so it
//! always has a whole sector to erase without losing the last complete
//! save. The three F4s are single-bank: erasing a storage sector stalls
//! every flash read, code included, for 1-2 s (docs/persistence.md says how
//! the store defers it). The L475's flash erases in 2 KiB pages: its
//! "sector" is 64 of them, erased one after the other, in bank 2, so that
//! code in bank 1 runs on while they erase.
//!
//! | chip | storage sectors | addresses |
//! |---|---|---|
//! | STM32F411CE | 6-7 | 0x0804_0000..0x0808_0000 |
//! | STM32F446RE | 6-7 | 0x0804_0000..0x0808_0000 |
//! | STM32F407VG | 10-11 | 0x080C_0000..0x0810_0000 |
//! | STM32L475VG | pages 256-383 (bank 2's first 256 KiB) | 0x0808_0000..0x080C_0000 |
//!
//! Addresses are absolute; embassy-stm32's flash driver takes offsets from
//! [`FLASH_BASE`] ([`STORAGE_OFFSET`]).

/// The first byte of flash (and of the code region).
pub const FLASH_BASE: u32 = 0x0800_0000;

/// The end of the code region: on the F4s sectors 0-3 (16 KiB each), 4
/// (64 KiB) and 5 (128 KiB), 256 KiB in all. `memory.x` gives FLASH this
/// length.
pub const CODE_END: u32 = FLASH_BASE + 256 * 1024;

/// Size of each storage sector (the sectors from 5 up are 128 KiB on the
/// F4s; 64 pages on the L475): the store's page, the unit of one erase.
pub const STORAGE_SECTOR_SIZE: u32 = 128 * 1024;

/// Number of storage sectors.
pub const STORAGE_SECTORS: u32 = 2;

/// First byte of storage: sector 6 (0x0804_0000) on the F411 and F446, the
/// top two of the F407's twelve sectors (sector 10, 0x080C_0000).
#[cfg(any(feature = "stm32f411ce", feature = "stm32f446re"))]
pub const STORAGE_START: u32 = 0x0804_0000;
/// First byte of storage: sector 6 (0x0804_0000) on the F411 and F446, the
/// top two of the F407's twelve sectors (sector 10, 0x080C_0000).
#[cfg(feature = "stm32f407vg")]
pub const STORAGE_START: u32 = 0x080C_0000;
/// First byte of storage: the start of bank 2 (page 256) on the L475.
#[cfg(feature = "stm32l475vg")]
pub const STORAGE_START: u32 = 0x0808_0000;

/// One past the last byte of storage (the end of flash on the F4s).
pub const STORAGE_END: u32 = STORAGE_START + STORAGE_SECTORS * STORAGE_SECTOR_SIZE;

/// [`STORAGE_START`] as an offset from [`FLASH_BASE`], as the flash driver
/// takes it.
pub const STORAGE_OFFSET: u32 = STORAGE_START - FLASH_BASE;

// The map holds together: code and storage apart, storage on sector
// boundaries (and so erasable without touching anything else).
const _: () = assert!(CODE_END <= STORAGE_START);
const _: () = assert!((STORAGE_START - FLASH_BASE).is_multiple_of(STORAGE_SECTOR_SIZE));
