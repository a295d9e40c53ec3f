//! The mount's configuration: one documented type, checked once at start-up.
//!
//! [`MountConfig`] holds the numbers that describe a mount (its drive
//! trains, the step-generator tick, the ST4 timing and what the firmware
//! assumes about the guider). [`MountConfig::validate`] checks every value
//! against what is physical (the limits are this module's constants), and
//! the values derived from them, and returns a [`Mount`] with the derived
//! constants, or the first value it refuses as a [`ConfigError`]: the
//! [`Field`] by name, its value and the rule it breaks, which the firmware
//! logs at start-up.
//!
//! The derived constants are computed once, in `f64`: a `u32` step count
//! above 2^24 is not exact in `f32`, and products such as arcsec per step
//! would otherwise be rounded twice. The getters return the stored `f32`
//! values, so no (soft-float) `f64` runs after start-up.

use core::fmt;

/// The sky's rate in RA: arcseconds of RA per second of time
/// (360 deg / one sidereal day of 86 164.0905 s).
pub const SIDEREAL_ARCSEC_PER_S: f64 = 15.041_068_6;

/// One sidereal day in seconds.
pub const SIDEREAL_DAY_S: f64 = 86_164.090_5;

/// Everything the firmware needs to know about the mount.
///
/// `Default` is an example EQ6-class mount (see [`MountConfig::default`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MountConfig {
    /// Microsteps of the RA motor per revolution of the RA worm
    /// (motor full steps x microstepping x gear/belt ratio between motor
    /// and worm). Must be > 0.
    pub ra_steps_per_worm_turn: u32,
    /// Seconds per worm revolution at the sidereal rate: one sidereal day
    /// (86 164.09 s) divided by the number of teeth of the worm wheel
    /// (180 teeth: 478.69 s; 144 teeth: 598.36 s). Finite, > 0. The
    /// learner's model keeps it as the worm's period unless a faster
    /// line is louder (the addition `configured_worm`): set the wheel the
    /// mount has.
    pub worm_period_s: f32,
    /// Microsteps of the Dec motor per degree of Dec. Finite, > 0.
    pub dec_steps_per_degree: f32,
    /// ST4 guide rate as a fraction of the sidereal rate, in (0, 1]
    /// (default 0.5: RA+ drives at 1.5x sidereal, RA- at 0.5x).
    pub guide_rate_sidereal: f32,
    /// Highest rate the step generator must produce on either axis, in
    /// multiples of the sidereal rate (default 8). At least
    /// 1 + `guide_rate_sidereal` (so that RA+ guiding fits), and low enough
    /// that both axes stay at or below one step per two timer ticks.
    pub max_rate_sidereal: f32,
    /// Step-generator timer tick in Hz (default 50 000). A step needs a high
    /// and a low tick, so an axis makes at most `step_tick_hz / 2` steps/s.
    pub step_tick_hz: u32,
    /// ST4 debounce in microseconds: a line level that lasts less than this
    /// is a glitch (default 1 000 = 1 ms). > 0 and below `pulse_cap_us`.
    pub glitch_us: u32,
    /// Longest accepted guide pulse in microseconds; a longer one is cut
    /// here (default 10 000 000 = 10 s). > 0.
    pub pulse_cap_us: u32,
    /// Guide cycle in seconds assumed when the guider sends no pulse
    /// (default 2.0); a guider whose pulses show a cycle more than half as
    /// long again is followed at its own. Finite, > 0.
    pub guide_cadence_s: f32,
    /// Assumed aggressiveness of the guider (the fraction of the measured
    /// error it corrects per frame), in (0, 1] (default 0.7, PHD2's
    /// default hysteresis algorithm).
    pub guider_aggressiveness: f32,
    /// A pulse longer than this many microseconds is a dither, not a
    /// correction (default 3 000 000 = 3 s). Above `glitch_us`, below
    /// `pulse_cap_us`.
    pub dither_threshold_us: u32,
    /// Guide cycles without any pulse after which learning freezes
    /// (default 15). > 0.
    pub silence_frames: u32,
    /// The least share of an RA guide pulse the firmware carries out once
    /// it has measured that the pulses mostly react to noise (behind a
    /// trusted model; `crate::mount::guiding::earned_share`), in [0.1, 1]
    /// (default 0.2). 1 carries out every pulse in full.
    pub least_pulse_share: f32,
}

