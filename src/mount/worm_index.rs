//! The worm-index sensor: an optional Hall or optical sensor that marks one
//! point of the worm's turn (as OnStep's PEC index does). Its passes, as RA
//! step counts, give the worm's phase after a power cycle: the step count
//! of the pass saved with the model and that of the first pass after the
//! boot are the same point of the worm, so their gear times differ by the
//! offset `model::snapshot::Phase::Worm` takes.

use crate::mount::config::Mount;

/// The sensor's passes, debounced.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WormIndex {
    /// Steps of half a worm turn: a second edge within it is a bounce or
    /// noise, not the next pass.
    min_gap_steps: i64,
    sidereal_steps_per_s: f64,
    last_pass: Option<i64>,
    passes: u32,
    ignored: u32,
}

impl WormIndex {
    pub fn new(mount: &Mount) -> Self {
        WormIndex {
            min_gap_steps: i64::from(mount.config().ra_steps_per_worm_turn / 2),
            sidereal_steps_per_s: mount.sidereal_ra_steps_per_s_f64(),
            last_pass: None,
            passes: 0,
            ignored: 0,
        }
    }

    /// An edge of the sensor with the RA axis at `ra_steps`: `true` if it
    /// is a pass (the first, or at least half a turn from the last).
    pub fn edge(&mut self, ra_steps: i64) -> bool {
        let pass = self
            .last_pass
            .is_none_or(|last| ra_steps.abs_diff(last) >= self.min_gap_steps.unsigned_abs());
        if pass {
            self.last_pass = Some(ra_steps);
            self.passes = self.passes.saturating_add(1);
        } else {
            self.ignored = self.ignored.saturating_add(1);
        }
        pass
    }

    /// The RA step count of the last pass.
    pub fn last_pass(&self) -> Option<i64> {
        self.last_pass
    }

    /// Passes since start-up.
    pub fn passes(&self) -> u32 {
        self.passes
    }

    /// Edges too close to a pass to be one.
    pub fn ignored(&self) -> u32 {
        self.ignored
    }

    /// The gear-time offset from a pass now at `ra_steps` to the pass
    /// `saved_steps` saved with a model: what `Phase::Worm` takes (saved
    /// gear time = new gear time + offset; right modulo the worm period).
    pub fn offset_s(&self, saved_steps: i64, ra_steps: i64) -> f64 {
        saved_steps.wrapping_sub(ra_steps) as f64 / self.sidereal_steps_per_s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mount::config::MountConfig;

    #[test]
    fn passes_are_half_a_turn_apart_or_ignored() {
        let mount = MountConfig::default().validate().unwrap();
        let turn = i64::from(mount.config().ra_steps_per_worm_turn);
        let mut index = WormIndex::new(&mount);
        assert!(index.edge(1_000));
        // Contact bounce and noise within half a turn, either way.
        assert!(!index.edge(1_003));
        assert!(!index.edge(1_000 - turn / 2 + 1));
        assert!(index.edge(1_000 + turn));
        assert!(index.edge(1_000 - turn));
        assert_eq!((index.passes(), index.ignored()), (3, 2));
        assert_eq!(index.last_pass(), Some(1_000 - turn));
    }

    /// The offset maps the new pass onto the saved one: a worm turn of
    /// steps is a worm period of gear time.
    #[test]
    fn the_offset_is_gear_time_between_the_passes() {
        let mount = MountConfig::default().validate().unwrap();
        let index = WormIndex::new(&mount);
        let turn = i64::from(mount.config().ra_steps_per_worm_turn);
        let period = f64::from(mount.config().worm_period_s);
        let offset = index.offset_s(5 * turn + 7, 7);
        assert!((offset - 5.0 * period).abs() < 1e-6 * period, "{offset}");
        assert_eq!(index.offset_s(7, 7), 0.0);
    }
}
