//! The mount's configuration: one documented type, checked once at start-up.
//!
//! [`MountConfig`] holds the numbers that describe a mount (its drive
//! trains, the step-generator tick, the ST4 timing and what the firmware
//! assumes about the guider). [`MountConfig::validate`] checks every value
//! and returns a [`Mount`] with the derived constants, or the first value it
//! refuses as a [`ConfigError`] (whose `Display` text the firmware prints at
//! start-up).
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
    /// (180 teeth: 478.69 s; 144 teeth: 598.36 s). Finite, > 0.
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
    /// (default 2.0). Finite, > 0.
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
        }
    }
}

/// A refused configuration value: one variant per check, naming the field.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ConfigError {
    /// `ra_steps_per_worm_turn` is 0.
    ZeroRaSteps,
    /// `worm_period_s` is not finite or not > 0.
    WormPeriod(f32),
    /// `dec_steps_per_degree` is not finite or not > 0.
    DecSteps(f32),
    /// `guide_rate_sidereal` is not in (0, 1].
    GuideRate(f32),
    /// `max_rate_sidereal` is not finite or below 1 + `guide_rate_sidereal`.
    MaxRate(f32),
    /// `step_tick_hz` is 0.
    StepTick,
    /// The RA axis at `max_rate_sidereal` needs more than one step per two
    /// ticks of `step_tick_hz` (or its rate is not finite).
    RateOverflow { max_steps_per_s: f32, tick_hz: u32 },
    /// The Dec axis at `max_rate_sidereal` needs more than one step per two
    /// ticks of `step_tick_hz` (or its rate is not finite).
    DecRateOverflow { max_steps_per_s: f32, tick_hz: u32 },
    /// `pulse_cap_us` is 0.
    PulseCap,
    /// `glitch_us` is 0 or not below `pulse_cap_us`.
    Glitch(u32),
    /// `dither_threshold_us` is not above `glitch_us` or not below
    /// `pulse_cap_us`.
    DitherThreshold(u32),
    /// `guide_cadence_s` is not finite or not > 0.
    GuideCadence(f32),
    /// `guider_aggressiveness` is not in (0, 1].
    Aggressiveness(f32),
    /// `silence_frames` is 0.
    SilenceFrames,
}

/// The message of a rate the step tick cannot produce, for either axis.
fn overflow(
    f: &mut fmt::Formatter<'_>,
    axis: &str,
    max_steps_per_s: f32,
    tick_hz: u32,
) -> fmt::Result {
    write!(
        f,
        "mount config: {axis} at max_rate_sidereal needs {max_steps_per_s} steps/s, \
         more than step_tick_hz / 2 = {} (tick {tick_hz} Hz); lower max_rate_sidereal \
         or raise step_tick_hz",
        tick_hz / 2
    )
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use ConfigError::*;
        match *self {
            ZeroRaSteps => write!(f, "mount config: ra_steps_per_worm_turn is 0, must be > 0"),
            WormPeriod(v) => write!(
                f,
                "mount config: worm_period_s = {v} s, must be finite and > 0"
            ),
            DecSteps(v) => write!(
                f,
                "mount config: dec_steps_per_degree = {v}, must be finite and > 0"
            ),
            GuideRate(v) => write!(
                f,
                "mount config: guide_rate_sidereal = {v}, must be in (0, 1]"
            ),
            MaxRate(v) => write!(
                f,
                "mount config: max_rate_sidereal = {v}, must be finite and at least 1 + guide_rate_sidereal"
            ),
            StepTick => write!(f, "mount config: step_tick_hz is 0, must be > 0"),
            RateOverflow {
                max_steps_per_s,
                tick_hz,
            } => overflow(f, "RA", max_steps_per_s, tick_hz),
            DecRateOverflow {
                max_steps_per_s,
                tick_hz,
            } => overflow(f, "Dec", max_steps_per_s, tick_hz),
            PulseCap => write!(f, "mount config: pulse_cap_us is 0, must be > 0"),
            Glitch(v) => write!(
                f,
                "mount config: glitch_us = {v}, must be > 0 and below pulse_cap_us"
            ),
            DitherThreshold(v) => write!(
                f,
                "mount config: dither_threshold_us = {v}, must be above glitch_us and below pulse_cap_us"
            ),
            GuideCadence(v) => write!(
                f,
                "mount config: guide_cadence_s = {v} s, must be finite and > 0"
            ),
            Aggressiveness(v) => write!(
                f,
                "mount config: guider_aggressiveness = {v}, must be in (0, 1]"
            ),
            SilenceFrames => write!(f, "mount config: silence_frames is 0, must be > 0"),
        }
    }
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

fn positive_finite(v: f32) -> bool {
    v.is_finite() && v > 0.0
}

fn in_unit_interval(v: f32) -> bool {
    // NaN fails both comparisons.
    v > 0.0 && v <= 1.0
}

