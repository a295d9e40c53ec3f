//! The store: the mount's records in a power-fail-safe key-value map
//! (sequential-storage's `MapStorage`) over a NOR flash range of at least
//! two erase pages, each record in a versioned [`Envelope`].
//!
//! Saves go through an [`EraseGate`]: the caller says whether the save may
//! erase a sector ([`Erase`]); a save that would need one while erases are
//! deferred fails with [`SaveError::EraseDeferred`] and changes nothing.
//! Loads may erase: a load finding what a power cut left half done (a
//! half-erased sector) repairs it first, so the firmware loads at boot,
//! before it tracks. Every operation that may erase first runs
//! `recovery::recover`, which finishes a sector erase a cut left
//! undefined before sequential-storage reads the pages.
//!
//! Every save is read back: a record written over bytes that were not
//! erased (bit rot, or what a cut erase left in the free space) fails its
//! CRC, and a load would return the previous one. A save whose record
//! reads back unlike what was written is written again after it, up to
//! [`SAVE_ATTEMPTS`] times, then reported as [`SaveError::Unverified`]:
//! never reported done when the next boot would not find it.
//!
//! The store keeps no state between calls besides its buffer and its
//! counters (the map is built per call, uncached), so it reads the flash
//! afresh each time: at most both pages, 256 KiB read and CRC-checked per
//! load, twice per save (the write and the read-back).

use core::ops::Range;

use embedded_storage_async::nor_flash::NorFlash;
use sequential_storage::cache::Cache;
use sequential_storage::map::{MapConfig, MapConfigError, MapStorage};

use super::config_record::{self, CONFIG_FORMAT};
use super::erase_gate::{Erase, EraseGate, GateError};
use super::park::{Park, PARK_FORMAT};
use super::record::{Envelope, ENVELOPE_LEN};
use super::recovery::recover;
use super::MODEL_RECORD_MAX;
use crate::mount::config::{ConfigError, Mount};

/// The key of each record in the map (one byte on flash). Keys other
/// firmware layouts wrote are carried along untouched.
#[repr(u8)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Slot {
    Config = 1,
    Model = 2,
    Park = 3,
    /// The RA step count of the worm index's last pass when the model was
    /// saved: with it the next boot's first pass gives the worm's phase.
    Index = 4,
}

/// Layout version of the index record (one `i64`, little-endian).
pub const INDEX_FORMAT: u16 = 1;

/// Bytes of a map key on flash.
const KEY_LEN: usize = 1;

/// The buffer sequential-storage serializes a record into and reads one
/// back into: key, envelope and the largest body, rounded up to 32 bytes
/// (the largest flash word it supports), 8224 bytes. This is the store's
/// RAM cost besides a few words.
pub const BUFFER_LEN: usize = (KEY_LEN + ENVELOPE_LEN + MODEL_RECORD_MAX).next_multiple_of(32);

/// Writes of one save before it is reported [`SaveError::Unverified`]. A
/// write that reads back wrong leaves a record that fails its CRC, and the
/// next write goes after it, past the bytes that spoilt it; three cover a
/// few spoilt words without filling the page with failed copies.
pub const SAVE_ATTEMPTS: u32 = 3;

crate::counters! {
    /// What the store's saves met, counted since it was opened.
    pub struct StoreCounters("store_") {
        /// Writes that read back unlike what was written, and were written
        /// again (or, the last, reported unverified).
        rewrites,
        /// Saves reported [`SaveError::Unverified`].
        unverified,
    }
}

/// The flash errors a store operation can meet: the flash's own, the gate's
/// refusal, or the map's (a corruption it could not repair, a full store).
pub type StoreError<E> = sequential_storage::Error<GateError<E>>;

/// Why a record could not be loaded. Every case but `Flash` leaves the
/// store usable; the caller falls back to its defaults.
#[derive(Debug)]
pub enum LoadError<E> {
    /// No record of this kind was ever saved (or the flash is new).
    NothingStored,
    /// The record was written in another layout (another firmware):
    /// refused, not misread.
    Format { found: u16, expected: u16 },
    /// The record has the expected format but not its length: written by a
    /// firmware that kept the version number while changing the layout.
    Malformed,
    /// The stored configuration decodes but does not validate: the field,
    /// its value and the rule, as at start-up.
    Invalid(ConfigError),
    /// The flash range does not fit the flash's pages (at least two whole
    /// erase pages).
    Geometry(MapConfigError),
    /// The flash or the map failed.
    Flash(StoreError<E>),
}

