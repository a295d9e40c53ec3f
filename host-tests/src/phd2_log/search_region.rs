//! Frames PHD2 would have lost. PHD2 looks for the guide star only within
//! its search region around the position where it last found it (at most
//! [`MAX_SEARCH_REGION_PX`] px along each axis, 15 by default), so between
//! two frames in which it found the star, the star's distance from the lock
//! position changes by at most the region's half-diagonal, plus however far
//! the lock itself moved. A row whose RARawDistance is farther than that
//! from the last star found is not a star PHD2 found there: the replay
//! takes it as the guider takes a star it lost, a dropped frame (its DROP
//! row: no measurement, no correction).

use std::f64::consts::SQRT_2;

/// PHD2's largest search region, px along each axis from the star's last
/// position (its setting runs from 7 to 50).
pub const MAX_SEARCH_REGION_PX: f64 = 50.0;

/// The farthest the star moves between two frames in which PHD2 finds it,
/// px: the search region's half-diagonal.
pub const MAX_STAR_STEP_PX: f64 = MAX_SEARCH_REGION_PX * SQRT_2;

/// The star PHD2 last found in a guiding section, as the log gives it.
#[derive(Debug, Clone, Copy)]
pub struct StarTrack {
    /// RARawDistance of the last star found, px; `None` once the lock was
    /// set anew (it may then be anywhere).
    last: Option<f64>,
    /// How far the lock position moved since (dithers), px.
    lock_moved: f64,
}

/// At the start of a section: PHD2 starts guiding on the star at the lock
/// position (the header's `Lock position` is its `Star position`).
impl Default for StarTrack {
    fn default() -> Self {
        StarTrack {
            last: Some(0.0),
            lock_moved: 0.0,
        }
    }
}

impl StarTrack {
    /// `INFO: DITHER by X, Y`: the lock moved by (X, Y) px.
    pub fn dithered(&mut self, x: f64, y: f64) {
        self.lock_moved += x.abs() + y.abs();
    }

    /// `INFO: SET LOCK POSITION`: the lock was put where the log does not
    /// say in RA terms; the next star found is the new reference.
    pub fn lock_set(&mut self) {
        self.last = None;
    }

    /// A row measured the star at `ra_raw` px: whether PHD2 could have
    /// found it there (it then becomes the last star found).
    pub fn found(&mut self, ra_raw: f64) -> bool {
        let reach = MAX_STAR_STEP_PX + self.lock_moved;
        let found = self.last.is_none_or(|last| (ra_raw - last).abs() <= reach);
        if found {
            *self = StarTrack {
                last: Some(ra_raw),
                lock_moved: 0.0,
            };
        }
        found
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_star_moves_within_the_search_region() {
        let mut s = StarTrack::default();
        assert!(!s.found(MAX_STAR_STEP_PX + 0.01));
        assert!(s.found(MAX_STAR_STEP_PX));
        // From the last star found, not from the one refused.
        assert!(!s.found(-1.0));
        assert!(!s.found(5000.0));
        assert!(s.found(2.0 * MAX_STAR_STEP_PX));
    }

    #[test]
    fn a_dither_moves_the_lock() {
        let mut s = StarTrack::default();
        s.dithered(-30.0, 40.0);
        assert!(!s.found(MAX_STAR_STEP_PX + 70.01));
        assert!(s.found(MAX_STAR_STEP_PX + 70.0));
        // The allowance is spent on the star that used it.
        assert!(!s.found(0.0));
    }

    #[test]
    fn a_lock_set_anew_takes_the_next_star() {
        let mut s = StarTrack::default();
        assert!(s.found(1.0));
        s.lock_set();
        assert!(s.found(-3000.0));
        assert!(!s.found(1.0));
        assert!(s.found(-2990.0));
    }
}
