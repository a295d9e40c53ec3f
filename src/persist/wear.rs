//! Flash wear: how many erase cycles a save cadence costs each sector per
//! year, from the records' sizes on flash and the store's page size.
//!
//! The map only appends. When a save does not fit in the current page the
//! store moves to the other page: it copies the records still current
//! (configuration, park, the last model) there, erases the old page and
//! appends the new record. So one erase buys the page's room less those
//! copies, `(page - 2 words - live) / model`, model saves (floor: the last
//! one that does not fit is left over). Parks are counted as model saves
//! (more than they take), so the figure errs towards more wear. The pages
//! are used in turn, each taking its share of the erases.

use embedded_storage_async::nor_flash::NorFlash;
use sequential_storage::cache::{Cache, Uncached};
use sequential_storage::map::MapStorage;

use super::config_record::CONFIG_RECORD_LEN;
use super::park::PARK_RECORD_LEN;
use super::record::ENVELOPE_LEN;

/// Erase cycles each sector is rated for (STM32F4 datasheets, minimum).
pub const RATED_ERASE_CYCLES: f64 = 10_000.0;

/// How often the firmware saves.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cadence {
    /// Seconds between model saves while guiding.
    pub model_save_interval_s: u32,
    /// Hours guided per night.
    pub hours_per_night: u32,
    /// Nights per year.
    pub nights_per_year: u32,
    /// Parks (park saves) per night.
    pub parks_per_night: u32,
}

impl Cadence {
    /// A save every 10 minutes over 8-hour nights, every night of the year,
    /// one park a night: more than any observer guides.
    pub const EVERY_NIGHT: Cadence = Cadence {
        model_save_interval_s: 600,
        hours_per_night: 8,
        nights_per_year: 365,
        parks_per_night: 1,
    };

    /// Saves per year, model and park.
    pub fn saves_per_year(&self) -> u64 {
        let per_night = (u64::from(self.hours_per_night) * 3600)
            .checked_div(u64::from(self.model_save_interval_s))
            .unwrap_or(0)
            + u64::from(self.parks_per_night);
        per_night * u64::from(self.nights_per_year)
    }
}

/// Wear of a cadence on the store.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Wear {
    /// Bytes one model record takes on flash (header, key, envelope, body,
    /// padded to the flash word).
    pub model_record_bytes: u32,
    /// Bytes of the records copied to each new page (configuration, park
    /// and model).
    pub live_bytes: u32,
    /// Model saves between two erases.
    pub saves_per_erase: u32,
    /// Erases per year, all pages together.
    pub erases_per_year: f64,
    /// Erases per year of each sector.
    pub erases_per_sector_per_year: f64,
    /// Years until each sector reaches [`RATED_ERASE_CYCLES`].
    pub years_to_rated: f64,
}

/// Bytes a record with a body of `body_len` takes on a flash `F`.
pub fn record_bytes<F: NorFlash>(body_len: usize) -> u32 {
    let header = MapStorage::<u8, F, Cache<Uncached, Uncached, Uncached, u8>>::item_overhead_size();
    // Key (1 byte), envelope, body, padded to whole words.
    let data = (1 + ENVELOPE_LEN + body_len).next_multiple_of(F::WRITE_SIZE);
    header + data as u32
}