/// Why a record was not saved. The previous record of the kind is still the
/// one a load returns.
#[derive(Debug)]
pub enum SaveError<E> {
    /// The save would change page, which may erase a sector, and erases are
    /// deferred: save again with [`Erase::Allow`] when the mount can stop.
    EraseDeferred,
    /// A body longer than the record's limit ([`MODEL_RECORD_MAX`]).
    TooLarge { len: usize },
    /// Each of [`SAVE_ATTEMPTS`] writes read back unlike what was written
    /// (the flash holds bytes that were not erased where it wrote).
    Unverified,
    /// See [`LoadError::Geometry`].
    Geometry(MapConfigError),
    /// The flash or the map failed.
    Flash(StoreError<E>),
}

/// The flash's own error `e`, as the map reports one.
fn flash_error<E>(e: E) -> StoreError<E> {
    sequential_storage::Error::Storage {
        value: GateError::Flash(e),
    }
}

/// 4-byte aligned, as some flash drivers want the bytes they program.
#[repr(align(4))]
struct Buffer([u8; BUFFER_LEN]);

/// The mount's records on `flash`, in `range` (offsets as the flash takes
/// them; whole erase pages, at least two).
pub struct Store<F> {
    flash: F,
    range: Range<u32>,
    buffer: Buffer,
    counters: StoreCounters,
}

impl<F: NorFlash> Store<F> {
    /// Checks nothing yet: a range that does not fit the flash is reported
    /// by the first load or save ([`LoadError::Geometry`]).
    pub fn new(flash: F, range: Range<u32>) -> Self {
        Store {
            flash,
            range,
            buffer: Buffer([0; BUFFER_LEN]),
            counters: StoreCounters::default(),
        }
    }

    pub fn counters(&self) -> StoreCounters {
        self.counters
    }

    /// The flash back.
    pub fn into_flash(self) -> F {
        self.flash
    }

    /// The stored configuration, validated.
    pub async fn load_config(&mut self) -> Result<Mount, LoadError<F::Error>> {
        let body = self.load(Slot::Config, CONFIG_FORMAT).await?;
        let config = config_record::decode(body).ok_or(LoadError::Malformed)?;
        config.validate().map_err(LoadError::Invalid)
    }

    /// Saves a validated configuration.
    pub async fn save_config(
        &mut self,
        mount: &Mount,
        erase: Erase,
    ) -> Result<(), SaveError<F::Error>> {
        let body = config_record::encode(mount.config());
        self.save(Slot::Config, CONFIG_FORMAT, &body, erase).await
    }

    /// The stored model snapshot, if it was written in `format` (the
    /// snapshot code's own layout version).
    pub async fn load_model(&mut self, format: u16) -> Result<&[u8], LoadError<F::Error>> {
        self.load(Slot::Model, format).await
    }

    /// Saves a model snapshot of at most [`MODEL_RECORD_MAX`] bytes in
    /// layout `format`.
    pub async fn save_model(
        &mut self,
        format: u16,
        snapshot: &[u8],
        erase: Erase,
    ) -> Result<(), SaveError<F::Error>> {
        self.save(Slot::Model, format, snapshot, erase).await
    }

    /// The step counts saved at the last park; `NothingStored` if the
    /// mount was unparked since ([`Store::clear_park`]).
    pub async fn load_park(&mut self) -> Result<Park, LoadError<F::Error>> {
        match self.load(Slot::Park, PARK_FORMAT).await? {
            [] => Err(LoadError::NothingStored),
            body => Park::decode(body).ok_or(LoadError::Malformed),
        }
    }

    /// Saves the step counts at park.
    pub async fn save_park(&mut self, park: Park, erase: Erase) -> Result<(), SaveError<F::Error>> {
        self.save(Slot::Park, PARK_FORMAT, &park.encode(), erase)
            .await
    }

    /// Unparked: the saved counts no longer say where the worm is. Stored as
    /// an empty park record (the map removes nothing on a flash whose words
    /// are written once).
    pub async fn clear_park(&mut self, erase: Erase) -> Result<(), SaveError<F::Error>> {
        self.save(Slot::Park, PARK_FORMAT, &[], erase).await
    }

    /// The RA step count of the worm index's pass saved with the model.
    pub async fn load_index(&mut self) -> Result<i64, LoadError<F::Error>> {
        let body = self.load(Slot::Index, INDEX_FORMAT).await?;
        let bytes: [u8; 8] = body.try_into().map_err(|_| LoadError::Malformed)?;
        Ok(i64::from_le_bytes(bytes))
    }

