//! The guider's calibration, as PHD2 makes it at the start of a section:
//! equal pulses west until the star has moved the calibration distance,
//! as many east to bring it back, then the same north and south, one
//! exposure after each pulse. PHD2 stops a leg when the star has moved
//! far enough; here each leg takes the steps PHD2 would on an ideal mount
//! (the distance over one step's move at the guide rate), so that every
//! firmware sees the same pulses at the same times.

use mkgp_mount::mount::st4::Line;

/// PHD2's default calibration step, ms.
pub const STEP_MS: u64 = 750;
/// PHD2's default calibration distance, px.
pub const DISTANCE_PX: f64 = 25.0;

/// A leg of the calibration, in the order they run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Leg {
    West,
    East,
    North,
    South,
}

impl Leg {
    /// The name in the log's rows.
    pub fn name(self) -> &'static str {
        match self {
            Leg::West => "West",
            Leg::East => "East",
            Leg::North => "North",
            Leg::South => "South",
        }
    }

    /// The ST4 line of its pulses.
    pub fn line(self) -> Line {
        match self {
            Leg::West => Line::RaPlus,
            Leg::East => Line::RaMinus,
            Leg::North => Line::DecPlus,
            Leg::South => Line::DecMinus,
        }
    }
}

/// What to do after the exposure of a calibration step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Next {
    /// Log the row `leg,step` (measured from `origin`), then pulse `pulse`
    /// if any (the next exposure waits for it).
    Row {
        leg: Leg,
        step: u32,
        pulse: Option<Leg>,
        /// The west or north leg has just ended at this row: log its angle
        /// and rate.
        leg_complete: bool,
    },
    /// The south leg is back: calibration complete.
    Done,
}

/// Where a calibration stands.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Calibration {
    /// Steps per leg.
    pub steps: u32,
    leg: Leg,
    step: u32,
    done: bool,
}

impl Calibration {
    /// A calibration at the guide rate `guide_px_per_s` (1 px = 1 arcsec).
    pub fn new(guide_px_per_s: f64) -> Self {
        let step_px = guide_px_per_s * STEP_MS as f64 * 1e-3;
        Calibration {
            steps: (DISTANCE_PX / step_px).ceil().max(1.0) as u32,
            leg: Leg::West,
            step: 0,
            done: false,
        }
    }

    /// One step's pulse, us.
    pub fn pulse_us(&self) -> u64 {
        STEP_MS * 1000
    }

    /// The exposure after the last pulse (or the first) has ended: what to
    /// log and send. A leg's rows count 0 up to `steps` going out (west,
    /// north) and `steps - 1` down to 0 coming back (east, south); the
    /// north leg starts from a fresh exposure, as PHD2 measures its new
    /// starting point.
    pub fn after_exposure(&mut self) -> Next {
        if self.done {
            return Next::Done;
        }
        let (leg, step) = (self.leg, self.step);
        let n = self.steps;
        let (pulse, leg_complete) = match leg {
            Leg::West | Leg::North if step < n => {
                self.step += 1;
                (Some(leg), false)
            }
            Leg::West | Leg::North => {
                let back = if leg == Leg::West {
                    Leg::East
                } else {
                    Leg::South
                };
                self.leg = back;
                self.step = n - 1;
                (Some(back), true)
            }
            Leg::East | Leg::South if step > 0 => {
                self.step -= 1;
                (Some(leg), false)
            }
            Leg::East => {
                self.leg = Leg::North;
                self.step = 0;
                (None, false)
            }
            Leg::South => {
                self.done = true;
                (None, false)
            }
        };
        Next::Row {
            leg,
            step,
            pulse,
            leg_complete,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn legs_and_rows() {
        let mut c = Calibration::new(7.52);
        assert_eq!(c.steps, 5);
        let mut rows = Vec::new();
        while let Next::Row {
            leg,
            step,
            pulse,
            leg_complete,
        } = c.after_exposure()
        {
            rows.push(format!(
                "{}{step}{}{}",
                leg.name(),
                pulse.map_or("-", Leg::name),
                if leg_complete { "!" } else { "" }
            ));
        }
        assert_eq!(
            rows.join(" "),
            "West0West West1West West2West West3West West4West West5East! \
             East4East East3East East2East East1East East0- \
             North0North North1North North2North North3North North4North North5South! \
             South4South South3South South2South South1South South0-"
        );
        assert_eq!(c.after_exposure(), Next::Done);
    }
}
