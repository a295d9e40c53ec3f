//! Finishing a sector erase that a power cut interrupted, before
//! sequential-storage reads the pages.
//!
//! sequential-storage 8 reads a page's state from its first and last byte
//! (start and close markers) and assumes that an interrupted erase is seen
//! as "start erased, close still written", which it repairs by erasing the
//! page again (its own test flash erases in address order). The STM32F4
//! promises no order: a cut erase leaves the sector's content undefined, so
//! the page can read as open with garbage in it, or as open for writing, or
//! as closed. Its repair then may erase the page that holds the only
//! complete copies (taking the garbage page for the intact source of an
//! unfinished copy), or read the garbage page as the one in use and find
//! nothing. Measured without this step: 56 of 100 such cuts (the erase of
//! a page change, `power_fail_tests`' undefined sectors) ended with records
//! lost or unreadable; with it, none (docs/decisions.md).
//!
//! Before every operation that may erase, the store runs [`recover`] on its
//! two pages, which uses only what the flash shows:
//!
//! 1. A page whose markers read open must be blank: only an erase leaves
//!    both markers erased, and the store never reads an open page, so a
//!    page that reads open but is not blank is a cut erase, erased again
//!    (nothing it holds is ever read).
//! 2. Both pages in use happens in a two-page store only in a change of
//!    page: the records still current were being copied from the full page
//!    to the other, which is then erased; a cut fell in the copy or in that
//!    erase (or in the erase of a repair). The keys each page holds a valid
//!    record of (CRC-checked, read with sequential-storage's own reader)
//!    tell which page has everything: a copy only ever holds keys of its
//!    source, and a cut erase only loses records. So a page whose keys are
//!    a strict subset of the other's (an unfinished copy, or a source whose
//!    erase was cut) is erased: the other holds every current record. With
//!    the same keys on both, the copy was complete: the page with more
//!    records is the old full page and is erased (the copy holds one record
//!    per key). Otherwise the pages are left to sequential-storage.
//!
//! What is left (docs/persistence.md): a cut erase that damaged so few
//! cells that the damaged page still holds a valid record of every key.

use core::ops::Range;

use embedded_storage_async::nor_flash::{ErrorType, NorFlash, NorFlashErrorKind, ReadNorFlash};
use sequential_storage::cache::Cache;
use sequential_storage::map::{MapConfig, MapStorage};

/// sequential-storage's marker rule: a marker byte with at least 4 of its
/// 8 bits cleared is written.
fn marked(bytes: &[u8]) -> bool {
    bytes.iter().map(|b| b.count_zeros()).sum::<u32>() >= 4
}

/// Which keys (one byte each) a page holds a valid record of.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Keys([u64; 4]);

impl Keys {
    fn insert(&mut self, key: u8) {
        if let Some(word) = self.0.get_mut(usize::from(key / 64)) {
            *word |= 1 << (key % 64);
        }
    }

    fn is_subset(&self, other: &Keys) -> bool {
        self.0.iter().zip(other.0).all(|(a, b)| a & !b == 0)
    }
}

/// One page of a flash shown as a two-page flash whose second page is
/// blank, read-only: sequential-storage's reader lists the page's records
/// and can change nothing (a repair it tries fails).
struct PageView<'f, F> {
    flash: &'f mut F,
    page: u32,
}

impl<F: NorFlash> ErrorType for PageView<'_, F> {
    type Error = NorFlashErrorKind;
}

impl<F: NorFlash> ReadNorFlash for PageView<'_, F> {
    const READ_SIZE: usize = F::READ_SIZE;

    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        if (offset as usize) < F::ERASE_SIZE {
            let at = self
                .page
                .checked_add(offset)
                .ok_or(NorFlashErrorKind::OutOfBounds)?;
            self.flash
                .read(at, bytes)
                .await
                .map_err(|_| NorFlashErrorKind::Other)
        } else {
            bytes.fill(0xFF);
            Ok(())
        }
    }

    fn capacity(&self) -> usize {
        2 * F::ERASE_SIZE
    }
}