    /// Saves the RA step count of the worm index's last pass (with the
    /// model it goes with).
    pub async fn save_index(
        &mut self,
        ra_steps: i64,
        erase: Erase,
    ) -> Result<(), SaveError<F::Error>> {
        self.save(Slot::Index, INDEX_FORMAT, &ra_steps.to_le_bytes(), erase)
            .await
    }

    /// The body of the newest complete record in `slot`, if its format is
    /// `format`.
    async fn load(&mut self, slot: Slot, format: u16) -> Result<&[u8], LoadError<F::Error>> {
        let config = MapConfig::try_new(self.range.clone()).map_err(LoadError::Geometry)?;
        recover(&mut self.flash, self.range.clone(), &mut self.buffer.0)
            .await
            .map_err(|e| LoadError::Flash(flash_error(e)))?;
        let gate = EraseGate::new(&mut self.flash, Erase::Allow);
        let mut map = MapStorage::<u8, _, _>::new(gate, config, Cache::new_uncached());
        let found = map
            .fetch_item::<Envelope>(&mut self.buffer.0, &(slot as u8))
            .await;
        match found {
            Ok(Some(e)) if e.format == format => Ok(e.body),
            Ok(Some(e)) => Err(LoadError::Format {
                found: e.format,
                expected: format,
            }),
            Ok(None) => Err(LoadError::NothingStored),
            // Too short for an envelope: no firmware of ours wrote it.
            Err(sequential_storage::Error::SerializationError(_)) => Err(LoadError::Malformed),
            Err(e) => Err(LoadError::Flash(e)),
        }
    }

