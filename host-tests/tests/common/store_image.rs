//! A store image for the emulated B-L475E-IOT01A (tests/board.rs): the
//! firmware's own `Store` over the L475's storage range, holding a model
//! that `st4_sim`'s rig learned under the firmware's default configuration
//! and the worm index's pass saved with it, so that the board's restores
//! at boot and at the index's first pass find a model to take back. QEMU's
//! model of the flash cannot erase or program: the image is loaded with
//! the ELF (`-device loader`), as a board flashed with it would hold it.

use std::ops::Range;

use embassy_futures::block_on;
use embedded_storage_async::nor_flash::{ErrorType, NorFlash, NorFlashErrorKind, ReadNorFlash};
use host_tests::cases::{self, Case};
use host_tests::st4_sim::{Firmware, Rig};
use mkgp_mount::mount::config::MountConfig;
use mkgp_mount::mount::learner::{RECORD_FORMAT, RECORD_MAX};
use mkgp_mount::persist::{Erase, Store};

/// The L475's storage as offsets from the flash base, and its "sector" of
/// 64 pages (hal/src/flash_map.rs).
const STORAGE: Range<u32> = 0x8_0000..0xC_0000;
const SECTOR: usize = 128 * 1024;
/// The L475's flash programs 64 bits at a time (embassy-stm32's
/// `flash::WRITE_SIZE` there): the store's records are aligned to it.
const WRITE_SIZE: usize = 8;
/// Where the image goes in the emulated flash (its first byte's address).
const IMAGE_ADDRESS: u32 = 0x0800_0000 + STORAGE.start;

/// NOR flash in RAM, erased at first: a program clears bits.
struct RamFlash(Vec<u8>);

impl ErrorType for RamFlash {
    type Error = NorFlashErrorKind;
}

impl ReadNorFlash for RamFlash {
    const READ_SIZE: usize = 1;

    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        let at = offset as usize;
        let from = self
            .0
            .get(at..at + bytes.len())
            .ok_or(NorFlashErrorKind::OutOfBounds)?;
        bytes.copy_from_slice(from);
        Ok(())
    }

    fn capacity(&self) -> usize {
        self.0.len()
    }
}

impl NorFlash for RamFlash {
    const WRITE_SIZE: usize = WRITE_SIZE;
    const ERASE_SIZE: usize = SECTOR;

    async fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        let span = self
            .0
            .get_mut(from as usize..to as usize)
            .ok_or(NorFlashErrorKind::OutOfBounds)?;
        span.fill(0xFF);
        Ok(())
    }

    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        let at = offset as usize;
        let to = self
            .0
            .get_mut(at..at + bytes.len())
            .ok_or(NorFlashErrorKind::OutOfBounds)?;
        for (old, new) in to.iter_mut().zip(bytes) {
            *old &= new;
        }
        Ok(())
    }
}

/// A two-stage gear in `st4_sim`'s terms: the default configuration's
/// worm (478.7 s) at 9 px, a 155 s stage at 4.5 px and a slow drift. The
/// long run's guider corrects it as the store image learned it.
pub fn gear() -> Case {
    let worm_s = MountConfig::default().worm_period_s;
    let csv = format!(
        "case,component,period_s,amplitude_px,phase_rad,drift_px_per_s
board,worm,{worm_s},9.0,0,
board,stage2,155,4.5,0,
board,drift,,,,0.0008
"
    );
    cases::parse(&csv, "store_image.rs".as_ref())
        .expect("the gear parses")
        .remove(0)
}

/// The storage range after `learn_s` of guiding on [`gear`] (noise
/// 0.3 px), as an ELF file for QEMU's `-device loader,file=` (a raw file
/// there may be no larger than the machine's RAM size, which this machine
/// leaves at 0): the model saved with the worm index's pass at RA step
/// `index_pass`, as the board's learning task saves them.
pub fn learned_model(learn_s: f64, index_pass: i64) -> Vec<u8> {
    let case = gear();
    let mut rig = Rig::with_mount(&case, Firmware::Mkgp, 0.3, 1, MountConfig::default());
    rig.run_until((learn_s * 1e6) as u64);
    let mut snapshot = vec![0; RECORD_MAX];
    let learner = rig.mkgp_learner().expect("the MKGP firmware has a learner");
    let n = learner.snapshot(&mut snapshot).expect("a snapshot");
    let mut store = Store::new(RamFlash(vec![0xFF; STORAGE.end as usize]), STORAGE);
    block_on(store.save_model(RECORD_FORMAT, &snapshot[..n], Erase::Allow)).expect("saved");
    block_on(store.save_index(index_pass, Erase::Allow)).expect("saved");
    elf(
        IMAGE_ADDRESS,
        &store.into_flash().0[STORAGE.start as usize..],
    )
}

/// A 32-bit little-endian ARM ELF file whose one loadable segment puts
/// `bytes` at `address`.
fn elf(address: u32, bytes: &[u8]) -> Vec<u8> {
    const HEADER: u32 = 52;
    const SEGMENT: u32 = 32;
    let len = u32::try_from(bytes.len()).expect("under 4 GiB");
    let mut f = vec![0x7f, b'E', b'L', b'F', 1, 1, 1];
    f.resize(16, 0);
    let u16s = |f: &mut Vec<u8>, v: &[u16]| v.iter().for_each(|v| f.extend(v.to_le_bytes()));
    let u32s = |f: &mut Vec<u8>, v: &[u32]| v.iter().for_each(|v| f.extend(v.to_le_bytes()));
    // Executable, ARM, version 1; entry 0, segments after this header, no
    // sections, flags: EABI 5.
    u16s(&mut f, &[2, 40]);
    u32s(&mut f, &[1, 0, HEADER, 0, 0x0500_0000]);
    u16s(&mut f, &[HEADER as u16, SEGMENT as u16, 1, 40, 0, 0]);
    // PT_LOAD: its bytes right after this entry, at `address` physical and
    // virtual, read-only.
    u32s(
        &mut f,
        &[1, HEADER + SEGMENT, address, address, len, len, 4, 4],
    );
    f.extend_from_slice(bytes);
    f
}
