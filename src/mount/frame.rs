//! What the guiding, the learner and the loop hand each other: step rates,
//! guide frames (gear-error observations) and the feed-forward.

/// The step rates to set now.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Rates {
    /// RA motor, steps/s, in [0, max]; forward (the tracking direction).
    pub ra_steps_per_s: f32,
    /// Dec motor, steps/s, signed: positive = north; |rate| <= max.
    pub dec_steps_per_s: f32,
}

/// What a frame tells the model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FrameKind {
    /// The guider was heard: [`Frame::gear_error_arcsec`] is an observation.
    Measured,
    /// The guider has been silent for more than `silence_frames`: nothing
    /// was measured; the model only keeps its clock.
    Unmeasured,
    /// The frame's RA pulse was a dither of this many arcsec (signed); not
    /// learned, and the model settles.
    Dither { amount_arcsec: f32 },
    /// The guider was calibrating (`crate::mount::guiding::calibration`):
    /// its pulses measured the mount, not the gear; not learned.
    Calibration,
    /// The command port moved the RA axis (or stopped its tracking) during
    /// the frame: nothing measured, and gear time ran ahead by the slew.
    /// The model keeps what it learned and places it before the next frame.
    Moved,
}

/// One guide frame: a gear-error observation for the learner.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// Gear time of the frame (seconds; see [`crate::mount::guiding`]): the
    /// RA pulse's start, or `previous frame + cadence` for a filled frame.
    pub gear_time_s: f64,
    /// Gear time since the previous frame, seconds (0 for the first).
    pub interval_s: f32,
    pub kind: FrameKind,
    /// The observation, arcsec: `applied_arcsec + pulse_arcsec /
    /// aggressiveness` for a measured frame; `applied_arcsec` otherwise.
    pub gear_error_arcsec: f32,
    /// Mean applied correction C over the interval since the previous frame
    /// (arcsec; the first frame: C at the frame).
    pub applied_arcsec: f32,
    /// Signed correction the frame's RA pulse asked for (duration x guide
    /// rate, arcsec; RA+ positive); 0 for a filled frame.
    pub pulse_arcsec: f32,
    /// Made by the cadence, not by a pulse.
    pub filled: bool,
}

/// The learner's feed-forward: an extra RA rate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FeedForward {
    /// Arcsec of RA per second of gear time; positive = faster.
    pub rate_arcsec_per_s: f32,
    /// Gear time of the frame it was computed for (seconds).
    pub from_gear_s: f64,
    /// Not applied beyond this gear time (seconds) unless replaced.
    pub until_gear_s: f64,
    /// How much of an RA guide pulse to carry out while this feed-forward
    /// is in effect.
    pub pulse_share: PulseShare,
}

impl FeedForward {
    /// No feed-forward.
    pub const NONE: FeedForward = FeedForward {
        rate_arcsec_per_s: 0.0,
        from_gear_s: 0.0,
        until_gear_s: 0.0,
        pulse_share: PulseShare::FULL,
    };
}

/// The share of an RA guide pulse the firmware carries out, as the learner
/// measured it (`crate::mount::guiding::earned_share`): a pulse is carried out
/// at `fraction` of the guide rate up to `up_to_arcsec` of correction
/// asked; a longer one is carried out in full, the part held back made up
/// at once.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PulseShare {
    /// In (0, 1]; 1: the pulse in full.
    pub fraction: f32,
    /// Arcsec of correction (pulse duration x guide rate), >= 0.
    pub up_to_arcsec: f32,
}

impl PulseShare {
    /// Every pulse in full.
    pub const FULL: PulseShare = PulseShare {
        fraction: 1.0,
        up_to_arcsec: 0.0,
    };
}
