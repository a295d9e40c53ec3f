//! The additions around the paper's model, each switchable by name.
//!
//! Each was added to mend one case or one log; a simulator turns any one
//! off (by its name, [`Additions::set`]) to measure what it is worth on
//! mounts it was not tuned on. All are on by default: the firmware runs
//! them all. `GuiderConfig::additions` carries them to the model and to the
//! learner around it (`crate::mount::learner`), which reads its own here;
//! the loop's fast part takes them at its start
//! (`crate::control_loop::ControlLoop::start_with`).

/// The switches, all on by default ([`Additions::ALL`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Additions {
    /// The learner: a pulse far beyond the recent ones is a step of the
    /// star, settled over and measured out of the observations
    /// (`mount::guiding::bump`). Off: learned as it comes.
    pub bump: bool,
    /// The learner: a guider whose pulses swing (anti-correlated two
    /// frames apart) is learned with a smaller part of each pulse
    /// (`mount::guiding::pulse_weight`). Off: every pulse in full.
    pub pulse_weight: bool,
    /// The learner: the share of each RA pulse the firmware carries out,
    /// earned from the pulses' correlation (`mount::guiding::earned_share`).
    /// Off: every pulse in full.
    pub earned_share: bool,
    /// The learner: the share is earned only while the model is trusted in
    /// full. Off: from the first measured pulses.
    pub trusted_gate: bool,
    /// The learner: a feed-forward lasts three of the guider's frames. Off:
    /// one.
    pub feed_forward_horizon: bool,
    /// The learner: the share of the feed-forward applied, earned against
    /// a shadow of the guider alone (`mount::guiding::feed_forward_weight`).
    /// Off: the feed-forward in full.
    pub feed_forward_weight: bool,
    /// The learner: the share and the pulse weight are saved with the
    /// model and taken back with it. Off: a restored learner starts with
    /// every pulse in full, to earn them again.
    pub saved_share: bool,
    /// The guiding: a guider's calibration recognised from its equal
    /// pulses, its frames not learned (`mount::guiding::calibration`;
    /// reached through `ControlLoop::start_with`). Off: learned as guide
    /// frames.
    pub calibration_watch: bool,
    /// The model: an inference's subset leaves out the cells without a
    /// measurement (a re-pointing's gap, clouds, a calibration), which the
    /// short kernels rank high near the frame though they carry nothing
    /// (`model::gp::subset`). Off: every cell competes, as in the paper.
    pub measured_subset: bool,
    /// Stage discovery: a candidate must be a local maximum of the
    /// spectrum, not the skirt of a notched line's main lobe
    /// (`model::spectral::discovery`). Off: the strongest bin with power
    /// that the notches and the guard leave, as in the paper.
    pub local_maximum: bool,
    /// Stage discovery: notches 6 % wide in frequency, as the
    /// commensurability guard, so that C5's 155 s stage beside the worm's
    /// 144 s division is seen. Off: the paper's 8 %.
    pub narrow_notch: bool,
    /// Stage discovery: a found stage whose smoothed amplitude ratio stays
    /// below half the gate's lower threshold for 100 frames is given up and
    /// searched for again. Off: a found stage is kept.
    pub drop_faded: bool,
    /// Stage discovery: the search waits until the worm's period has
    /// roughly converged (0.3), and the amplitude ratio that drives a gate
    /// is smoothed with weight 0.03 per frame. Off: the search runs from
    /// the first spectrum, and the ratio's weight is 0.1 (the period
    /// tracker's, the setting before the addition).
    pub convergence_gate: bool,
    /// Stage discovery: a peak in the notch or guard of a known period's
    /// harmonic (k >= 2) is admitted once the data resolves it from that
    /// harmonic. Off: refused whatever the span, as in the paper.
    pub near_harmonic: bool,
    /// Stage discovery: a found stage whose gate is not fully open moves to
    /// twice or half its period where that line has twice its power. Off:
    /// it stays.
    pub octave_move: bool,
    /// Stage discovery: a found stage follows its line past the later
    /// stages that carry no weight yet (an ungated third stage's period
    /// does not notch the second's line). Off: every found stage's period
    /// is notched and guarded, as for a new stage.
    pub follow_past: bool,
    /// Stage discovery: a found stage moves up to twice its period where
    /// that line is its fundamental (a line of its own with at least half
    /// its power). Off: it stays.
    pub fundamental_move: bool,
    /// Stage discovery: a found stage follows its peak in a band of 10 %
    /// around its own period (where the octave moves are looked at). Off:
    /// every spectrum it takes the strongest admissible peak of the search
    /// band, as when it was found, and never moves to an octave.
    pub follow_band: bool,
    /// The guider: with more than one stage, the reference blend is
    /// weighted by the trust the model earns in shadow loops, the model's
    /// against the reactive law alone (`model::guider::trust`). Off: the
    /// reference blend as it is (INDIGO's).
    pub trust_shadows: bool,
    /// The guider: with more than one stage, shadows of the two reactive
    /// laws choose between them, proportional control in place of the
    /// hysteresis term while it is measured better, and the model's trust
    /// is measured against the better (`model::guider::trust`). Off: the
    /// reference's hysteresis term always, and the trust against it.
    pub law_choice: bool,
    /// The guider: when the model's stages change (a stage found, given
    /// up, or moved by more than 5 %), the trust's score of the old model
    /// counts as 200 frames, no more (`model::guider::trust`). Off: the new
    /// model inherits the old one's whole score.
    pub trust_rescore: bool,
    /// The guider: the mount's feed-forward reads the model the grid's lag
    /// later, where the gear error's own time lies
    /// (`GuiderConfig::prediction_at_gear_time`, `Grid::lag_s`). Off: at
    /// the grid's time, the reference's timing.
    pub grid_lag: bool,
    /// The guider: a frame off the clock by more than 600 s is held, and
    /// the next frame that continues it moves the clock there (a paused
    /// guider, a reset clock; `Guider::accept_time`). Off: such a frame is
    /// refused like any other off the clock, and a clock that jumped is
    /// refused until it comes back.
    pub clock_hold: bool,
    /// The restore: with every stage's phase known, the saved data is
    /// placed where the stages' phases, weighted by their gates, are least
    /// off within eight worm periods (`model::guider::restore`,
    /// `placement`). Off: at the worm's phase within one worm period.
    pub placement_search: bool,
    /// The restore: with the phase unknown, the saved data is matched
    /// against the first half worm period of new data and placed at the
    /// phase found (`Restore::phase_search_pending`). Off: the saved data
    /// is dropped, the stages' periods and gates kept.
    pub phase_search: bool,
    /// The restore: with the worm's phase known (an index), each other
    /// stage's share of the saved data is taken out and put back at the
    /// phase the new data shows (`restore::harmonics`). Off: the saved data
    /// placed at the worm's phase, the other stages left out of the fit
    /// until a search of the whole at that phase, a quarter worm period on.
    pub stage_phases: bool,
    /// The restore: the stages' phases are searched again at each new cell
    /// until an F-test picks each one clearly, up to half a worm period.
    /// Off: the first search places them.
    pub phase_retry: bool,
    /// The restore: the spectrum is not read until the data resolves the
    /// restored stages (2.5 beats) or fills the grid, the stages held as
    /// saved (`SpectrumHold`). Off: read from the first frame after the
    /// placement.
    pub spectrum_hold: bool,
    /// The restore: at the first frame the restored data moves to meet the
    /// measured gear error's level (the mount's reconstruction starts
    /// again from 0 each night). Off: it stays at the saved level.
    pub level_match: bool,
}

