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
//! The store keeps no state between calls besides its buffer (the map is
//! built per call, uncached), so it reads the flash afresh each time: at
//! most both pages, 256 KiB read and CRC-checked per load or save.

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
}

impl<F: NorFlash> Store<F> {
    /// Checks nothing yet: a range that does not fit the flash is reported
    /// by the first load or save ([`LoadError::Geometry`]).
    pub fn new(flash: F, range: Range<u32>) -> Self {
        Store {
            flash,
            range,
            buffer: Buffer([0; BUFFER_LEN]),
        }
    }

    /// The flash back.
    pub fn into_flash(self) -> F {
        self.flash
    }

    /// The stored configuration, validated.
    pub async fn load_config(&mut self) -> Result<Mount, LoadError<F::Error>> {
        let (_, body) = self.load(Slot::Config, &[CONFIG_FORMAT]).await?;
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
        self.load(Slot::Model, &[format])
            .await
            .map(|(_, body)| body)
    }

    /// The stored model snapshot if it was written in one of `formats`
    /// (newest first: a `Format` error names the first), with its format.
    pub async fn load_model_of(
        &mut self,
        formats: &[u16],
    ) -> Result<(u16, &[u8]), LoadError<F::Error>> {
        self.load(Slot::Model, formats).await
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
        match self.load(Slot::Park, &[PARK_FORMAT]).await?.1 {
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
        let (_, body) = self.load(Slot::Index, &[INDEX_FORMAT]).await?;
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
    /// The newest record of `slot` and its format, one of `formats`.
    async fn load(
        &mut self,
        slot: Slot,
        formats: &[u16],
    ) -> Result<(u16, &[u8]), LoadError<F::Error>> {
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
            Ok(Some(e)) if formats.contains(&e.format) => Ok((e.format, e.body)),
            Ok(Some(e)) => Err(LoadError::Format {
                found: e.format,
                expected: formats.first().copied().unwrap_or(0),
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
        match map
            .store_item(&mut self.buffer.0, &(slot as u8), &record)
            .await
        {
            Ok(()) => Ok(()),
            Err(sequential_storage::Error::Storage {
                value: GateError::EraseDeferred,
                ..
            }) => Err(SaveError::EraseDeferred),
            Err(e) => Err(SaveError::Flash(e)),
        }
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
            // Either of two formats: the stored one, with its format.
            assert_eq!(s.load_model_of(&[5, 4]).await.unwrap(), (4, &[1, 2, 3][..]));
            assert!(matches!(
                s.load_model_of(&[6, 5]).await,
                Err(LoadError::Format {
                    found: 4,
                    expected: 6
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
                };
                let r = store.save_park(p, Erase::Allow).await;
                assert!(matches!(r, Err(SaveError::Geometry(_))));
            });
        }
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