impl Default for MountConfig {
    /// An example EQ6-class mount (both axes alike):
    ///
    /// - motor: 0.9 deg stepper, 400 full steps per turn, 64 microsteps
    ///   (25 600 microsteps per motor turn);
    /// - belt 48:16 (3:1) from motor to worm: 76 800 microsteps per worm turn;
    /// - 180-tooth worm wheel: worm period 86 164.09 s / 180 = 478.689 s,
    ///   13 824 000 microsteps per axis turn, 38 400 per degree,
    ///   0.093 75 arcsec per microstep;
    /// - sidereal tracking: 76 800 / 478.689 = 160.438 steps/s;
    ///   at 8x sidereal 1 283.5 steps/s, far below the 25 000 steps/s the
    ///   50 kHz tick allows.
    fn default() -> Self {
        MountConfig {
            ra_steps_per_worm_turn: 400 * 64 * 3,
            worm_period_s: (SIDEREAL_DAY_S / 180.0) as f32,
            dec_steps_per_degree: (400 * 64 * 3 * 180 / 360) as f32,
            guide_rate_sidereal: 0.5,
            max_rate_sidereal: 8.0,
            step_tick_hz: 50_000,
            glitch_us: 1_000,
            pulse_cap_us: 10_000_000,
            guide_cadence_s: 2.0,
            guider_aggressiveness: 0.7,
            dither_threshold_us: 3_000_000,
            silence_frames: 15,
            least_pulse_share: 0.2,
        }
    }
}

/// A field of [`MountConfig`], by name.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Field {
    RaStepsPerWormTurn,
    WormPeriodS,
    DecStepsPerDegree,
    GuideRateSidereal,
    MaxRateSidereal,
    StepTickHz,
    GlitchUs,
    PulseCapUs,
    GuideCadenceS,
    GuiderAggressiveness,
    DitherThresholdUs,
    SilenceFrames,
    LeastPulseShare,
}

impl Field {
    pub const ALL: [Field; 13] = [
        Field::RaStepsPerWormTurn,
        Field::WormPeriodS,
        Field::DecStepsPerDegree,
        Field::GuideRateSidereal,
        Field::MaxRateSidereal,
        Field::StepTickHz,
        Field::GlitchUs,
        Field::PulseCapUs,
        Field::GuideCadenceS,
        Field::GuiderAggressiveness,
        Field::DitherThresholdUs,
        Field::SilenceFrames,
        Field::LeastPulseShare,
    ];

    /// The field's name in [`MountConfig`].
    pub fn name(self) -> &'static str {
        match self {
            Field::RaStepsPerWormTurn => "ra_steps_per_worm_turn",
            Field::WormPeriodS => "worm_period_s",
            Field::DecStepsPerDegree => "dec_steps_per_degree",
            Field::GuideRateSidereal => "guide_rate_sidereal",
            Field::MaxRateSidereal => "max_rate_sidereal",
            Field::StepTickHz => "step_tick_hz",
            Field::GlitchUs => "glitch_us",
            Field::PulseCapUs => "pulse_cap_us",
            Field::GuideCadenceS => "guide_cadence_s",
            Field::GuiderAggressiveness => "guider_aggressiveness",
            Field::DitherThresholdUs => "dither_threshold_us",
            Field::SilenceFrames => "silence_frames",
            Field::LeastPulseShare => "least_pulse_share",
        }
    }

    /// The field called `name` (its name in [`MountConfig`], as bytes).
    pub fn from_name(name: &[u8]) -> Option<Field> {
        Field::ALL.into_iter().find(|f| f.name().as_bytes() == name)
    }
}

/// A field's value: a count or a real number.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Value {
    Count(u32),
    Real(f32),
}

impl fmt::Display for Value {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Value::Count(v) => write!(f, "{v}"),
            Value::Real(v) => write!(f, "{v}"),
        }
    }
}

/// A refused configuration: the field, its value and the rule it breaks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConfigError {
    pub field: Field,
    pub value: Value,
    /// What the value must be, in words (the limits are the constants of
    /// this module).
    pub rule: &'static str,
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "mount config: {} = {}: {}",
            self.field.name(),
            self.value,
            self.rule
        )
    }
}

// What is physical. A value outside these limits is a typo or a unit
// mistake, and the firmware refuses it rather than drive a motor with it.

