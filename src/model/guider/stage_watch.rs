//! Whether the model's stages changed: a stage found, given up, or moved
//! to another line. What was measured of the model before (the trust's
//! score, the learner's feed-forward weight) measured another model.

/// How far a stage's period moves, as a fraction of it, before the model
/// counts as another: a stage moving to another line, not its tracker
/// following one.
pub const STAGE_MOVE: f64 = 0.05;

/// The stage periods last noted (NaN: a stage not found, or none noted).
#[derive(Clone, Copy, Debug)]
pub struct StageWatch<const N: usize> {
    noted: [f32; N],
}

impl<const N: usize> StageWatch<N> {
    /// Nothing noted: the first periods seen count as a change.
    pub const NEW: Self = Self {
        noted: [f32::NAN; N],
    };

    /// Whether a stage of `periods_s` (NaN: not found) was found, given up
    /// or moved by more than [`STAGE_MOVE`] since the periods were last
    /// noted; notes them if so.
    pub fn changed(&mut self, periods_s: [f64; N]) -> bool {
        let mut changed = false;
        for (noted, p) in self.noted.iter_mut().zip(periods_s) {
            let p = p as f32;
            let moved = match (p.is_finite(), noted.is_finite()) {
                (true, true) => (p - *noted).abs() > STAGE_MOVE as f32 * *noted,
                (a, b) => a != b,
            };
            if moved {
                *noted = p;
                changed = true;
            }
        }
        changed
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stage_found_moved_or_given_up_is_a_change_and_its_tracker_following_is_not() {
        let mut w = StageWatch::<2>::NEW;
        assert!(w.changed([600.0, f64::NAN]), "the first periods");
        assert!(!w.changed([600.0, f64::NAN]));
        assert!(!w.changed([629.0, f64::NAN]), "within 5 %");
        assert!(w.changed([631.0, f64::NAN]), "beyond 5 %");
        assert!(w.changed([631.0, 96.0]), "a stage found");
        assert!(!w.changed([631.0, 96.0]));
        assert!(w.changed([631.0, f64::NAN]), "a stage given up");
    }
}
