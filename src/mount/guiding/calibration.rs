//! A guider's calibration, recognised from its pulses.
//!
//! A guider calibrates at the start of each section (PHD2: equal pulses west
//! until the star has moved far enough, as many east to bring it back, then
//! the same north and south, an exposure after each). Those pulses answer
//! no error of the gear, and a frame that took one for a correction would
//! learn several arcsec of error that never was. Guide pulses follow the
//! error the guider measured, so [`RUN`] in a row on one axis, one way, of
//! the same length (within [`TOLERANCE_US`]) and at least [`LEAST_STEP_US`]
//! long are a calibration's steps. (Two in a row happen by chance: about
//! one guide pulse in a hundred at a pixel of seeing. A steady drift
//! corrected without seeing makes runs of short equal pulses: those are
//! gear error, and learned.) From the last of them until [`HOLD_CADENCES`] cadences after the last one the
//! frames are [`FrameKind::Calibration`](crate::mount::frame::FrameKind):
//! not learned. The hold bridges the turn of a leg (the first pulse back
//! matches none before it) and the fresh exposure the guider takes before
//! its Dec legs, and covers the first frames of guiding after them.
//!
//! A calibration's first pulses look like any guide pulses; the learner's
//! bump rule takes the first, far beyond the recent ones, for a step of
//! the star and settles over the next. A guider that sends [`RUN`] equal
//! guide pulses in a row costs the frames of one hold.

use crate::mount::st4::{Axis, Direction};

/// How far apart two pulses' lengths may be and still be a calibration's
/// equal steps, µs: PHD2 gives whole milliseconds, and an ST4 adapter's
/// timing moves each edge by up to a millisecond.
pub const TOLERANCE_US: u64 = 2_000;

/// The shortest calibration step. PHD2 sizes its step so that about a
/// dozen move the star its calibration distance (25 px): at half the
/// sidereal rate and a guide camera's 1-4 arcsec per pixel that is 250 ms
/// and longer, where guide pulses at a pixel of seeing last about 100 ms.
pub const LEAST_STEP_US: u64 = 200_000;

/// Cadences after a calibration's last pulse before frames are learned
/// again. PHD2's Dec legs start from a fresh exposure: from the last pulse
/// east to the third pulse north there are four exposures.
pub const HOLD_CADENCES: u64 = 6;

/// Equal pulses in a row that make a calibration.
pub const RUN: u8 = 3;

/// One axis's last pulse: its direction, length and end, and how many
/// equal pulses in a row it ended.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Pulse {
    direction: Direction,
    length_us: u64,
    end_us: u64,
    run: u8,
}

/// Whether the guider is calibrating, from its pulses on both axes.
#[derive(Clone, Copy, Debug)]
pub(super) struct CalibrationWatch {
    /// Off: no pulse is a calibration's (`Additions::calibration_watch`).
    on: bool,
    last: [Option<Pulse>; 2],
    /// Frames up to this time are a calibration's.
    until_us: Option<u64>,
}

impl CalibrationWatch {
    pub fn new(on: bool) -> Self {
        CalibrationWatch {
            on,
            last: [None; 2],
            until_us: None,
        }
    }

    /// A pulse on `axis` ended at `end_us` after `length_us`; `hold_us` is
    /// the hold after it. True when it is a calibration's step that begins
    /// a calibration: not one recognised within a hold before (a Dec leg
    /// recognised as the RA legs' hold ran out is the same calibration's).
    pub fn pulse(
        &mut self,
        axis: Axis,
        direction: Direction,
        length_us: u64,
        end_us: u64,
        hold_us: u64,
    ) -> bool {
        let slot = match axis {
            Axis::Ra => 0,
            Axis::Dec => 1,
        };
        let Some(entry) = self.last.get_mut(slot) else {
            return false;
        };
        let equal = |prev: &Pulse| {
            length_us >= LEAST_STEP_US
                && prev.direction == direction
                && prev.length_us.abs_diff(length_us) <= TOLERANCE_US
                && end_us.saturating_sub(prev.end_us) <= length_us.saturating_add(hold_us)
        };
        let run = match entry {
            Some(prev) if equal(prev) => prev.run.saturating_add(1),
            _ => 1,
        };
        *entry = Some(Pulse {
            direction,
            length_us,
            end_us,
            run,
        });
        if run < RUN || !self.on {
            return false;
        }
        let began = self
            .until_us
            .is_none_or(|until| end_us > until.saturating_add(hold_us));
        self.until_us = Some(end_us.saturating_add(hold_us));
        began
    }