/// The coarsest step on either axis, arcsec: coarser cannot follow the
/// guide corrections of about an arcsecond that the model exists for, and a
/// sidereal rate below one step per second does not track smoothly.
pub const MAX_ARCSEC_PER_STEP: f64 = 15.0;
/// Shortest worm period, s: a worm wheel of at most 1 436 teeth. The longest
/// is one sidereal day (one tooth).
pub const MIN_WORM_PERIOD_S: f32 = 60.0;
/// Guide rates, in multiples of sidereal: PHD2 and INDI offer 0.1 to 1.
pub const GUIDE_RATE_RANGE: (f32, f32) = (0.1, 1.0);
/// Step tick, Hz: below 1 kHz a sidereal step train jitters by a
/// millisecond; above 200 kHz the interrupt alone would eat the CPU.
pub const STEP_TICK_RANGE_HZ: (u32, u32) = (1_000, 200_000);
/// Longest debounce, µs: guide pulses can be as short as 10 ms.
pub const MAX_GLITCH_US: u32 = 10_000;
/// Longest pulse cap, µs: the longest LX200 pulse (60 s).
pub const MAX_PULSE_CAP_US: u32 = 60_000_000;
/// Guide cycle, s.
pub const GUIDE_CADENCE_RANGE_S: (f32, f32) = (0.1, 60.0);
/// The guider's aggressiveness: the firmware divides a pulse by it to
/// rebuild the error the guider saw, so a setting far below the guider's
/// real one multiplies every pulse into a false gear error (at 0.1 against
/// a real 0.7 the mount guides 21 times worse than the guider alone). PHD2
/// users run 0.4 to 1.0; its default is 0.7.
pub const AGGRESSIVENESS_RANGE: (f32, f32) = (0.3, 1.0);
/// Guide cycles of silence before learning freezes.
pub const SILENCE_FRAMES_RANGE: (u32, u32) = (1, 1_000);
/// The least share of a guide pulse carried out: below a tenth the loop
/// would barely follow what the model does not explain.
pub const LEAST_PULSE_SHARE_RANGE: (f32, f32) = (0.1, 1.0);

/// `lo <= v <= hi`; false for NaN.
fn within(v: f32, (lo, hi): (f32, f32)) -> bool {
    v >= lo && v <= hi
}

/// A validated configuration and the constants derived from it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mount {
    config: MountConfig,
    sidereal_ra_steps_per_s_f64: f64,
    sidereal_ra_steps_per_s: f32,
    arcsec_per_ra_step: f32,
    arcsec_per_dec_step: f32,
    guide_rate_arcsec_per_s: f32,
    guide_ra_steps_per_s: f32,
    guide_dec_steps_per_s: f32,
    max_ra_steps_per_s: f32,
    max_dec_steps_per_s: f32,
}

impl MountConfig {
    /// The value of `field`.
    pub fn get(&self, field: Field) -> Value {
        let c = self;
        match field {
            Field::RaStepsPerWormTurn => Value::Count(c.ra_steps_per_worm_turn),
            Field::WormPeriodS => Value::Real(c.worm_period_s),
            Field::DecStepsPerDegree => Value::Real(c.dec_steps_per_degree),
            Field::GuideRateSidereal => Value::Real(c.guide_rate_sidereal),
            Field::MaxRateSidereal => Value::Real(c.max_rate_sidereal),
            Field::StepTickHz => Value::Count(c.step_tick_hz),
            Field::GlitchUs => Value::Count(c.glitch_us),
            Field::PulseCapUs => Value::Count(c.pulse_cap_us),
            Field::GuideCadenceS => Value::Real(c.guide_cadence_s),
            Field::GuiderAggressiveness => Value::Real(c.guider_aggressiveness),
            Field::DitherThresholdUs => Value::Count(c.dither_threshold_us),
            Field::SilenceFrames => Value::Count(c.silence_frames),
            Field::LeastPulseShare => Value::Real(c.least_pulse_share),
        }
    }

    /// Sets `field` to `value` (not validated: [`MountConfig::validate`]
    /// the result). `Err` if the value is of the other kind than the
    /// field's (a real number for a count).
    pub fn set(&mut self, field: Field, value: Value) -> Result<(), Value> {
        let c = self;
        match (field, value) {
            (Field::RaStepsPerWormTurn, Value::Count(v)) => c.ra_steps_per_worm_turn = v,
            (Field::WormPeriodS, Value::Real(v)) => c.worm_period_s = v,
            (Field::DecStepsPerDegree, Value::Real(v)) => c.dec_steps_per_degree = v,
            (Field::GuideRateSidereal, Value::Real(v)) => c.guide_rate_sidereal = v,
            (Field::MaxRateSidereal, Value::Real(v)) => c.max_rate_sidereal = v,
            (Field::StepTickHz, Value::Count(v)) => c.step_tick_hz = v,
            (Field::GlitchUs, Value::Count(v)) => c.glitch_us = v,
            (Field::PulseCapUs, Value::Count(v)) => c.pulse_cap_us = v,
            (Field::GuideCadenceS, Value::Real(v)) => c.guide_cadence_s = v,
            (Field::GuiderAggressiveness, Value::Real(v)) => c.guider_aggressiveness = v,
            (Field::DitherThresholdUs, Value::Count(v)) => c.dither_threshold_us = v,
            (Field::SilenceFrames, Value::Count(v)) => c.silence_frames = v,
            (Field::LeastPulseShare, Value::Real(v)) => c.least_pulse_share = v,
            (_, other) => return Err(other),
        }
        Ok(())
    }

