//! The STEP and DIR waveform of one stepper driver, tick by tick.
//!
//! The step generator ([`crate::mount::stepgen`]) says on which tick a step
//! is due; this turns that into pin changes a driver accepts:
//!
//! - STEP is high for exactly one tick and low for at least one, so the
//!   highest step rate is half the tick rate (the limit that
//!   `MountConfig::validate` enforces). At 50 kHz that is 20 µs high: A4988
//!   needs 1 µs, DRV8825 1.9 µs, TMC2209 100 ns.
//! - DIR changes one tick before the STEP rising edge that needs it (set-up
//!   time one tick; drivers need 20-650 ns) and never while STEP is high.
//! - A step that cannot go out on the tick it is due (STEP still high, or
//!   DIR about to change) is owed and goes out on the next free tick; a step
//!   due in the opposite direction cancels an owed one.
//!
//! [`StepPulse::tick`] returns both the pin change for the hal to make and
//! the step that went out, so the position the firmware keeps is the
//! motor's, step for step.

/// What the hal does to the pins on this tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PinChange {
    /// Nothing.
    None,
    /// STEP low (the end of a step pulse).
    StepLow,
    /// DIR to this direction (true = forward), ahead of the next step.
    Dir { forward: bool },
    /// STEP high: a step goes out in the direction DIR shows.
    StepHigh,
}

/// The pulse state of one axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StepPulse {
    step_high: bool,
    dir_forward: bool,
    /// Steps due but not yet emitted (signed: positive = forward).
    owed: i32,
}

impl Default for StepPulse {
    fn default() -> Self {
        Self::new()
    }
}

impl StepPulse {
    /// STEP low, DIR forward, nothing owed: the levels the hal sets up.
    pub const fn new() -> Self {
        StepPulse {
            step_high: false,
            dir_forward: true,
            owed: 0,
        }
    }

    /// One tick: `due` is the step generator's output (`Some(forward)` when
    /// a step is due). Returns the pin change and the step emitted on this
    /// tick (+1, -1 or 0).
    #[inline]
    pub fn tick(&mut self, due: Option<bool>) -> (PinChange, i32) {
        match due {
            Some(true) => self.owed = self.owed.saturating_add(1),
            Some(false) => self.owed = self.owed.saturating_sub(1),
            None => {}
        }
        if self.step_high {
            self.step_high = false;
            return (PinChange::StepLow, 0);
        }
        if self.owed == 0 {
            return (PinChange::None, 0);
        }
        let forward = self.owed > 0;
        if forward != self.dir_forward {
            self.dir_forward = forward;
            return (PinChange::Dir { forward }, 0);
        }
        self.step_high = true;
        if forward {
            self.owed -= 1;
            (PinChange::StepHigh, 1)
        } else {
            self.owed += 1;
            (PinChange::StepHigh, -1)
        }
    }

    /// Steps due but not yet emitted (at most a few at any time).
    pub fn owed(&self) -> i32 {
        self.owed
    }

    /// The DIR level the pulse state has set (true = forward).
    pub fn dir_forward(&self) -> bool {
        self.dir_forward
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::SplitMix64;

    /// Feeds `due` one tick at a time; returns the changes and the count.
    fn run(p: &mut StepPulse, due: &[Option<bool>]) -> (std::vec::Vec<PinChange>, i32) {
        let mut n = 0;
        let changes = due
            .iter()
            .map(|&d| {
                let (c, s) = p.tick(d);
                n += s;
                c
            })
            .collect();
        (changes, n)
    }

    #[test]
    fn a_step_is_high_for_one_tick() {
        let mut p = StepPulse::new();
        let (c, n) = run(&mut p, &[Some(true), None, None]);
        assert_eq!(
            c,
            [PinChange::StepHigh, PinChange::StepLow, PinChange::None]
        );
        assert_eq!(n, 1);
    }

    #[test]
    fn dir_changes_a_tick_before_the_step() {
        let mut p = StepPulse::new();
        let (c, n) = run(&mut p, &[Some(false), None, None, None]);
        assert_eq!(
            c,
            [
                PinChange::Dir { forward: false },
                PinChange::StepHigh,
                PinChange::StepLow,
                PinChange::None
            ]
        );
        assert_eq!(n, -1);
        assert!(!p.dir_forward());
    }

    #[test]
    fn a_step_due_while_step_is_high_is_owed_then_sent() {
        let mut p = StepPulse::new();
        let (c, n) = run(&mut p, &[Some(true), Some(true), None, None]);
        assert_eq!(
            c,
            [
                PinChange::StepHigh,
                PinChange::StepLow,
                PinChange::StepHigh,
                PinChange::StepLow
            ]
        );
        assert_eq!((n, p.owed()), (2, 0));
    }

    #[test]
    fn an_opposite_step_cancels_an_owed_one() {
        let mut p = StepPulse::new();
        let (_, n) = run(&mut p, &[Some(true), Some(true), Some(false), None, None]);
        assert_eq!((n, p.owed()), (1, 0));
    }

    /// Any sequence of due steps the generator can produce (never due on
    /// two ticks running): STEP never high two ticks running, DIR
    /// never changes while STEP is high, every step goes out in the
    /// direction DIR shows, and the emitted count follows the due count
    /// within what is owed.
    #[test]
    fn random_due_steps_keep_the_waveform_legal() {
        let mut rng = SplitMix64::new(1);
        let mut p = StepPulse::new();
        let (mut step_high, mut dir_forward) = (false, true);
        let (mut due_sum, mut emitted) = (0i64, 0i64);
        let mut last_due = false;
        for _ in 0..200_000 {
            let due = match rng.below(5) {
                0 if !last_due => Some(true),
                1 if !last_due => Some(false),
                _ => None,
            };
            last_due = due.is_some();
            due_sum += match due {
                Some(true) => 1,
                Some(false) => -1,
                None => 0,
            };
            let (c, s) = p.tick(due);
            match c {
                PinChange::None => assert_eq!(s, 0),
                PinChange::StepLow => {
                    assert!(step_high);
                    step_high = false;
                }
                PinChange::Dir { forward } => {
                    assert!(!step_high);
                    assert_ne!(forward, dir_forward);
                    dir_forward = forward;
                }
                PinChange::StepHigh => {
                    assert!(!step_high);
                    assert_eq!(s, if dir_forward { 1 } else { -1 });
                    step_high = true;
                }
            }
            emitted += i64::from(s);
            assert_eq!(due_sum - emitted, i64::from(p.owed()));
            assert!(p.owed().abs() <= 2, "owed {}", p.owed());
        }
    }
}
