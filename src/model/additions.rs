//! The additions around the paper's model, each switchable by name.
//!
//! Each was added to mend one case or one log; a simulator turns any one
//! off (by its name, [`Additions::set`]) to measure what it is worth on
//! mounts it was not tuned on. All are on by default: the firmware runs
//! them all. `GuiderConfig::additions` carries them to the model and to the
//! learner around it (`crate::mount::learner`), which reads its own here;
//! the loop's fast part takes them at its start
//! (`crate::control_loop::ControlLoop::start_with`).

/// The loop in which an addition acts, and so where its worth is measured.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Acts {
    /// The model's closed loop: the guider's model.
    Model,
    /// Only the firmware's loop: the learner, the loop's fast part, or a
    /// part of the model only the learner reads.
    Firmware,
    /// Across a power cycle: on a restored model, where its worth shows.
    Restore,
}

/// A name [`Additions::set`] does not know.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct UnknownAddition;

/// One list makes the switches, their names, where each acts and
/// [`Additions::set`], so that an addition is added or deleted in one
/// place.
macro_rules! additions {
    ($($(#[doc = $doc:literal])* $name:ident: $acts:ident,)*) => {
        /// The switches, all on by default ([`Additions::ALL`]).
        #[derive(Clone, Copy, Debug, PartialEq, Eq)]
        pub struct Additions {
            $($(#[doc = $doc])* pub $name: bool,)*
        }

        impl Additions {
            /// Every addition on: the firmware's model.
            pub const ALL: Additions = Additions { $($name: true,)* };

            /// Each addition's name, as [`set`](Self::set) takes it, and
            /// the loop it acts in.
            pub const NAMES: &'static [(&'static str, Acts)] =
                &[$((stringify!($name), Acts::$acts),)*];

            /// Switches the addition called `name` on or off.
            pub fn set(&mut self, name: &str, on: bool) -> Result<(), UnknownAddition> {
                let switch = match name {
                    $(stringify!($name) => &mut self.$name,)*
                    _ => return Err(UnknownAddition),
                };
                *switch = on;
                Ok(())
            }
        }
    };
}

additions! {
    /// The learner: a pulse far beyond the recent ones is a step of the
    /// star, settled over and measured out of the observations
    /// (`mount::guiding::bump`). Off: learned as it comes.
    bump: Firmware,
    /// The learner: a guider whose pulses swing (anti-correlated two
    /// frames apart) is learned with a smaller part of each pulse
    /// (`mount::guiding::pulse_weight`). Off: every pulse in full.
    pulse_weight: Firmware,
    /// The learner: the share of each RA pulse the firmware carries out,
    /// earned from the pulses' correlation (`mount::guiding::earned_share`).
    /// Off: every pulse in full.
    earned_share: Firmware,
    /// The learner: the share is earned, and a share saved with a
    /// restored model used, only while the model is trusted in full. Off:
    /// from the first measured pulses. Measured across a power cycle, where
    /// it pays (a restored model's first frames); on a cold start it acts
    /// alike.
    trusted_gate: Restore,
    /// The learner: a feed-forward lasts three of the guider's frames. Off:
    /// one.
    feed_forward_horizon: Firmware,
    /// The learner: the share of the feed-forward applied, earned against
    /// a shadow of the guider alone (`mount::guiding::feed_forward_weight`).
    /// Off: the feed-forward in full.
    feed_forward_weight: Firmware,
    /// The learner: the feed-forward weight's windows (its means, the
    /// frames before it moves) last no longer than at 2 s frames, as the
    /// trust's do with `trust_by_time`; behind longer frames their counts
    /// are cut in proportion (`mount::guiding::feed_forward_weight`). Off:
    /// the same counts whatever the frames' length.
    weight_by_time: Firmware,
    /// The learner: the share and the pulse weight are saved with the
    /// model and taken back with it. Off: a restored learner starts with
    /// every pulse in full, to earn them again.
    saved_share: Restore,
    /// The guiding: a guider's calibration recognised from its equal
    /// pulses, its frames not learned (`mount::guiding::calibration`;
    /// reached through `ControlLoop::start_with`). Off: learned as guide
    /// frames.
    calibration_watch: Firmware,
    /// The learner: a calibration's first steps, taken for guide pulses
    /// until it is recognised, are taken back out of the earned share
    /// (`mount::guiding::earned_share`). Off: two of them in a row bring
    /// full pulses, and the share is earned again after each calibration.
    calibration_share: Firmware,
    /// The learner: where the guide frames after a calibration come more
    /// than 1.5 times as far apart as before it, the share earned before
    /// is scaled by the square root of the intervals' ratio and earned on
    /// from there (`mount::guiding::earned_share`). Off: full pulses, the
    /// share earned again.
    share_to_interval: Firmware,
    /// The model: an inference's subset leaves out the cells without a
    /// measurement (a re-pointing's gap, clouds, a calibration), which the
    /// short kernels rank high near the frame though they carry nothing
    /// (`model::gp::subset`). Off: every cell competes, as in the paper.
    measured_subset: Model,
    /// Stage discovery: a candidate must be a local maximum of the
    /// spectrum, not the skirt of a notched line's main lobe
    /// (`model::spectral::discovery`). Off: the strongest bin with power
    /// that the notches and the guard leave, as in the paper.
    local_maximum: Model,
    /// Stage discovery: a found stage whose smoothed amplitude ratio stays
    /// below half the gate's lower threshold for 100 frames is given up and
    /// searched for again. Off: a found stage is kept.
    drop_faded: Model,
    /// Stage discovery: the search waits until the worm's period has
    /// roughly converged (0.3), and the amplitude ratio that drives a gate
    /// is smoothed with weight 0.03 per frame. Off: the search runs from
    /// the first spectrum, and the ratio's weight is 0.1 (the period
    /// tracker's, the setting before the addition).
    convergence_gate: Model,
    /// Stage discovery: a peak in the notch or guard of a known period's
    /// harmonic (k >= 2) is admitted once the data resolves it from that
    /// harmonic. Off: refused whatever the span, as in the paper.
    near_harmonic: Model,
    /// Stage discovery: a found stage follows its line past the later
    /// stages that carry no weight yet (an ungated third stage's period
    /// does not notch the second's line). Off: every found stage's period
    /// is notched and guarded, as for a new stage.
    follow_past: Model,
    /// Stage discovery: a found stage moves up to twice its period where
    /// that line is its fundamental (a line of its own with at least half
    /// its power). Off: it stays.
    fundamental_move: Model,
    /// Stage discovery: a found stage follows its peak in a band of 10 %
    /// around its own period (where the move to its fundamental is looked
    /// at). Off: every spectrum it takes the strongest admissible peak of
    /// the search band, as when it was found, and never moves to its
    /// fundamental.
    follow_band: Model,
    /// Stage discovery on the mount's exact grid (`exact_cells`): a peak
    /// is a line only where its power stands
    /// [`NOISE_FLOOR`](crate::model::spectral::discovery::NOISE_FLOOR)
    /// times above the median of the spectrum around it, so that the
    /// seeing noise alone finds no stage (the reference's averaging
    /// smooths it across cells). Off: the strongest admissible peak is a
    /// stage's, however weak.
    noise_floor: Firmware,
    /// The guider: with more than one stage, the reference blend is
    /// weighted by the trust the model earns in shadow loops, the model's
    /// against the reactive law alone (`model::guider::trust`). Off: the
    /// reference blend as it is (INDIGO's).
    trust_shadows: Model,
    /// The guider: with more than one stage, shadows of the two reactive
    /// laws choose between them, proportional control in place of the
    /// hysteresis term while it is measured better, and the model's trust
    /// is measured against the better (`model::guider::trust`). Off: the
    /// reference's hysteresis term always, and the trust against it.
    law_choice: Model,
    /// The guider: when the model's stages change (a stage found, given
    /// up, or moved by more than 5 %), the trust's score of the old model
    /// counts as 200 frames, no more (`model::guider::trust`). Off: the new
    /// model inherits the old one's whole score.
    trust_rescore: Model,
    /// The guider: the trust's windows (its score, the frames before the
    /// weight or the law may move) last no longer than at 2 s frames;
    /// behind longer frames their counts are cut in proportion
    /// (`model::guider::trust`). Off: the same counts whatever the frames'
    /// length.
    trust_by_time: Model,
    /// The guider: the mount's grid averages each cell exactly, the mean
    /// over it of the straight lines between consecutive frames, so that
    /// a cell stands for its centre whatever the frames' times
    /// (`GuiderConfig::prediction_at_gear_time`, `grid::Averaging`). Off:
    /// the reference's averaging, whose cells sit before their centres by
    /// an amount that moves with the frames' phase against the cells.
    exact_cells: Firmware,
    /// The guider, on the mount's exact grid: while the steps between
    /// consecutive frames are anti-correlated, a measured frame more than
    /// half a cell and at most a cell after the one before counts as the
    /// mean of the two at the middle of their times
    /// (`model::gp::grid::pairs`), so that the swing of a loop that
    /// overcorrects (a period of two frames) is not passed on by the
    /// cells at an alias as gear error. Off: each frame as it is.
    paired_frames: Firmware,
    /// The guider: a frame off the clock by more than 600 s is held, and
    /// the next frame that continues it moves the clock there (a paused
    /// guider, a reset clock; `Guider::accept_time`). Off: such a frame is
    /// refused like any other off the clock, and a clock that jumped is
    /// refused until it comes back.
    clock_hold: Model,
    /// The spectrum: a peak's period from the parabola through the
    /// logarithm of its bins' power (`model::spectral::spectrum`), which
    /// the window's main lobe follows closely, so the worm's period is
    /// right to a few hundredths of a second and a long jump's placement
    /// keeps its phase. Off: the parabola through the power, as in the
    /// paper, off by up to 0.3 s on a worm of 432 s.
    log_power_peak: Model,
    /// The model in the firmware: the worm's period is the mount's
    /// configured one, which the step rate turns the worm at
    /// (`GuiderConfig::worm_period_known`, set by the learner); the worm's
    /// tracker keeps it unless the spectrum's strongest line is a faster
    /// one resolved from it (a stage louder than the worm). Off: tracked
    /// from the spectrum as in the paper, which the night's gaps and
    /// re-pointed data pull off by up to 1 %.
    configured_worm: Firmware,
    /// The restore and a jump: a new stage, or a stage's move to another
    /// line, beside another's harmonic is admitted once the data learned
    /// since the placement resolves it (the placed data's phases are only
    /// as right as the placement, and a line across it shows as a split
    /// peak; `Guider::resolving_spans`); a stage's own line is followed
    /// across the whole grid. Off: once the whole grid's span resolves it.
    one_piece: Restore,
    /// The restore: with every stage's phase known, the saved data is
    /// placed where the stages' phases, weighted by their gates, are least
    /// off within eight worm periods (`model::guider::restore`,
    /// `placement`). Off: at the worm's phase within one worm period.
    placement_search: Restore,
    /// The restore: with the phase unknown, the saved data is matched
    /// against the first half worm period of new data and placed at the
    /// phase found (`Restore::phase_search_pending`). Off: the saved data
    /// is dropped, the stages' periods and gates kept.
    phase_search: Restore,
    /// The restore: with the worm's phase known (an index), each other
    /// stage's share of the saved data is taken out and put back at the
    /// phase the new data shows (`restore::harmonics`). Off: the saved data
    /// placed at the worm's phase, the other stages left out of the fit
    /// until a search of the whole at that phase, a quarter worm period on.
    stage_phases: Restore,
    /// The restore: with the other stages' shares taken out of the saved
    /// data (`stage_phases`), the model predicts nothing until their first
    /// search puts them back: a fit of the worm alone takes their error in
    /// the new data for a level and a trend (`PhaseSearch::blocks`). Off:
    /// the worm's share predicts from the first frame.
    stage_wait: Restore,
    /// The restore: the stages' shares taken out of the saved data are
    /// fitted with the newest cells weighing most, as the shortest fitted
    /// stage's envelope weighs them (`restore::harmonics`): a stage that
    /// faded over the saved span is put back as it was last. Off: every
    /// saved cell alike, each stage at its mean over the span.
    recent_shares: Restore,
    /// The restore: once the stages are put back (at the phases the first
    /// search finds), their phases are searched again over all the new
    /// data at each new measured cell, up to half a worm period of it, and
    /// each stage moved where the data picks its phase clearly. Off: they
    /// stay where the first search put them.
    phase_refine: Restore,
    /// A jump: after a slew whose placement reaches so far beyond the
    /// data that the tracked periods' error leaves a stage's phase
    /// uncertain by an eighth of its period (a meridian flip), that
    /// stage's phase is searched in the new data as `phase_refine`
    /// searches a restored one, and the stage moved where the data picks
    /// it clearly. Off: the stages stay where the placement put them.
    slew_refine: Restore,
    /// The restore: at the first measured frame the restored (or, after
    /// a slew, re-placed) data moves to meet the measured gear error's
    /// level (the mount's reconstruction starts again from 0 each night;
    /// after a slew the guider centres the star anew). Off: it stays at
    /// the saved level.
    level_match: Restore,
    /// A jump: the gap the placement after a slew leaves (the gears
    /// turned through it at the slew's rate, unobserved) is marked
    /// (`Grid::set_dark`), and the stages' envelopes skip it (they count
    /// observed time, `Kernel::projection_observed`). Off: the gap ages
    /// the stages as time observed does.
    observed_envelope: Firmware,
}

impl Additions {
    /// Where the addition called `name` acts (`None` for a name not known).
    pub fn acts(name: &str) -> Option<Acts> {
        Self::NAMES
            .iter()
            .find(|(n, _)| *n == name)
            .map(|&(_, a)| a)
    }
}

impl Default for Additions {
    fn default() -> Self {
        Self::ALL
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_name_switches_its_own_addition_and_no_other() {
        for &(name, _) in Additions::NAMES {
            let mut a = Additions::ALL;
            a.set(name, false).unwrap();
            assert_ne!(a, Additions::ALL, "{name}");
            for &(other, _) in Additions::NAMES.iter().filter(|&&(o, _)| o != name) {
                let mut b = Additions::ALL;
                b.set(other, false).unwrap();
                assert_ne!(a, b, "{name} and {other}");
            }
            a.set(name, true).unwrap();
            assert_eq!(a, Additions::ALL, "{name}");
        }
        let mut a = Additions::ALL;
        assert_eq!(a.set("no_such", false), Err(UnknownAddition));
        assert_eq!(a, Additions::ALL);
    }

    #[test]
    fn each_addition_acts_in_its_own_loop() {
        let firmware = [
            "bump",
            "pulse_weight",
            "earned_share",
            "feed_forward_horizon",
            "feed_forward_weight",
            "weight_by_time",
            "calibration_watch",
            "calibration_share",
            "share_to_interval",
            "exact_cells",
            "paired_frames",
            "noise_floor",
            "configured_worm",
            "observed_envelope",
        ];
        let restore = [
            "one_piece",
            "placement_search",
            "phase_search",
            "stage_phases",
            "stage_wait",
            "recent_shares",
            "phase_refine",
            "slew_refine",
            "level_match",
            "saved_share",
            "trusted_gate",
        ];
        for &(name, acts) in Additions::NAMES {
            let want = if firmware.contains(&name) {
                Acts::Firmware
            } else if restore.contains(&name) {
                Acts::Restore
            } else {
                Acts::Model
            };
            assert_eq!(acts, want, "{name}");
            assert_eq!(Additions::acts(name), Some(acts));
        }
        assert_eq!(Additions::acts("measured_subset"), Some(Acts::Model));
        assert_eq!(Additions::acts("no_such"), None);
    }
}