    /// `Ok` if `ok`, else the error for `field` breaking `rule`.
    fn require(&self, ok: bool, field: Field, rule: &'static str) -> Result<(), ConfigError> {
        if ok {
            Ok(())
        } else {
            Err(ConfigError {
                field,
                value: self.get(field),
                rule,
            })
        }
    }

    /// Checks every value and what follows from them (in field order; the
    /// first refused one is returned) and derives the constants.
    pub fn validate(&self) -> Result<Mount, ConfigError> {
        use Field::*;
        let c = self;
        c.require(
            c.ra_steps_per_worm_turn > 0,
            RaStepsPerWormTurn,
            "must be > 0",
        )?;
        c.require(
            within(c.worm_period_s, (MIN_WORM_PERIOD_S, SIDEREAL_DAY_S as f32)),
            WormPeriodS,
            "must be 60 s to one sidereal day (86164 s): a wheel of 1 to 1436 teeth",
        )?;
        c.require(
            c.dec_steps_per_degree.is_finite() && c.dec_steps_per_degree > 0.0,
            DecStepsPerDegree,
            "must be finite and > 0",
        )?;
        c.require(
            within(c.guide_rate_sidereal, GUIDE_RATE_RANGE),
            GuideRateSidereal,
            "must be 0.1 to 1 (x sidereal)",
        )?;
        c.require(
            c.max_rate_sidereal.is_finite() && c.max_rate_sidereal >= 1.0 + c.guide_rate_sidereal,
            MaxRateSidereal,
            "must be finite and at least 1 + guide_rate_sidereal",
        )?;
        c.require(
            (STEP_TICK_RANGE_HZ.0..=STEP_TICK_RANGE_HZ.1).contains(&c.step_tick_hz),
            StepTickHz,
            "must be 1000 to 200000 Hz",
        )?;

        // Derived rates, in f64 (see the module documentation). Every input
        // is finite and positive here, and the checks below bound them.
        let sidereal_ra = c.ra_steps_per_worm_turn as f64 / c.worm_period_s as f64;
        // Dec microsteps per second at the sidereal rate (arcsec/s -> deg/s).
        let sidereal_dec = SIDEREAL_ARCSEC_PER_S / 3600.0 * c.dec_steps_per_degree as f64;
        let arcsec_per_ra_step = SIDEREAL_ARCSEC_PER_S / sidereal_ra;
        let arcsec_per_dec_step = 3600.0 / c.dec_steps_per_degree as f64;
        c.require(
            arcsec_per_ra_step <= MAX_ARCSEC_PER_STEP,
            RaStepsPerWormTurn,
            "too few for the worm period: more than 15 arcsec per RA step",
        )?;
        c.require(
            arcsec_per_dec_step <= MAX_ARCSEC_PER_STEP,
            DecStepsPerDegree,
            "must be at least 240: more than 15 arcsec per Dec step",
        )?;
        // At most one step per two ticks; this also keeps the Q0.32
        // increment (rate / tick_hz * 2^32) at or below 2^31. An axis that
        // cannot even guide at that is refused for its steps; one that
        // cannot reach max_rate_sidereal, for that rate.
        let limit = c.step_tick_hz as f64 / 2.0;
        let guiding = 1.0 + c.guide_rate_sidereal as f64;
        c.require(
            sidereal_ra * guiding <= limit,
            RaStepsPerWormTurn,
            "too many for step_tick_hz: RA guiding needs more than step_tick_hz / 2 steps/s",
        )?;
        c.require(
            sidereal_dec * guiding <= limit,
            DecStepsPerDegree,
            "too many for step_tick_hz: Dec guiding needs more than step_tick_hz / 2 steps/s",
        )?;
        let max = c.max_rate_sidereal as f64;
        let (max_ra, max_dec) = (sidereal_ra * max, sidereal_dec * max);
        c.require(
            max_ra.max(max_dec) <= limit,
            MaxRateSidereal,
            "too fast for step_tick_hz: an axis would need more than step_tick_hz / 2 steps/s",
        )?;

        c.require(
            c.glitch_us > 0 && c.glitch_us <= MAX_GLITCH_US,
            GlitchUs,
            "must be 1 to 10000 us",
        )?;
        c.require(
            c.pulse_cap_us > c.glitch_us && c.pulse_cap_us <= MAX_PULSE_CAP_US,
            PulseCapUs,
            "must be above glitch_us and at most 60000000 us (60 s)",
        )?;
        c.require(
            within(c.guide_cadence_s, GUIDE_CADENCE_RANGE_S),
            GuideCadenceS,
            "must be 0.1 to 60 s",
        )?;
        c.require(
            within(c.guider_aggressiveness, AGGRESSIVENESS_RANGE),
            GuiderAggressiveness,
            "must be 0.3 to 1 (PHD2's default is 0.7)",
        )?;
        c.require(
            c.dither_threshold_us > c.glitch_us && c.dither_threshold_us < c.pulse_cap_us,
            DitherThresholdUs,
            "must be above glitch_us and below pulse_cap_us",
        )?;
        c.require(
            (SILENCE_FRAMES_RANGE.0..=SILENCE_FRAMES_RANGE.1).contains(&c.silence_frames),
            SilenceFrames,
            "must be 1 to 1000",
        )?;
        c.require(
            within(c.least_pulse_share, LEAST_PULSE_SHARE_RANGE),
            LeastPulseShare,
            "must be 0.1 to 1 (1: every guide pulse in full)",
        )?;

        let guide = c.guide_rate_sidereal as f64;
        Ok(Mount {
            config: *c,
            sidereal_ra_steps_per_s_f64: sidereal_ra,
            sidereal_ra_steps_per_s: sidereal_ra as f32,
            arcsec_per_ra_step: arcsec_per_ra_step as f32,
            arcsec_per_dec_step: arcsec_per_dec_step as f32,
            guide_rate_arcsec_per_s: (guide * SIDEREAL_ARCSEC_PER_S) as f32,
            guide_ra_steps_per_s: (guide * sidereal_ra) as f32,
            guide_dec_steps_per_s: (guide * sidereal_dec) as f32,
            max_ra_steps_per_s: max_ra as f32,
            max_dec_steps_per_s: max_dec as f32,
        })
    }
}

