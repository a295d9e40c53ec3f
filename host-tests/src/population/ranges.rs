//! The ranges a mount of the population is drawn from (issue 28), each
//! with where it comes from. Pixels are arcseconds: the simulators' scale
//! (1 arcsec per px, as the paper's cases). Each range is drawn uniformly
//! unless its comment says otherwise; the draw is `super::draw`.

/// One sidereal day, s: the RA axis turns once in it while tracking, so a
/// worm wheel of n teeth makes the worm turn every day / n.
pub const SIDEREAL_DAY_S: f64 = 86_164.09;

/// Teeth of the RA worm wheel (whole numbers, inclusive): 90, the small
/// wheels of light mounts, to 360 (Losmandy G11, worm period 239.3 s);
/// Sky-Watcher HEQ5 135, EQ5 144, EQ6 180 (the default mount of
/// `MountConfig`, 478.7 s), Astro-Physics Mach1 225 lie between. Worm
/// periods 239.3-957.4 s.
pub const WORM_TEETH: (u32, u32) = (90, 360);

/// The worm's fundamental, px peak. Mass-produced mounts show some 10-30
/// arcsec peak to peak of periodic error before PEC, better mounts a few
/// arcsec (makers' and users' PEC curves); the paper's cases have 9 px.
pub const WORM_AMPLITUDE_PX: (f64, f64) = (2.0, 12.0);

/// Each of the worm's 2nd, 3rd and 4th harmonics, as a share of its
/// fundamental: a worm's error is not a pure sine (eccentricity, tooth
/// form, bearing play); the paper's C4 has 33, 22 and 11 %.
pub const HARMONIC_SHARE: (f64, f64) = (0.05, 0.40);

/// Further stages beyond the worm (whole numbers, inclusive): none (a worm
/// driven directly) to three (a belt, a spur pair and a motor gearbox).
pub const STAGES: (usize, usize) = (0, 3);

/// A spur or motor gear's turns per worm turn: single spur reductions and a
/// gearbox's intermediate stage. Pairs with coprime tooth counts (hunting
/// teeth, which spread the wear, e.g. 47:15 = 3.13) make ratios that are
/// not whole numbers: a drawn ratio is at least [`WHOLE_RATIO_MARGIN`]
/// from one.
pub const GEAR_RATIO: (f64, f64) = (2.0, 12.0);

/// How far (relative) a gear's ratio stays from a whole number: a whole
/// ratio would be a harmonic of the worm, not another stage.
pub const WHOLE_RATIO_MARGIN: f64 = 0.01;

/// The share of gears drawn near a harmonic of the worm (within
/// [`NEAR_HARMONIC_OFFSET`] of its 2nd-4th, either side), as real trains
/// have (49:16 = 3.06 is 2 % off the 3rd): the case the model's
/// commensurability rule is for (docs/model.md, "Stages near a harmonic").
pub const NEAR_HARMONIC_SHARE: f64 = 1.0 / 3.0;

/// Relative distance of a near-harmonic gear's ratio from the harmonic.
pub const NEAR_HARMONIC_OFFSET: (f64, f64) = (0.01, 0.05);

/// The harmonics of the worm a near-harmonic gear sits by (inclusive): the
/// ones the worm has ([`HARMONIC_SHARE`]). A ratio just below the 2nd,
/// out of [`GEAR_RATIO`], is drawn again.
pub const NEAR_HARMONIC: (u32, u32) = (2, 4);

/// The share of further stages that are belts (the others are gears).
pub const BELT_SHARE: f64 = 0.5;

/// A belt drive's period, s: the runout of its small pulley, which turns
/// every 40-200 s (the EQ6's 16-tooth motor pulley at 3:1 to the worm
/// pulley, 160 s; faster behind a gearbox).
pub const BELT_PERIOD_S: (f64, f64) = (40.0, 200.0);

/// A further stage's fundamental, px peak: from 0.3, near the noise floor,
/// to 5 (the paper's second stages have 2.4-4.5).
pub const STAGE_AMPLITUDE_PX: (f64, f64) = (0.3, 5.0);

/// The share of mounts whose worm is amplitude-modulated.
pub const MODULATED_SHARE: f64 = 0.25;

/// Depth of the worm's modulation: its amplitude swings by this share
/// either way.
pub const MODULATION_DEPTH: (f64, f64) = (0.1, 0.5);

/// Period of the worm's modulation, s (1-4 h): the worm meets wheel teeth
/// cut with different errors as the wheel turns (sector-to-sector
/// variation of a hobbed wheel). A stress range, not a measured one: a
/// wheel's runout alone modulates once a sidereal day, far slower.
pub const MODULATION_PERIOD_S: (f64, f64) = (3_600.0, 14_400.0);

/// The share of mounts with a further stage in which one of them fades.
pub const FADING_SHARE: f64 = 0.25;

/// When the stage starts to fade, s: within the run, mostly in the scored
/// part (t >= 3600 s), so that a model that learned it must unlearn it.
/// A stage's error fades when the load on the train changes (the balance
/// shifts with hour angle and a gear's backlash opens).
pub const FADE_FROM_S: (f64, f64) = (1_200.0, 7_200.0);

/// How long the fade takes, s.
pub const FADE_OVER_S: (f64, f64) = (600.0, 3_600.0);

/// What is left of the faded stage's amplitude.
pub const FADE_TO: (f64, f64) = (0.0, 0.2);

/// The RA drift of the star, px/s, either sign, up to this size: a polar
/// alignment error (and refraction) drifts the star steadily; the paper's
/// cases have 0.0008, 0.002 is 7.2 px an hour.
pub const DRIFT_PX_PER_S: f64 = 0.002;

/// A slow random walk of the star, px per square root of a minute:
/// differential flexure between guide scope and main scope; 0.3 (the
/// largest, `guide-sim st4 --walk 0.3` of docs/results.md) spreads about
/// 4 px over the 3 h run.
pub const WALK_PX_PER_SQRT_MIN: (f64, f64) = (0.0, 0.3);

/// The guide camera's noise, px (1 sigma per frame): the centroid's
/// scatter from seeing over a 1-4 s exposure, 0.3 px on a good night to
/// 1.5 in poor seeing; the tables' 1 px lies within.
pub const SEEING_PX: (f64, f64) = (0.3, 1.5);

/// The guide exposure, s, in steps of [`EXPOSURE_STEP_S`] (PHD2's exposure
/// menu): long enough to average the seeing, short enough to follow the
/// gear.
pub const EXPOSURE_S: (f64, f64) = (1.0, 4.0);

/// The steps of PHD2's exposure menu, s.
pub const EXPOSURE_STEP_S: f64 = 0.5;