/// A name [`Additions::set`] does not know.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct UnknownAddition;

impl Additions {
    /// Every addition on: the firmware's model.
    pub const ALL: Additions = Additions {
        bump: true,
        pulse_weight: true,
        earned_share: true,
        trusted_gate: true,
        feed_forward_horizon: true,
        feed_forward_weight: true,
        saved_share: true,
        calibration_watch: true,
        measured_subset: true,
        local_maximum: true,
        narrow_notch: true,
        drop_faded: true,
        convergence_gate: true,
        near_harmonic: true,
        octave_move: true,
        follow_past: true,
        fundamental_move: true,
        follow_band: true,
        trust_shadows: true,
        law_choice: true,
        trust_rescore: true,
        grid_lag: true,
        clock_hold: true,
        placement_search: true,
        phase_search: true,
        stage_phases: true,
        phase_retry: true,
        spectrum_hold: true,
        level_match: true,
    };

    /// Each addition's name, as [`set`](Self::set) takes it.
    pub const NAMES: [&'static str; 29] = [
        "bump",
        "pulse_weight",
        "earned_share",
        "trusted_gate",
        "feed_forward_horizon",
        "feed_forward_weight",
        "saved_share",
        "calibration_watch",
        "measured_subset",
        "local_maximum",
        "narrow_notch",
        "drop_faded",
        "convergence_gate",
        "near_harmonic",
        "octave_move",
        "follow_past",
        "fundamental_move",
        "follow_band",
        "trust_shadows",
        "law_choice",
        "trust_rescore",
        "grid_lag",
        "clock_hold",
        "placement_search",
        "phase_search",
        "stage_phases",
        "phase_retry",
        "spectrum_hold",
        "level_match",
    ];

    /// Switches the addition called `name` on or off.
    pub fn set(&mut self, name: &str, on: bool) -> Result<(), UnknownAddition> {
        let switch = match name {
            "bump" => &mut self.bump,
            "pulse_weight" => &mut self.pulse_weight,
            "earned_share" => &mut self.earned_share,
            "trusted_gate" => &mut self.trusted_gate,
            "feed_forward_horizon" => &mut self.feed_forward_horizon,
            "feed_forward_weight" => &mut self.feed_forward_weight,
            "saved_share" => &mut self.saved_share,
            "calibration_watch" => &mut self.calibration_watch,
            "measured_subset" => &mut self.measured_subset,
            "local_maximum" => &mut self.local_maximum,
            "narrow_notch" => &mut self.narrow_notch,
            "drop_faded" => &mut self.drop_faded,
            "convergence_gate" => &mut self.convergence_gate,
            "near_harmonic" => &mut self.near_harmonic,
            "octave_move" => &mut self.octave_move,
            "follow_past" => &mut self.follow_past,
            "fundamental_move" => &mut self.fundamental_move,
            "follow_band" => &mut self.follow_band,
            "trust_shadows" => &mut self.trust_shadows,
            "law_choice" => &mut self.law_choice,
            "trust_rescore" => &mut self.trust_rescore,
            "grid_lag" => &mut self.grid_lag,
            "clock_hold" => &mut self.clock_hold,
            "placement_search" => &mut self.placement_search,
            "phase_search" => &mut self.phase_search,
            "stage_phases" => &mut self.stage_phases,
            "phase_retry" => &mut self.phase_retry,
            "spectrum_hold" => &mut self.spectrum_hold,
            "level_match" => &mut self.level_match,
            _ => return Err(UnknownAddition),
        };
        *switch = on;
        Ok(())
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
        for name in Additions::NAMES {
            let mut a = Additions::ALL;
            a.set(name, false).unwrap();
            assert_ne!(a, Additions::ALL, "{name}");
            for other in Additions::NAMES.iter().filter(|&&o| o != name) {
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
}