impl Mount {
    /// The validated configuration.
    pub fn config(&self) -> &MountConfig {
        &self.config
    }

    /// RA microsteps per second at the sidereal rate:
    /// `ra_steps_per_worm_turn / worm_period_s`.
    pub fn sidereal_ra_steps_per_s(&self) -> f32 {
        self.sidereal_ra_steps_per_s
    }

    /// The same in `f64` (the quotient of the configured values rounded
    /// once), for host-side references and gear-time arithmetic that needs
    /// more than `f32`'s 24 bits.
    pub fn sidereal_ra_steps_per_s_f64(&self) -> f64 {
        self.sidereal_ra_steps_per_s_f64
    }

    /// Arcseconds of RA per RA microstep:
    /// `SIDEREAL_ARCSEC_PER_S / sidereal_ra_steps_per_s`.
    pub fn arcsec_per_ra_step(&self) -> f32 {
        self.arcsec_per_ra_step
    }

    /// Arcseconds of Dec per Dec microstep: `3600 / dec_steps_per_degree`.
    pub fn arcsec_per_dec_step(&self) -> f32 {
        self.arcsec_per_dec_step
    }

    /// The guide rate in arcsec/s: `guide_rate_sidereal * SIDEREAL_ARCSEC_PER_S`.
    pub fn guide_rate_arcsec_per_s(&self) -> f32 {
        self.guide_rate_arcsec_per_s
    }

    /// The guide rate in RA microsteps/s (the offset added to or taken from
    /// the sidereal rate during an RA pulse).
    pub fn guide_ra_steps_per_s(&self) -> f32 {
        self.guide_ra_steps_per_s
    }

    /// The guide rate in Dec microsteps/s (the Dec rate during a Dec pulse).
    pub fn guide_dec_steps_per_s(&self) -> f32 {
        self.guide_dec_steps_per_s
    }

    /// RA microsteps/s at `max_rate_sidereal` (the step generator's clamp).
    pub fn max_ra_steps_per_s(&self) -> f32 {
        self.max_ra_steps_per_s
    }