impl<F: NorFlash> NorFlash for PageView<'_, F> {
    const WRITE_SIZE: usize = F::WRITE_SIZE;
    const ERASE_SIZE: usize = F::ERASE_SIZE;

    async fn erase(&mut self, _: u32, _: u32) -> Result<(), Self::Error> {
        Err(NorFlashErrorKind::Other)
    }

    async fn write(&mut self, _: u32, _: &[u8]) -> Result<(), Self::Error> {
        Err(NorFlashErrorKind::Other)
    }
}

/// The keys `page` holds valid records of and the number of those records,
/// or `None` if sequential-storage cannot read it as a page in use.
async fn keys<F: NorFlash>(flash: &mut F, page: u32, buffer: &mut [u8]) -> Option<(Keys, u32)> {
    let view = PageView { flash, page };
    let config = MapConfig::try_new(0..2 * F::ERASE_SIZE as u32).ok()?;
    let mut map = MapStorage::<u8, _, _>::new(view, config, Cache::new_uncached());
    let mut items = map.fetch_all_items(buffer).await.ok()?;
    let (mut keys, mut records) = (Keys::default(), 0u32);
    while let Some((key, _)) = items.next::<&[u8]>(buffer).await.ok()? {
        keys.insert(key);
        records = records.saturating_add(1);
    }
    Some((keys, records))
}

/// Whether a page reads as open (neither marker written).
async fn reads_open<F: NorFlash>(
    flash: &mut F,
    page: u32,
    buffer: &mut [u8],
) -> Result<bool, F::Error> {
    let n = F::READ_SIZE;
    let last = page + F::ERASE_SIZE as u32 - n as u32;
    let Some(probe) = buffer.get_mut(..n) else {
        return Ok(false);
    };
    flash.read(page, probe).await?;
    let start = marked(probe);
    flash.read(last, probe).await?;
    Ok(!start && !marked(probe))
}

async fn is_blank<F: NorFlash>(
    flash: &mut F,
    page: u32,
    buffer: &mut [u8],
) -> Result<bool, F::Error> {
    let chunk = buffer.len() - buffer.len() % F::READ_SIZE.max(1);
    let mut at = page;
    let end = page + F::ERASE_SIZE as u32;
    while at < end && chunk > 0 {
        let n = chunk.min((end - at) as usize);
        let Some(part) = buffer.get_mut(..n) else {
            return Ok(false);
        };
        flash.read(at, part).await?;
        if part.iter().any(|&b| b != 0xFF) {
            return Ok(false);
        }
        at += n as u32;
    }
    Ok(true)
}

/// Finishes an interrupted erase on a store of two pages in `range` (see
/// the module documentation); a range of another size is left alone.
/// `buffer` is the store's.
pub(super) async fn recover<F: NorFlash>(
    flash: &mut F,
    range: Range<u32>,
    buffer: &mut [u8],
) -> Result<(), F::Error> {
    let page = F::ERASE_SIZE as u32;
    if range.end.checked_sub(range.start) != page.checked_mul(2) {
        return Ok(());
    }
    let pages = [range.start, range.start + page];
    let mut in_use = 0;
    for &p in &pages {
        if !reads_open(flash, p, buffer).await? {
            in_use += 1;
        } else if !is_blank(flash, p, buffer).await? {
            flash.erase(p, p + page).await?;
        }
    }
    if in_use < 2 {
        return Ok(());
    }
    let (Some((keys_0, records_0)), Some((keys_1, records_1))) = (
        keys(flash, pages[0], buffer).await,
        keys(flash, pages[1], buffer).await,
    ) else {
        return Ok(());
    };
    let redundant = match (keys_0.is_subset(&keys_1), keys_1.is_subset(&keys_0)) {
        (true, false) => pages[0],
        (false, true) => pages[1],
        (true, true) if records_0 > records_1 => pages[0],
        (true, true) if records_1 > records_0 => pages[1],
        _ => return Ok(()),
    };
    flash.erase(redundant, redundant + page).await
}