    async fn save(
        &mut self,
        slot: Slot,
        format: u16,
        body: &[u8],
        erase: Erase,
    ) -> Result<(), SaveError<F::Error>> {
        if body.len() > MODEL_RECORD_MAX {
            return Err(SaveError::TooLarge { len: body.len() });
        }
        let config = MapConfig::try_new(self.range.clone()).map_err(SaveError::Geometry)?;
        if erase == Erase::Allow {
            recover(&mut self.flash, self.range.clone(), &mut self.buffer.0)
                .await
                .map_err(|e| SaveError::Flash(flash_error(e)))?;
        }
        let gate = EraseGate::new(&mut self.flash, erase);
        let mut map = MapStorage::<u8, _, _>::new(gate, config, Cache::new_uncached());
        let record = Envelope { format, body };
        for attempt in 1..=SAVE_ATTEMPTS {
            match map
                .store_item(&mut self.buffer.0, &(slot as u8), &record)
                .await
            {
                Ok(()) => {}
                Err(sequential_storage::Error::Storage {
                    value: GateError::EraseDeferred,
                    ..
                }) => return Err(SaveError::EraseDeferred),
                Err(e) => return Err(SaveError::Flash(e)),
            }
            let read_back = map
                .fetch_item::<Envelope>(&mut self.buffer.0, &(slot as u8))
                .await;
            match read_back {
                Ok(Some(found)) if found == record => return Ok(()),
                // The previous record, another, or none: this write is spoilt.
                Ok(_) | Err(sequential_storage::Error::SerializationError(_)) => {}
                Err(e) => return Err(SaveError::Flash(e)),
            }
            self.counters.rewrites = self.counters.rewrites.saturating_add(1);
            if attempt == SAVE_ATTEMPTS {
                self.counters.unverified = self.counters.unverified.saturating_add(1);
            }
        }
        Err(SaveError::Unverified)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mount::config::{Field, MountConfig};
    use crate::persist::sim_flash::SimFlash;
    use embassy_futures::block_on;
    use std::vec;

    const SECTOR: usize = 128 * 1024;
    type Flash<'a> = SimFlash<'a, SECTOR>;

    fn with_store<T>(mem: &mut [u8], f: impl AsyncFnOnce(&mut Store<Flash>) -> T) -> T {
        let len = mem.len() as u32;
        let mut store = Store::new(Flash::new(mem), 0..len);
        block_on(f(&mut store))
    }

    #[test]
    fn records_of_another_layout_are_refused_by_name() {
        let mut mem = vec![0xFF; 2 * SECTOR];
        let config = config_record::encode(&MountConfig::default());
        let bad = MountConfig {
            guide_rate_sidereal: 5.0,
            ..MountConfig::default()
        };
        with_store(&mut mem, async |s| {
            // Another format number: refused, whatever the body.
            s.save(Slot::Config, CONFIG_FORMAT + 1, &config, Erase::Allow)
                .await
                .unwrap();
            assert!(matches!(
                s.load_config().await,
                Err(LoadError::Format { found, expected })
                    if found == CONFIG_FORMAT + 1 && expected == CONFIG_FORMAT
            ));
            // Our format number, another length.
            s.save(Slot::Config, CONFIG_FORMAT, &config[..44], Erase::Allow)
                .await
                .unwrap();
            assert!(matches!(s.load_config().await, Err(LoadError::Malformed)));
            // Our layout, a value the validation refuses: named.
            s.save(
                Slot::Config,
                CONFIG_FORMAT,
                &config_record::encode(&bad),
                Erase::Allow,
            )
            .await
            .unwrap();
            match s.load_config().await {
                Err(LoadError::Invalid(e)) => assert_eq!(e.field, Field::GuideRateSidereal),
                other => panic!("{other:?}"),
            }
            // A park of another length; a model of another snapshot format.
            s.save(Slot::Park, PARK_FORMAT, &[0; 8], Erase::Allow)
                .await
                .unwrap();
            assert!(matches!(s.load_park().await, Err(LoadError::Malformed)));
            s.save_model(4, &[1, 2, 3], Erase::Allow).await.unwrap();
            assert_eq!(s.load_model(4).await.unwrap(), &[1, 2, 3]);
            assert!(matches!(
                s.load_model(5).await,
                Err(LoadError::Format {
                    found: 4,
                    expected: 5
                })
            ));
        });
    }

    #[test]
    fn a_record_too_short_for_an_envelope_is_malformed() {
        let mut mem = vec![0xFF; 2 * SECTOR];
        block_on(async {
            let mut map = MapStorage::<u8, _, _>::new(
                Flash::new(&mut mem),
                MapConfig::try_new(0..2 * SECTOR as u32).unwrap(),
                Cache::new_uncached(),
            );
            let mut buf = [0; 16];
            map.store_item(&mut buf, &(Slot::Park as u8), &&[7u8][..])
                .await
                .unwrap();
        });
        with_store(&mut mem, async |s| {
            assert!(matches!(s.load_park().await, Err(LoadError::Malformed)));
            assert!(matches!(
                s.load_config().await,
                Err(LoadError::NothingStored)
            ));
        });
    }

    /// The index pass round-trips; a body of another length is malformed.
    #[test]
    fn the_index_pass_round_trips() {
        let mut mem = vec![0xFF; 2 * SECTOR];
        with_store(&mut mem, async |s| {
            assert!(matches!(
                s.load_index().await,
                Err(LoadError::NothingStored)
            ));
            s.save_index(-987_654_321, Erase::Defer).await.unwrap();
            assert_eq!(s.load_index().await.unwrap(), -987_654_321);
            s.save(Slot::Index, INDEX_FORMAT, &[1, 2, 3], Erase::Defer)
                .await
                .unwrap();
            assert!(matches!(s.load_index().await, Err(LoadError::Malformed)));
        });
    }

    /// An unpark clears the park, and a new park replaces it.
    #[test]
    fn a_cleared_park_is_no_park() {
        let mut mem = vec![0xFF; 2 * SECTOR];
        let park = Park {
            ra_steps: 123_456_789,
            dec_steps: -42,
            carries_model: true,
        };
        with_store(&mut mem, async |s| {
            s.save_park(park, Erase::Allow).await.unwrap();
            assert_eq!(s.load_park().await.unwrap(), park);
            s.clear_park(Erase::Defer).await.unwrap();
            assert!(matches!(s.load_park().await, Err(LoadError::NothingStored)));
            s.save_park(park, Erase::Defer).await.unwrap();
            assert_eq!(s.load_park().await.unwrap(), park);
        });
    }

    #[test]
    fn oversized_snapshots_and_bad_ranges_are_refused() {
        let mut mem = vec![0xFF; 2 * SECTOR];
        let big = vec![0u8; MODEL_RECORD_MAX + 1];
        with_store(&mut mem, async |s| {
            let r = s.save_model(1, &big, Erase::Allow).await;
            assert!(matches!(r, Err(SaveError::TooLarge { len }) if len == MODEL_RECORD_MAX + 1));
            // The largest is taken.
            s.save_model(1, &big[1..], Erase::Allow).await.unwrap();
            assert_eq!(s.load_model(1).await.unwrap().len(), MODEL_RECORD_MAX);
        });
        // One page, and a range off the page boundary.
        for range in [0..SECTOR as u32, 4..2 * SECTOR as u32] {
            let mut store = Store::new(Flash::new(&mut mem), range);
            block_on(async {
                assert!(matches!(
                    store.load_park().await,
                    Err(LoadError::Geometry(_))
                ));
                let p = Park {
                    ra_steps: 0,
                    dec_steps: 0,
                    carries_model: false,
                };
                let r = store.save_park(p, Erase::Allow).await;
                assert!(matches!(r, Err(SaveError::Geometry(_))));
            });
        }
    }

    /// Where the next record goes: the first erased word after the
    /// records of page 0.
    fn free_space_start(mem: &[u8]) -> usize {
        let interior = &mem[4..SECTOR - 4];
        let used = interior
            .chunks(4)
            .rposition(|w| w.iter().any(|&b| b != 0xFF))
            .map_or(0, |i| i + 1);
        4 + 4 * used
    }

    /// One byte not erased in the free space where the next record goes:
    /// the save is written again after it and loads at the next boot, or
    /// the save is reported failed. Never done and lost.
    #[test]
    fn a_save_over_a_byte_not_erased_is_written_again_or_reported() {
        let first = vec![0x11u8; 600];
        let second = vec![0x22u8; 600];
        for offset in [0, 3, 9, 17, 300, 601, 700] {
            let mut mem = vec![0xFF; 2 * SECTOR];
            with_store(&mut mem, async |s| {
                s.save_model(1, &first, Erase::Defer).await.unwrap();
            });
            let at = free_space_start(&mem) + offset;
            mem[at] = 0x5A;
            let (r, counters) = with_store(&mut mem, async |s| {
                (s.save_model(1, &second, Erase::Defer).await, s.counters())
            });
            r.unwrap_or_else(|e| panic!("offset {offset}: {e:?}"));
            // The next boot finds what was reported saved.
            let loaded = with_store(&mut mem, async |s| s.load_model(1).await.unwrap().to_vec());
            assert!(loaded == second, "offset {offset}: the save was lost");
            // In the first free word it reads as a spoilt header, which
            // sequential-storage steps over before writing; past the
            // record's end (header 8, key 1, envelope 2, 600, padding 1)
            // it spoils nothing yet.
            let spoilt = (4..8 + 604).contains(&offset);
            assert_eq!(counters.rewrites, u32::from(spoilt), "offset {offset}");
            assert_eq!(counters.unverified, 0);
        }
    }

    /// Bytes not erased all through the free space: every write spoilt,
    /// the save reported unverified and the previous record kept.
    #[test]
    fn a_save_that_never_reads_back_is_reported_unverified() {
        let mut mem = vec![0xFF; 2 * SECTOR];
        let first = vec![0x11u8; 64];
        with_store(&mut mem, async |s| {
            s.save_model(1, &first, Erase::Defer).await.unwrap();
        });
        let from = free_space_start(&mem);
        for i in (from..SECTOR - 16).step_by(16) {
            mem[i + 7] = 0x0F;
        }
        let (r, counters) = with_store(&mut mem, async |s| {
            (
                s.save_model(1, &[0x22; 64], Erase::Defer).await,
                s.counters(),
            )
        });
        assert!(matches!(r, Err(SaveError::Unverified)), "{r:?}");
        assert_eq!(
            counters,
            StoreCounters {
                rewrites: SAVE_ATTEMPTS,
                unverified: 1
            }
        );
        let loaded = with_store(&mut mem, async |s| s.load_model(1).await.unwrap().to_vec());
        assert_eq!(loaded, first);
    }

    #[test]
    fn a_deferred_save_that_needs_a_page_change_leaves_the_flash_untouched() {
        let mut mem = vec![0xFF; 2 * SECTOR];
        let model = vec![0xA5u8; 4096];
        let mut saves = 0;
        with_store(&mut mem, async |s| loop {
            match s.save_model(1, &model, Erase::Defer).await {
                Ok(()) => saves += 1,
                Err(SaveError::EraseDeferred) => break,
                Err(e) => panic!("{e:?}"),
            }
        });
        // A page's worth: 128 KiB over 4 KiB and a little.
        assert_eq!(saves, (SECTOR - 8) / (4096 + 3 + 1 + 8));
        let before = mem.clone();
        let next = vec![9u8; 4096];
        let r = with_store(&mut mem, async |s| {
            s.save_model(1, &next, Erase::Defer).await
        });
        assert!(matches!(r, Err(SaveError::EraseDeferred)), "{r:?}");
        assert!(mem == before, "a deferred save wrote");
        // Allowed, it changes page: one erase, and the new record loads.
        let len = mem.len() as u32;
        let mut flash = Flash::new(&mut mem);
        block_on(async {
            let mut s = Store::new(&mut flash, 0..len);
            s.save_model(1, &next, Erase::Allow).await.unwrap();
            assert_eq!(s.load_model(1).await.unwrap(), &next[..]);
        });
        assert_eq!(flash.erases(), 1);
    }
}