    /// Dec microsteps/s at `max_rate_sidereal` (the step generator's clamp).
    pub fn max_dec_steps_per_s(&self) -> f32 {
        self.max_dec_steps_per_s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::SplitMix64;

    fn close(a: f64, b: f64, rel: f64) -> bool {
        (a - b).abs() <= rel * b.abs()
    }

    #[test]
    fn default_validates_with_the_documented_numbers() {
        let c = MountConfig::default();
        assert_eq!(c.ra_steps_per_worm_turn, 76_800);
        assert_eq!(c.dec_steps_per_degree, 38_400.0);
        assert!(close(c.worm_period_s as f64, 478.6894, 1e-6));
        let m = c.validate().unwrap();
        assert_eq!(*m.config(), c);
        // 76 800 / 478.6894 = 160.4381 steps/s.
        assert!(close(m.sidereal_ra_steps_per_s() as f64, 160.43807, 1e-6));
        // 360 deg * 3600 / (76 800 * 180) = 0.09375 arcsec per step, both axes.
        assert!(close(m.arcsec_per_ra_step() as f64, 0.09375, 1e-6));
        assert!(close(m.arcsec_per_dec_step() as f64, 0.09375, 1e-7));
        assert!(close(m.guide_rate_arcsec_per_s() as f64, 7.5205343, 1e-7));
        assert!(close(m.guide_ra_steps_per_s() as f64, 80.219033, 1e-6));
        assert!(close(m.guide_dec_steps_per_s() as f64, 80.219033, 1e-6));
        assert!(close(m.max_ra_steps_per_s() as f64, 1283.5045, 1e-6));
        assert!(close(m.max_dec_steps_per_s() as f64, 1283.5045, 1e-6));
    }

    #[test]
    fn derived_values_for_a_known_mount() {
        // A 144-tooth worm (period 598.36 s), 200-step motor, 16 microsteps,
        // 4:1 gearbox: 12 800 steps per worm turn; Dec 10 000 steps/deg.
        let c = MountConfig {
            ra_steps_per_worm_turn: 12_800,
            worm_period_s: 600.0,
            dec_steps_per_degree: 10_000.0,
            guide_rate_sidereal: 1.0,
            max_rate_sidereal: 4.0,
            step_tick_hz: 20_000,
            ..MountConfig::default()
        };
        let m = c.validate().unwrap();
        assert!(close(
            m.sidereal_ra_steps_per_s() as f64,
            12_800.0 / 600.0,
            1e-7
        ));
        assert!(close(
            m.sidereal_ra_steps_per_s_f64(),
            21.333_333_333_333,
            1e-12
        ));
        assert!(close(
            m.arcsec_per_ra_step() as f64,
            SIDEREAL_ARCSEC_PER_S * 600.0 / 12_800.0,
            1e-7
        ));
        assert!(close(m.arcsec_per_dec_step() as f64, 0.36, 1e-7));
        assert!(close(
            m.guide_rate_arcsec_per_s() as f64,
            SIDEREAL_ARCSEC_PER_S,
            1e-7
        ));
        assert!(close(
            m.max_ra_steps_per_s() as f64,
            4.0 * 12_800.0 / 600.0,
            1e-7
        ));
        assert!(close(
            m.max_dec_steps_per_s() as f64,
            4.0 * SIDEREAL_ARCSEC_PER_S / 0.36,
            1e-7
        ));
        assert!(close(
            m.guide_dec_steps_per_s() as f64,
            SIDEREAL_ARCSEC_PER_S / 0.36,
            1e-7
        ));
    }

    fn refused(c: MountConfig) -> ConfigError {
        match c.validate() {
            Ok(_) => panic!("accepted {c:?}"),
            Err(e) => e,
        }
    }

    /// The default with `field` set to `v`.
    fn with(field: Field, v: f64) -> MountConfig {
        let mut c = MountConfig::default();
        set(&mut c, field, v);
        c
    }

    /// Sets `field` to `v` (a count saturates: `v as u32`).
    fn set(c: &mut MountConfig, field: Field, v: f64) {
        let count = v as u32;
        let real = v as f32;
        match field {
            Field::RaStepsPerWormTurn => c.ra_steps_per_worm_turn = count,
            Field::WormPeriodS => c.worm_period_s = real,
            Field::DecStepsPerDegree => c.dec_steps_per_degree = real,
            Field::GuideRateSidereal => c.guide_rate_sidereal = real,
            Field::MaxRateSidereal => c.max_rate_sidereal = real,
            Field::StepTickHz => c.step_tick_hz = count,
            Field::GlitchUs => c.glitch_us = count,
            Field::PulseCapUs => c.pulse_cap_us = count,
            Field::GuideCadenceS => c.guide_cadence_s = real,
            Field::GuiderAggressiveness => c.guider_aggressiveness = real,
            Field::DitherThresholdUs => c.dither_threshold_us = count,
            Field::SilenceFrames => c.silence_frames = count,
            Field::LeastPulseShare => c.least_pulse_share = real,
        }
    }

    #[test]
    fn each_bad_value_is_refused_naming_its_field() {
        use Field::*;
        let nan = f64::NAN;
        let inf = f64::INFINITY;
        let bad: [(Field, &[f64]); 13] = [
            // 0; 15.04 arcsec per step; 50 kHz tick / 2 at 1.5x sidereal.
            (
                RaStepsPerWormTurn,
                &[0.0, 31.0, 9_000_000.0, u32::MAX as f64],
            ),
            (
                WormPeriodS,
                &[0.0, -479.0, 59.0, 86_200.0, 1e-30, 3.4e38, nan, inf],
            ),
            (
                DecStepsPerDegree,
                &[0.0, -1.0, 1e-45, 239.0, 5e6, 3.4e38, nan, inf],
            ),
            (GuideRateSidereal, &[0.0, 1e-45, 0.09, 1.01, -0.5, nan, inf]),
            (MaxRateSidereal, &[0.0, 1.49, 200.0, -8.0, nan, inf]),
            (StepTickHz, &[0.0, 999.0, 200_001.0]),
            (GlitchUs, &[0.0, 10_001.0]),
            (PulseCapUs, &[0.0, 1_000.0, 60_000_001.0]),
            (GuideCadenceS, &[0.0, 0.09, 61.0, -2.0, nan, inf]),
            (
                GuiderAggressiveness,
                &[0.0, 1e-45, 0.1, 0.29, 1.01, nan, inf],
            ),
            (
                DitherThresholdUs,
                &[0.0, 1_000.0, 10_000_000.0, u32::MAX as f64],
            ),
            (SilenceFrames, &[0.0, 1_001.0]),
            (LeastPulseShare, &[0.0, 0.09, 1.01, -0.5, nan, inf]),
        ];
        for (field, values) in bad {
            for &v in values {
                let e = refused(with(field, v));
                assert_eq!(e.field, field, "{} = {v}: {e}", field.name());
            }
        }
    }

    #[test]
    fn the_limits_themselves_are_accepted() {
        use Field::*;
        let good: [(Field, &[f64]); 10] = [
            (WormPeriodS, &[60.0, 4_000.0]),
            (DecStepsPerDegree, &[240.0]),
            (GuideRateSidereal, &[0.1, 1.0]),
            (StepTickHz, &[2_568.0, 200_000.0]),
            (GlitchUs, &[1.0, 10_000.0]),
            (PulseCapUs, &[3_000_001.0, 60_000_000.0]),
            (GuideCadenceS, &[0.1, 60.0]),
            (GuiderAggressiveness, &[0.3, 1.0]),
            (SilenceFrames, &[1.0, 1_000.0]),
            (LeastPulseShare, &[0.1, 1.0]),
        ];
        for (field, values) in good {
            for &v in values {
                let c = with(field, v);
                assert!(
                    c.validate().is_ok(),
                    "{} = {v}: {:?}",
                    field.name(),
                    c.validate()
                );
            }
        }
        // A one-tooth "worm" (a harmonic drive turning once a day) with
        // enough steps.
        let day = MountConfig {
            worm_period_s: 86_164.0,
            ra_steps_per_worm_turn: 1_000_000,
            ..MountConfig::default()
        };
        assert!(day.validate().is_ok());
    }

    /// The configurations randomized testing found accepted with infinite or
    /// zero derived values (issue F6), each refused now, naming the field.
    #[test]
    fn configs_with_absurd_derived_values_are_refused() {
        let d = MountConfig::default();
        let cases = [
            (
                MountConfig {
                    ra_steps_per_worm_turn: 1,
                    worm_period_s: f32::MAX,
                    ..d
                },
                Field::WormPeriodS,
            ),
            (
                MountConfig {
                    dec_steps_per_degree: 1e-45,
                    ..d
                },
                Field::DecStepsPerDegree,
            ),
            (
                MountConfig {
                    guide_rate_sidereal: 1e-45,
                    ..d
                },
                Field::GuideRateSidereal,
            ),
            (
                MountConfig {
                    guider_aggressiveness: 1e-45,
                    ..d
                },
                Field::GuiderAggressiveness,
            ),
            (
                MountConfig {
                    ra_steps_per_worm_turn: 1,
                    ..d
                },
                Field::RaStepsPerWormTurn,
            ),
        ];
        for (c, field) in cases {
            assert_eq!(refused(c).field, field, "{c:?}");
        }
    }

    /// A value near `typical` (within a factor of 30 either way), an extreme
    /// or raw bits: configurations both valid and refused.
    fn draw(rng: &mut SplitMix64, typical: f64) -> f64 {
        match rng.below(8) {
            0 => f64::from(f32::from_bits(rng.next_u64() as u32)),
            1 => [0.0, -1.0, 1e-45, f64::MAX, f64::NAN, u32::MAX as f64][rng.below(6) as usize],
            _ => typical * 30f64.powf(rng.f64_in(-1.0, 1.0)),
        }
    }

    #[test]
    fn random_configs_are_refused_by_name_or_derive_sane_values() {
        let d = MountConfig::default();
        let mut rng = SplitMix64::new(11);
        let (mut ok, mut refused_by) = (0usize, [0usize; 13]);
        for _ in 0..300_000 {
            let mut c = d;
            for field in Field::ALL {
                let typical = match d.get(field) {
                    Value::Count(v) => f64::from(v),
                    Value::Real(v) => f64::from(v),
                };
                // About half the fields keep their default.
                if rng.below(2) == 0 {
                    set(&mut c, field, draw(&mut rng, typical));
                }
            }
            match c.validate() {
                Err(e) => {
                    // Compared as text: a NaN value is not equal to itself.
                    assert_eq!(
                        std::format!("{:?}", e.value),
                        std::format!("{:?}", c.get(e.field))
                    );
                    let i = Field::ALL.iter().position(|&f| f == e.field).unwrap();
                    refused_by[i] += 1;
                }
                Ok(m) => {
                    ok += 1;
                    let tick_half = c.step_tick_hz as f32 / 2.0;
                    for v in [
                        m.sidereal_ra_steps_per_s(),
                        m.guide_ra_steps_per_s(),
                        m.guide_dec_steps_per_s(),
                        m.guide_rate_arcsec_per_s(),
                    ] {
                        assert!(v.is_finite() && v > 0.0, "{c:?}");
                    }
                    for v in [m.arcsec_per_ra_step(), m.arcsec_per_dec_step()] {
                        assert!(
                            v > 0.0 && v <= MAX_ARCSEC_PER_STEP as f32 * 1.000_001,
                            "{c:?}"
                        );
                    }
                    for v in [m.max_ra_steps_per_s(), m.max_dec_steps_per_s()] {
                        assert!(v > 0.0 && v <= tick_half * 1.000_001, "{c:?}");
                    }
                }
            }
        }
        // Both outcomes, and every field's refusal, were exercised.
        assert!(ok > 1_000, "{ok} accepted");
        assert!(refused_by.iter().all(|&n| n > 0), "{refused_by:?}");
    }

    /// Every field by its name, and `set` then `get` round-trips; a value
    /// of the other kind is refused and changes nothing.
    #[test]
    fn fields_by_name_set_and_get() {
        let mut c = MountConfig::default();
        for field in Field::ALL {
            assert_eq!(Field::from_name(field.name().as_bytes()), Some(field));
            let value = match c.get(field) {
                Value::Count(v) => Value::Count(v + 1),
                Value::Real(v) => Value::Real(v * 1.5),
            };
            c.set(field, value).unwrap();
            assert_eq!(c.get(field), value);
            let other = match value {
                Value::Count(_) => Value::Real(1.0),
                Value::Real(_) => Value::Count(1),
            };
            let before = c;
            assert_eq!(c.set(field, other), Err(other));
            assert_eq!(c, before);
        }
        assert_eq!(Field::from_name(b"worm_period"), None);
        assert_eq!(Field::from_name(b""), None);
    }

    #[test]
    fn errors_print_the_field_the_value_and_the_rule() {
        let e = refused(with(Field::GuideRateSidereal, 1.5));
        assert_eq!(
            std::format!("{e}"),
            "mount config: guide_rate_sidereal = 1.5: must be 0.1 to 1 (x sidereal)"
        );
        let e = refused(with(Field::SilenceFrames, 0.0));
        assert_eq!(
            std::format!("{e}"),
            "mount config: silence_frames = 0: must be 1 to 1000"
        );
    }
}
