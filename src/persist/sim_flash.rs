//! A simulated NOR flash with the STM32F4's semantics, whose power can be
//! cut at any operation (feature `testing`, and the library's unit tests;
//! never in the firmware).
//!
//! - an erase sets a whole sector to `0xFF`; a program only clears bits (a
//!   word programmed twice holds the AND of both), one 32-bit word at a
//!   time, as the F4 programs with a 32-bit parallelism;
//! - the operations counted, and so the places a cut can fall, are the
//!   word programs and the sector erases (a read changes nothing);
//! - a cut at operation N: operations before N are done, operation N is
//!   left half done, and every later call fails with
//!   [`SimError::PowerCut`]. A word cut while being programmed has cleared
//!   only some of the bits it was to clear (drawn from a seeded generator,
//!   so a test is repeatable). A sector cut while being erased is left as
//!   [`EraseCut`] says: erased in address order up to a word (what
//!   sequential-storage's own tests assume), or with every word erased,
//!   untouched or only partly set (what the STM32F4's reference manual
//!   allows: an interrupted erase leaves the sector's content undefined).
//!
//! The memory is borrowed, so a test "reboots" by building a new flash (and
//! a new store) over the same bytes.

use crate::testing::SplitMix64;
use embedded_storage_async::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};

/// Bytes programmed at once.
pub const WORD: usize = 4;

/// Why an operation failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SimError {
    /// The power was cut (at this operation or before).
    PowerCut,
    /// An offset or length not a multiple of the word (program) or of the
    /// sector (erase).
    NotAligned,
    /// Outside the memory.
    OutOfBounds,
}

impl NorFlashError for SimError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            SimError::PowerCut => NorFlashErrorKind::Other,
            SimError::NotAligned => NorFlashErrorKind::NotAligned,
            SimError::OutOfBounds => NorFlashErrorKind::OutOfBounds,
        }
    }
}

/// What a cut erase leaves.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EraseCut {
    /// The words from the sector's start up to a random one erased, the
    /// rest untouched: the page's first word (sequential-storage's start
    /// marker) always erased first, its last word last.
    InOrder,
    /// Each word erased, untouched or with some of its bits set, at random.
    Undefined,
}

/// A NOR flash of `mem.len()` bytes in sectors of `SECTOR` bytes.
#[derive(Debug)]
pub struct SimFlash<'a, const SECTOR: usize> {
    mem: &'a mut [u8],
    /// Word programs and sector erases done so far.
    ops: u64,
    /// Sector erases done so far.
    erases: u64,
    /// The operation the power is cut at, if any.
    cut_at: Option<u64>,
    powered: bool,
    garbage: SplitMix64,
    erase_cut: EraseCut,
}

impl<'a, const SECTOR: usize> SimFlash<'a, SECTOR> {
    /// A flash over `mem`, as it is (a new part is all `0xFF`), that never
    /// loses power.
    pub fn new(mem: &'a mut [u8]) -> Self {
        SimFlash {
            mem,
            ops: 0,
            erases: 0,
            cut_at: None,
            powered: true,
            garbage: SplitMix64::new(0),
            erase_cut: EraseCut::InOrder,
        }
    }

    /// What a cut erase leaves (default [`EraseCut::InOrder`]).
    pub fn with_erase_cut(mut self, erase_cut: EraseCut) -> Self {
        self.erase_cut = erase_cut;
        self
    }

    /// Cut the power at operation `n` from now (0: the next one), leaving
    /// garbage drawn with `seed`.
    pub fn cut_after(&mut self, n: u64, seed: u64) {
        self.cut_at = Some(self.ops.saturating_add(n));
        self.garbage = SplitMix64::new(seed);
    }

    /// Word programs and sector erases done (the one a cut fell on
    /// included).
    pub fn ops(&self) -> u64 {
        self.ops
    }

    /// Sector erases done (a cut one included).
    pub fn erases(&self) -> u64 {
        self.erases
    }

    /// Whether the power has been cut.
    pub fn is_cut(&self) -> bool {
        !self.powered
    }

    /// Counts one operation; false if the power is cut at it.
    fn survives_op(&mut self) -> bool {
        let cut = self.cut_at == Some(self.ops);
        self.ops += 1;
        if cut {
            self.powered = false;
        }
        !cut
    }

    /// The bytes of `[offset, offset + len)`, if in the memory.
    fn span(&mut self, offset: u32, len: usize) -> Result<&mut [u8], SimError> {
        let start = offset as usize;
        let end = start.checked_add(len).ok_or(SimError::OutOfBounds)?;
        self.mem.get_mut(start..end).ok_or(SimError::OutOfBounds)
    }
}

impl<const SECTOR: usize> ErrorType for SimFlash<'_, SECTOR> {
    type Error = SimError;
}

impl<const SECTOR: usize> ReadNorFlash for SimFlash<'_, SECTOR> {
    const READ_SIZE: usize = 1;

    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), SimError> {
        if !self.powered {
            return Err(SimError::PowerCut);
        }
        bytes.copy_from_slice(self.span(offset, bytes.len())?);
        Ok(())
    }

    fn capacity(&self) -> usize {
        self.mem.len()
    }
}

