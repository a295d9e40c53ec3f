//! A NOR-flash wrapper that lets the firmware choose when a sector may be
//! erased.
//!
//! On the STM32F4 (single bank) erasing a 128 KiB sector stalls every flash
//! read for 1-2 s, the step tick's code included, and the mount stops
//! tracking. sequential-storage erases inside a save, at the save that
//! fills a page: it closes the full page (writes the page's last word),
//! opens the next, copies the records still current into it and erases the
//! oldest page. It has no mode that refuses to erase, so this wrapper makes
//! one: with [`Erase::Defer`] it refuses both an erase and a write to the
//! last word of a page (the close marker, the first step of a page change).
//! A save that would change page therefore fails before it has written
//! anything, and the previous record stays current. Refusing the close
//! marker rather than only the erase matters: refused at the erase, the
//! store would be left in the middle of a copy, which its repair finishes by
//! erasing the new page once more (an extra erase cycle per deferred save).
//!
//! Refusing is conservative: a page change on a page never used before
//! needs no erase, yet is refused too.

use embedded_storage_async::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};

/// Whether an operation may erase a sector.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Erase {
    /// Erases allowed: at boot, at park, on command (the mount is not
    /// tracking, or the user asked).
    Allow,
    /// No erase: the operation fails with [`GateError::EraseDeferred`]
    /// before changing page, leaving the flash as it was.
    Defer,
}

/// A flash error, or an erase the gate refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GateError<E> {
    /// The operation would have changed page (and so may have erased a
    /// sector) while erases were deferred.
    EraseDeferred,
    /// The flash's own error.
    Flash(E),
}

impl<E: NorFlashError> NorFlashError for GateError<E> {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            GateError::EraseDeferred => NorFlashErrorKind::Other,
            GateError::Flash(e) => e.kind(),
        }
    }
}

/// `flash`, with erases allowed or deferred (see the module documentation).
#[derive(Debug)]
pub struct EraseGate<F> {
    flash: F,
    erase: Erase,
}

impl<F: NorFlash> EraseGate<F> {
    pub fn new(flash: F, erase: Erase) -> Self {
        EraseGate { flash, erase }
    }

    pub fn into_inner(self) -> F {
        self.flash
    }

    /// Whether a write of `len` bytes at `offset` reaches the last word of
    /// the page it starts in (the page's close marker), or beyond it.
    fn reaches_page_end(offset: u32, len: usize) -> bool {
        let (offset, len) = (u64::from(offset), len as u64);
        let page = F::ERASE_SIZE as u64;
        let Some(page_end) = offset.checked_div(page).map(|index| (index + 1) * page) else {
            // A flash without pages: nothing can be known, refuse.
            return true;
        };
        len > 0 && offset + len > page_end.saturating_sub(F::WRITE_SIZE as u64)
    }
}

impl<F: ErrorType> ErrorType for EraseGate<F> {
    type Error = GateError<F::Error>;
}

impl<F: NorFlash> ReadNorFlash for EraseGate<F> {
    const READ_SIZE: usize = F::READ_SIZE;

    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        self.flash
            .read(offset, bytes)
            .await
            .map_err(GateError::Flash)
    }

    fn capacity(&self) -> usize {
        self.flash.capacity()
    }
}

impl<F: NorFlash> NorFlash for EraseGate<F> {
    const WRITE_SIZE: usize = F::WRITE_SIZE;
    const ERASE_SIZE: usize = F::ERASE_SIZE;

    async fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        if self.erase == Erase::Defer {
            return Err(GateError::EraseDeferred);
        }
        self.flash.erase(from, to).await.map_err(GateError::Flash)
    }

    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        if self.erase == Erase::Defer && Self::reaches_page_end(offset, bytes.len()) {
            return Err(GateError::EraseDeferred);
        }
        self.flash
            .write(offset, bytes)
            .await
            .map_err(GateError::Flash)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::persist::sim_flash::SimFlash;
    use embassy_futures::block_on;

    type Gate<'a> = EraseGate<SimFlash<'a, 64>>;

    #[test]
    fn deferred_refuses_erases_and_close_markers_and_nothing_else() {
        let mut mem = [0xFFu8; 128];
        let mut gate = Gate::new(SimFlash::new(&mut mem), Erase::Defer);
        block_on(async {
            // Anywhere before a page's last word: written.
            for (offset, len) in [(0, 4), (4, 56), (56, 4), (64, 60)] {
                assert_eq!(gate.write(offset, &[0u8; 60][..len]).await, Ok(()));
            }
            // The last word of either page, or across the boundary: refused.
            for (offset, len) in [(60, 4), (56, 8), (124, 4), (60, 8)] {
                let r = gate.write(offset, &[0u8; 8][..len]).await;
                assert_eq!(r, Err(GateError::EraseDeferred), "{offset}+{len}");
            }
            assert_eq!(gate.erase(0, 64).await, Err(GateError::EraseDeferred));
        });
        // Nothing refused reached the flash: the last words are still erased.
        assert_eq!(gate.into_inner().erases(), 0);
        assert_eq!(mem[60..64], [0xFF; 4]);
        assert_eq!(mem[124..128], [0xFF; 4]);
        assert_eq!(mem[..60], [0; 60]);
    }

    #[test]
    fn allowed_passes_everything_through() {
        let mut mem = [0u8; 128];
        let mut gate = Gate::new(SimFlash::new(&mut mem), Erase::Allow);
        block_on(async {
            assert_eq!(gate.erase(0, 128).await, Ok(()));
            assert_eq!(gate.write(60, &[0x12, 0x34, 0x56, 0x78]).await, Ok(()));
        });
        assert_eq!(gate.into_inner().erases(), 2);
        assert_eq!(mem[60..64], [0x12, 0x34, 0x56, 0x78]);
        assert_eq!(mem[64..], [0xFF; 64]);
    }
}