/// The wear `cadence` causes on a store of `pages` pages of flash `F`
/// saving model snapshots of `model_len` bytes.
pub fn wear<F: NorFlash>(cadence: &Cadence, model_len: usize, pages: u32) -> Wear {
    let model = record_bytes::<F>(model_len);
    let live = record_bytes::<F>(CONFIG_RECORD_LEN) + record_bytes::<F>(PARK_RECORD_LEN) + model;
    // Each page keeps its first and last word for its state markers.
    let room = (F::ERASE_SIZE as u32).saturating_sub(2 * F::WRITE_SIZE as u32 + live);
    let saves_per_erase = room.checked_div(model).unwrap_or(0);
    let erases_per_year = cadence.saves_per_year() as f64 / f64::from(saves_per_erase);
    let erases_per_sector_per_year = erases_per_year / f64::from(pages);
    Wear {
        model_record_bytes: model,
        live_bytes: live,
        saves_per_erase,
        erases_per_year,
        erases_per_sector_per_year,
        years_to_rated: RATED_ERASE_CYCLES / erases_per_sector_per_year,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mount::config::MountConfig;
    use crate::persist::sim_flash::SimFlash;
    use crate::persist::{Erase, Park, Store};
    use embassy_futures::block_on;
    use std::vec;

    const SECTOR: usize = 128 * 1024;
    type Flash<'a> = SimFlash<'a, SECTOR>;

    /// Model saves between erases, counted on the real store over a
    /// simulated 2 x 128 KiB flash (after the first page, which starts
    /// empty): the arithmetic of `wear` must match it.
    fn measured_saves_per_erase(model_len: usize) -> u32 {
        let mut mem = vec![0xFFu8; 2 * SECTOR];
        let mut flash = Flash::new(&mut mem);
        let range = 0..2 * SECTOR as u32;
        let model = vec![0x5Au8; model_len];
        let mount = MountConfig::default().validate().unwrap();
        let park = Park {
            ra_steps: 1,
            dec_steps: 2,
            carries_model: true,
        };
        let mut erase_at = vec![];
        block_on(async {
            let mut store = Store::new(&mut flash, range.clone());
            store.save_config(&mount, Erase::Allow).await.unwrap();
            store.save_park(park, Erase::Allow).await.unwrap();
            for i in 0..250 {
                let mut store = Store::new(&mut flash, range.clone());
                store.save_model(1, &model, Erase::Allow).await.unwrap();
                if flash.erases() > erase_at.len() as u64 {
                    erase_at.push(i);
                }
            }
        });
        assert!(erase_at.len() >= 3, "{erase_at:?}");
        let gaps: vec::Vec<u32> = erase_at.windows(2).map(|w| w[1] - w[0]).collect();
        assert!(gaps.iter().all(|&g| g == gaps[0]), "{gaps:?}");
        gaps[0]
    }

    #[test]
    fn the_arithmetic_matches_the_store() {
        for model_len in [2_048, 4_096, crate::persist::MODEL_RECORD_MAX] {
            let w = wear::<Flash>(&Cadence::EVERY_NIGHT, model_len, 2);
            assert_eq!(
                w.saves_per_erase,
                measured_saves_per_erase(model_len),
                "{model_len} B"
            );
        }
    }

    /// The figures of docs/persistence.md:
    /// `cargo test --release --lib --no-default-features --target
    /// x86_64-unknown-linux-gnu persist::wear -- --nocapture`.
    #[test]
    fn wear_at_the_documented_cadence() {
        let c = Cadence::EVERY_NIGHT;
        assert_eq!(c.saves_per_year(), (48 + 1) * 365);
        std::println!(
            "cadence: a model save every {} s over {} h nights, {} nights/year, {} park/night: {} saves/year",
            c.model_save_interval_s,
            c.hours_per_night,
            c.nights_per_year,
            c.parks_per_night,
            c.saves_per_year()
        );
        std::println!("model_bytes,record_bytes,live_bytes,saves_per_erase,erases_per_year,erases_per_sector_per_year,years_to_10000");
        for model_len in [4_096, crate::persist::MODEL_RECORD_MAX] {
            let w = wear::<Flash>(&c, model_len, 2);
            std::println!(
                "{model_len},{},{},{},{:.0},{:.0},{:.1}",
                w.model_record_bytes,
                w.live_bytes,
                w.saves_per_erase,
                w.erases_per_year,
                w.erases_per_sector_per_year,
                w.years_to_rated
            );
            // The sectors outlive a mount (ten years) even at the largest
            // record and this cadence.
            assert!(w.years_to_rated > 10.0, "{w:?}");
            // Consistent: the per-sector rate times the pages is the total,
            // and the total is saves over saves per erase.
            assert!((w.erases_per_sector_per_year * 2.0 - w.erases_per_year).abs() < 1e-9);
            let saves = c.saves_per_year() as f64;
            assert!((w.erases_per_year * f64::from(w.saves_per_erase) - saves).abs() < 1e-6);
        }
    }
}