impl MountConfig {
    /// Checks every value (in field order; the first refused one is
    /// returned) and derives the constants.
    pub fn validate(&self) -> Result<Mount, ConfigError> {
        let c = self;
        if c.ra_steps_per_worm_turn == 0 {
            return Err(ConfigError::ZeroRaSteps);
        }
        if !positive_finite(c.worm_period_s) {
            return Err(ConfigError::WormPeriod(c.worm_period_s));
        }
        if !positive_finite(c.dec_steps_per_degree) {
            return Err(ConfigError::DecSteps(c.dec_steps_per_degree));
        }
        if !in_unit_interval(c.guide_rate_sidereal) {
            return Err(ConfigError::GuideRate(c.guide_rate_sidereal));
        }
        // NaN fails the comparison.
        if !(c.max_rate_sidereal.is_finite() && c.max_rate_sidereal >= 1.0 + c.guide_rate_sidereal)
        {
            return Err(ConfigError::MaxRate(c.max_rate_sidereal));
        }
        if c.step_tick_hz == 0 {
            return Err(ConfigError::StepTick);
        }

        // Derived rates, in f64 (see the module documentation).
        let sidereal_ra = c.ra_steps_per_worm_turn as f64 / c.worm_period_s as f64;
        // Dec microsteps per second at the sidereal rate (arcsec/s -> deg/s).
        let sidereal_dec = SIDEREAL_ARCSEC_PER_S / 3600.0 * c.dec_steps_per_degree as f64;
        let max = c.max_rate_sidereal as f64;
        let max_ra = sidereal_ra * max;
        let max_dec = sidereal_dec * max;
        // At most one step per two ticks; this also keeps the Q0.32
        // increment (rate / tick_hz * 2^32) at or below 2^31.
        let limit = c.step_tick_hz as f64 / 2.0;
        if !(max_ra.is_finite() && max_ra <= limit) {
            return Err(ConfigError::RateOverflow {
                max_steps_per_s: max_ra as f32,
                tick_hz: c.step_tick_hz,
            });
        }
        if !(max_dec.is_finite() && max_dec <= limit) {
            return Err(ConfigError::DecRateOverflow {
                max_steps_per_s: max_dec as f32,
                tick_hz: c.step_tick_hz,
            });
        }

        if c.pulse_cap_us == 0 {
            return Err(ConfigError::PulseCap);
        }
        if c.glitch_us == 0 || c.glitch_us >= c.pulse_cap_us {
            return Err(ConfigError::Glitch(c.glitch_us));
        }
        if c.dither_threshold_us <= c.glitch_us || c.dither_threshold_us >= c.pulse_cap_us {
            return Err(ConfigError::DitherThreshold(c.dither_threshold_us));
        }
        if !positive_finite(c.guide_cadence_s) {
            return Err(ConfigError::GuideCadence(c.guide_cadence_s));
        }
        if !in_unit_interval(c.guider_aggressiveness) {
            return Err(ConfigError::Aggressiveness(c.guider_aggressiveness));
        }
        if c.silence_frames == 0 {
            return Err(ConfigError::SilenceFrames);
        }

        let guide = c.guide_rate_sidereal as f64;
        Ok(Mount {
            config: *c,
            sidereal_ra_steps_per_s_f64: sidereal_ra,
            sidereal_ra_steps_per_s: sidereal_ra as f32,
            arcsec_per_ra_step: (SIDEREAL_ARCSEC_PER_S / sidereal_ra) as f32,
            arcsec_per_dec_step: (3600.0 / c.dec_steps_per_degree as f64) as f32,
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

    #[test]
    fn each_bad_field_is_refused_with_its_variant() {
        let d = MountConfig::default();
        assert_eq!(
            refused(MountConfig {
                ra_steps_per_worm_turn: 0,
                ..d
            }),
            ConfigError::ZeroRaSteps
        );
        for v in [0.0, -479.0, f32::NAN, f32::INFINITY] {
            let e = refused(MountConfig {
                worm_period_s: v,
                ..d
            });
            assert!(matches!(e, ConfigError::WormPeriod(_)), "{v}: {e:?}");
        }
        for v in [0.0, -1.0, f32::NAN, f32::INFINITY] {
            let e = refused(MountConfig {
                dec_steps_per_degree: v,
                ..d
            });
            assert!(matches!(e, ConfigError::DecSteps(_)), "{v}: {e:?}");
        }
        for v in [0.0, -0.5, 1.01, f32::NAN, f32::INFINITY] {
            let e = refused(MountConfig {
                guide_rate_sidereal: v,
                ..d
            });
            assert!(matches!(e, ConfigError::GuideRate(_)), "{v}: {e:?}");
        }
        // Guide rate 1 is allowed.
        assert!(MountConfig {
            guide_rate_sidereal: 1.0,
            ..d
        }
        .validate()
        .is_ok());
        for v in [0.0, 0.5, 1.0, 1.49, -8.0, f32::NAN, f32::INFINITY] {
            let e = refused(MountConfig {
                max_rate_sidereal: v,
                ..d
            });
            assert!(matches!(e, ConfigError::MaxRate(_)), "{v}: {e:?}");
        }
        assert_eq!(
            refused(MountConfig {
                step_tick_hz: 0,
                ..d
            }),
            ConfigError::StepTick
        );
        // 8x sidereal = 1283.5 steps/s needs a tick of at least 2567 Hz.
        let e = refused(MountConfig {
            step_tick_hz: 2_000,
            ..d
        });
        match e {
            ConfigError::RateOverflow {
                max_steps_per_s,
                tick_hz,
            } => {
                assert!((max_steps_per_s - 1283.5).abs() < 0.1);
                assert_eq!(tick_hz, 2_000);
            }
            _ => panic!("{e:?}"),
        }
        assert!(MountConfig {
            step_tick_hz: 2_568,
            ..d
        }
        .validate()
        .is_ok());
        // A huge step count per worm turn overflows the tick too.
        assert!(matches!(
            refused(MountConfig {
                ra_steps_per_worm_turn: u32::MAX,
                ..d
            }),
            ConfigError::RateOverflow { .. }
        ));
        // A tiny worm period as well.
        assert!(matches!(
            refused(MountConfig {
                worm_period_s: 1e-30,
                ..d
            }),
            ConfigError::RateOverflow { .. }
        ));
        // Dec alone too fast.
        assert!(matches!(
            refused(MountConfig {
                dec_steps_per_degree: 1e6,
                ..d
            }),
            ConfigError::DecRateOverflow { .. }
        ));
        assert!(matches!(
            refused(MountConfig {
                dec_steps_per_degree: f32::MAX,
                ..d
            }),
            ConfigError::DecRateOverflow { .. }
        ));
        assert_eq!(
            refused(MountConfig {
                pulse_cap_us: 0,
                ..d
            }),
            ConfigError::PulseCap
        );
        assert_eq!(
            refused(MountConfig { glitch_us: 0, ..d }),
            ConfigError::Glitch(0)
        );
        assert_eq!(
            refused(MountConfig {
                glitch_us: 10_000_000,
                ..d
            }),
            ConfigError::Glitch(10_000_000)
        );
        for v in [0, 1_000, 10_000_000, u32::MAX] {
            assert_eq!(
                refused(MountConfig {
                    dither_threshold_us: v,
                    ..d
                }),
                ConfigError::DitherThreshold(v)
            );
        }
        for v in [0.0, -2.0, f32::NAN, f32::INFINITY] {
            let e = refused(MountConfig {
                guide_cadence_s: v,
                ..d
            });
            assert!(matches!(e, ConfigError::GuideCadence(_)), "{v}: {e:?}");
        }
        for v in [0.0, -0.7, 1.5, f32::NAN, f32::INFINITY] {
            let e = refused(MountConfig {
                guider_aggressiveness: v,
                ..d
            });
            assert!(matches!(e, ConfigError::Aggressiveness(_)), "{v}: {e:?}");
        }
        assert_eq!(
            refused(MountConfig {
                silence_frames: 0,
                ..d
            }),
            ConfigError::SilenceFrames
        );
    }

    /// A fixed buffer that implements `fmt::Write`, for the Display test.
    struct Buf {
        b: [u8; 256],
        n: usize,
    }
    impl fmt::Write for Buf {
        fn write_str(&mut self, s: &str) -> fmt::Result {
            let end = self.n + s.len();
            let dst = self.b.get_mut(self.n..end).ok_or(fmt::Error)?;
            dst.copy_from_slice(s.as_bytes());
            self.n = end;
            Ok(())
        }
    }

    #[test]
    fn errors_print_the_field_and_the_value() {
        use core::fmt::Write;
        let cases: [(ConfigError, &str); 4] = [
            (ConfigError::ZeroRaSteps, "ra_steps_per_worm_turn"),
            (ConfigError::GuideRate(1.5), "guide_rate_sidereal = 1.5"),
            (
                ConfigError::RateOverflow {
                    max_steps_per_s: 30_000.0,
                    tick_hz: 50_000,
                },
                "30000 steps/s, more than step_tick_hz / 2 = 25000",
            ),
            (ConfigError::SilenceFrames, "silence_frames"),
        ];
        for (e, want) in cases {
            let mut b = Buf { b: [0; 256], n: 0 };
            write!(b, "{e}").unwrap();
            let s = core::str::from_utf8(&b.b[..b.n]).unwrap();
            assert!(s.contains(want), "{s:?} lacks {want:?}");
        }
    }
}