    /// Whether a frame at `at_us` is a calibration's.
    pub fn active(&self, at_us: u64) -> bool {
        self.until_us.is_some_and(|until| at_us <= until)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const HOLD: u64 = 8_000_000;

    /// PHD2's calibration: `n` equal pulses each way on each axis, one
    /// every `every_us`, after `before` of them west (they began the
    /// calibration); returns the end of the last and how many began a
    /// calibration.
    fn calibrate(
        w: &mut CalibrationWatch,
        before: u64,
        n: u64,
        every_us: u64,
        length_us: u64,
    ) -> (u64, u32) {
        let mut t = before * every_us;
        let mut began = 0;
        let legs = [
            (Axis::Ra, Direction::Plus),
            (Axis::Ra, Direction::Minus),
            (Axis::Dec, Direction::Plus),
            (Axis::Dec, Direction::Minus),
        ];
        for (i, (axis, direction)) in legs.into_iter().enumerate() {
            if i == 2 {
                t += every_us; // the fresh exposure before the Dec legs
            }
            let first = if i == 0 { before } else { 0 };
            for k in first..n {
                t += every_us;
                // an adapter's jitter: a millisecond either way
                let jitter = if k % 2 == 0 { 0 } else { 1_000 };
                began += u32::from(w.pulse(axis, direction, length_us + jitter, t, HOLD));
                if k + 1 >= u64::from(RUN) || i > 0 {
                    assert!(w.active(t), "leg {i} step {k} not taken for a calibration");
                }
            }
        }
        (t, began)
    }

    #[test]
    fn a_calibration_is_recognised_from_its_third_pulse_to_the_hold_after_its_last() {
        let mut w = CalibrationWatch::new(true);
        for k in 1..u64::from(RUN) {
            let t = k * 2_000_000;
            assert!(!w.pulse(Axis::Ra, Direction::Plus, 750_000, t, HOLD));
            assert!(!w.active(t));
        }
        let (end, began) = calibrate(&mut w, u64::from(RUN) - 1, 5, 2_000_000, 750_000);
        assert_eq!(began, 1);
        assert!(w.active(end + HOLD));
        assert!(!w.active(end + HOLD + 1));
    }

    #[test]
    fn guide_pulses_of_different_lengths_or_ways_are_no_calibration() {
        let mut w = CalibrationWatch::new(true);
        let pulses = [
            (Direction::Plus, 300_000),
            (Direction::Plus, 301_000),
            (Direction::Plus, 304_000),
            (Direction::Minus, 304_000),
            (Direction::Plus, 304_000),
            (Direction::Plus, 250_000),
            (Direction::Plus, 250_000),
        ];
        for (k, (direction, length)) in pulses.into_iter().enumerate() {
            let t = (k as u64 + 1) * 2_000_000;
            assert!(!w.pulse(Axis::Ra, direction, length, t, HOLD));
            assert!(!w.active(t));
        }
        // equal, but long after the one before: separate corrections
        let t = 7 * 2_000_000 + 250_000 + HOLD + 1;
        assert!(!w.pulse(Axis::Ra, Direction::Plus, 250_000, t, HOLD));
        // equal pulses on the other axis are no steps of this one's
        for k in 1..=2 {
            assert!(!w.pulse(Axis::Dec, Direction::Plus, 250_000, t + k, HOLD));
        }
        assert!(!w.active(t + 2));
        // a steady drift's short equal corrections are guide pulses
        for k in 1..=5 {
            let at = t + k * 2_000_000;
            assert!(!w.pulse(Axis::Ra, Direction::Plus, LEAST_STEP_US - 1, at, HOLD));
            assert!(!w.active(at));
        }
    }
}