impl<const SECTOR: usize> NorFlash for SimFlash<'_, SECTOR> {
    const WRITE_SIZE: usize = WORD;
    const ERASE_SIZE: usize = SECTOR;

    async fn erase(&mut self, from: u32, to: u32) -> Result<(), SimError> {
        if !self.powered {
            return Err(SimError::PowerCut);
        }
        let (from, to) = (from as usize, to as usize);
        if !from.is_multiple_of(SECTOR) || !to.is_multiple_of(SECTOR) {
            return Err(SimError::NotAligned);
        }
        let len = to.checked_sub(from).ok_or(SimError::OutOfBounds)?;
        self.span(from as u32, len)?;
        for sector in (from..to).step_by(SECTOR) {
            self.erases += 1;
            let done = self.survives_op();
            let mut garbage = self.garbage.clone();
            let erase_cut = self.erase_cut;
            let words = self.span(sector as u32, SECTOR)?.as_chunks_mut::<WORD>().0;
            // Cut in order: the words before this one are erased.
            let reached = garbage.below(words.len() as u64 + 1) as usize;
            for (i, word) in words.iter_mut().enumerate() {
                let old = u32::from_le_bytes(*word);
                let new = match (done, erase_cut) {
                    (true, _) => u32::MAX,
                    (false, EraseCut::InOrder) if i < reached => u32::MAX,
                    (false, EraseCut::InOrder) => old,
                    (false, EraseCut::Undefined) => match garbage.below(3) {
                        0 => u32::MAX,
                        1 => old,
                        _ => old | garbage.next_u64() as u32,
                    },
                };
                *word = new.to_le_bytes();
            }
            if !done {
                return Err(SimError::PowerCut);
            }
        }
        Ok(())
    }

    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), SimError> {
        if !self.powered {
            return Err(SimError::PowerCut);
        }
        if !(offset as usize).is_multiple_of(WORD) || !bytes.len().is_multiple_of(WORD) {
            return Err(SimError::NotAligned);
        }
        self.span(offset, bytes.len())?;
        let words = bytes.as_chunks::<WORD>().0;
        for (i, new) in words.iter().enumerate() {
            let done = self.survives_op();
            let mut garbage = self.garbage.clone();
            let at = offset as usize + i * WORD;
            let word = self
                .span(at as u32, WORD)?
                .first_chunk_mut::<WORD>()
                .ok_or(SimError::OutOfBounds)?;
            let (old, new) = (u32::from_le_bytes(*word), u32::from_le_bytes(*new));
            let to_clear = old & !new;
            let cleared = if done {
                to_clear
            } else {
                to_clear & garbage.next_u64() as u32
            };
            *word = (old & !cleared).to_le_bytes();
            if !done {
                return Err(SimError::PowerCut);
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use embassy_futures::block_on;

    type Flash<'a> = SimFlash<'a, 16>;

    #[test]
    fn programs_clear_bits_and_erases_set_them() {
        let mut mem = [0xFFu8; 32];
        let mut f = Flash::new(&mut mem);
        block_on(async {
            f.write(4, &[0x0F, 0xF0, 0x00, 0xFF]).await.unwrap();
            // A second program only clears more bits.
            f.write(4, &[0xFF, 0x0F, 0xFF, 0xF0]).await.unwrap();
            let mut word = [0; 4];
            f.read(4, &mut word).await.unwrap();
            assert_eq!(word, [0x0F, 0x00, 0x00, 0xF0]);
            assert_eq!(f.write(2, &[0; 4]).await, Err(SimError::NotAligned));
            assert_eq!(f.write(4, &[0; 3]).await, Err(SimError::NotAligned));
            assert_eq!(f.write(32, &[0; 4]).await, Err(SimError::OutOfBounds));
            assert_eq!(f.erase(0, 8).await, Err(SimError::NotAligned));
            assert_eq!(f.erase(0, 48).await, Err(SimError::OutOfBounds));
            f.erase(0, 16).await.unwrap();
        });
        assert_eq!((f.ops(), f.erases()), (3, 1));
        assert_eq!(mem[4..8], [0xFF; 4]);
    }

    #[test]
    fn a_cut_program_clears_only_some_bits_and_stops_everything() {
        let mut partial = 0;
        for seed in 0..100 {
            let mut mem = [0xFFu8; 32];
            let mut f = Flash::new(&mut mem);
            f.cut_after(1, seed);
            block_on(async {
                // Word 0 done, word 1 cut, word 2 never programmed.
                let r = f.write(0, &[0u8; 12]).await;
                assert_eq!(r, Err(SimError::PowerCut));
                assert!(f.is_cut());
                assert_eq!(f.read(0, &mut [0; 4]).await, Err(SimError::PowerCut));
                assert_eq!(f.write(16, &[0; 4]).await, Err(SimError::PowerCut));
            });
            assert_eq!(mem[..4], [0; 4]);
            assert_eq!(mem[8..], [0xFF; 24]);
            if mem[4..8] != [0; 4] && mem[4..8] != [0xFF; 4] {
                partial += 1;
            }
        }
        assert!(partial > 90, "{partial} of 100 cut words half-programmed");
    }

    #[test]
    fn a_cut_erase_leaves_the_sector_neither_old_nor_erased() {
        for erase_cut in [EraseCut::InOrder, EraseCut::Undefined] {
            let (mut prefix, mut mixed) = (0, 0);
            for seed in 0..100 {
                let mut mem = [0u8; 32];
                let mut f = Flash::new(&mut mem).with_erase_cut(erase_cut);
                f.cut_after(0, seed);
                assert_eq!(block_on(f.erase(0, 32)), Err(SimError::PowerCut));
                assert_eq!(f.erases(), 1);
                // The second sector untouched.
                assert_eq!(mem[16..], [0; 16]);
                let erased = mem[..16].iter().take_while(|&&b| b == 0xFF).count();
                if mem[erased..16].iter().all(|&b| b == 0) {
                    prefix += 1;
                } else {
                    mixed += 1;
                }
            }
            match erase_cut {
                EraseCut::InOrder => assert_eq!(prefix, 100),
                EraseCut::Undefined => assert!(mixed > 50, "{mixed} mixed"),
            }
        }
    }
}
