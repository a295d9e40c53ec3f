//! Fixed-point step generation: one 32-bit phase accumulator per axis.
//!
//! The hal's step timer calls [`PhaseAccumulator::tick`] once per tick
//! (`step_tick_hz`, 50 kHz by default) for each axis. The accumulator adds
//! its increment, the rate as a fraction of the tick rate in Q0.32
//! (`increment = round(|rate| / tick_hz * 2^32)`), to the phase; when the
//! phase wraps, a step is due. There is no division and no float in the
//! tick: the average step rate is exact to 2^-32 steps per tick, and the
//! steps are never more than one tick away from where the ideal rate puts
//! them.
//!
//! - **RAM**: 12 bytes per axis (`phase: u32`, `increment: u32`,
//!   `forward: bool`, `stepped: bool`, padded to 4).
//! - **Per tick**: one 32-bit add with carry-out, two stores and a branch,
//!   no float, no division: 13 Cortex-M4 instructions per axis (thumbv7em,
//!   opt-level "s", counted in the assembly of a wrapper that also maps the
//!   result to a step code), about 1.3 M instructions/s for two axes at
//!   50 kHz.
//!   [`PhaseAccumulator::set_rate`] does one `f64` division and
//!   multiplication (software floating point on the Cortex-M4F, a few
//!   hundred cycles), but it runs once per rate change, not per tick.
//!
//! **Why `f64` in `set_rate`**: the increment has 32 significant bits; `f32`
//! (24 bits) would round it to 2^-24 relative, up to 0.26 steps over 12 h of
//! sidereal tracking on top of the other errors. In `f64` the increment is
//! the correctly rounded Q0.32 value of the rate, and the step count after
//! `T` ticks is exactly `floor((2^31 + T * increment) / 2^32)`: within
//! `0.5 + T * 2^-33` steps of `T * rate / tick_hz` (0.75 steps after 12 h at
//! 50 kHz). An `f32` *rate* is itself rounded to 2^-24 relative, which adds
//! up to 0.33 steps in 12 h below 256 steps/s (the default mount tracks at
//! 160 steps/s) but 5 steps at 2 864 steps/s; [`PhaseAccumulator::set_rate_f64`]
//! takes the rate in `f64` (e.g. `Mount::sidereal_ra_steps_per_s_f64()` plus
//! the guide offset) and keeps the 0.75-step bound on any mount. The host
//! tests prove both for 12 h of sidereal tracking.
//!
//! **Phase**: it starts at one half (2^31), so the emitted count is the
//! rounded ideal count rather than its floor. On a direction reversal the
//! phase is mirrored (`!phase`), so that the fraction of a step already made
//! in one direction counts against the first step in the other: a run
//! forward and the same run backward return to the same step count.
//!
//! **Timing**: a step is never due on two consecutive ticks (the hal can
//! raise STEP on one tick and lower it on the next). The rate is clamped to
//! `tick_hz / 2` (increment <= 2^31), so a steady rate cannot do it; a
//! reversal right after a step could, and then the first step in the new
//! direction is held back by one tick (the phase loses less than half a
//! step; only in that case).

use crate::model::numeric::clamp;

/// One axis: a 32-bit phase accumulator advanced once per timer tick; a
/// step is emitted when it wraps.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PhaseAccumulator {
    /// Progress towards the next step in the current direction, Q0.32.
    phase: u32,
    /// Added to `phase` every tick: |rate| / tick_hz in Q0.32 (<= 2^31).
    increment: u32,
    /// Direction of the steps (true = forward, DIR high).
    forward: bool,
    /// The last tick emitted a step.
    stepped: bool,
}

impl Default for PhaseAccumulator {
    fn default() -> Self {
        Self::new()
    }
}

/// 2^32 as f64.
const Q32: f64 = 4_294_967_296.0;

impl PhaseAccumulator {
    /// Stopped (rate 0), direction forward, phase one half.
    pub const fn new() -> Self {
        PhaseAccumulator {
            phase: 1 << 31,
            increment: 0,
            forward: true,
            stepped: false,
        }
    }

    /// Signed rate in steps/s (positive = forward). Clamped to
    /// `[-max, max]` where `max = min(max_steps_per_s, tick_hz / 2)`;
    /// NaN -> 0, +-inf -> +-max; a NaN or non-positive `max_steps_per_s`
    /// or a zero `tick_hz` stops the axis. Returns the clamped rate actually
    /// set (before the Q0.32 rounding, which changes it by at most
    /// `tick_hz * 2^-33` steps/s: 5.8e-6 at 50 kHz; see
    /// [`rate_steps_per_s`](Self::rate_steps_per_s) for the exact value).
    ///
    /// The phase is kept across rate changes (and mirrored on a direction
    /// reversal), so changing the rate never gains or loses a fraction of a
    /// step. A zero rate keeps the direction.
    pub fn set_rate(&mut self, steps_per_s: f32, max_steps_per_s: f32, tick_hz: u32) -> f32 {
        self.set_rate_f64(steps_per_s as f64, max_steps_per_s as f64, tick_hz) as f32
    }

    /// [`set_rate`](Self::set_rate) with an `f64` rate and limit, for rates
    /// that `f32` cannot carry precisely enough: an `f32` rate is rounded to
    /// 2^-24 relative (half an ulp: 7.6e-6 steps/s at 160 steps/s, 0.33
    /// steps in 12 h; 1.2e-4 steps/s at 2 864 steps/s, 5.3 steps in 12 h).
    /// Pass `Mount::sidereal_ra_steps_per_s_f64() + offset as f64` to track
    /// within one step per 12 h on any mount the configuration accepts.
    pub fn set_rate_f64(&mut self, steps_per_s: f64, max_steps_per_s: f64, tick_hz: u32) -> f64 {
        let tick = tick_hz as f64;
        let max = max_steps_per_s;
        // NaN fails `max > 0.0`; +inf is limited by the tick.
        let limit = if max > 0.0 { max.min(tick / 2.0) } else { 0.0 };
        let rate = if steps_per_s.is_nan() {
            0.0
        } else {
            clamp(steps_per_s, -limit, limit)
        };
        let increment = if tick_hz == 0 {
            0
        } else {
            // |rate| <= tick / 2, so this is at most 2^31; `as` saturates
            // anyway. Round half up (no `round` in core for f64).
            (rate.abs() / tick * Q32 + 0.5) as u32
        };
        if increment != 0 {
            let forward = rate > 0.0;
            if forward != self.forward {
                self.phase = !self.phase;
                self.forward = forward;
            }
        }
        self.increment = increment;
        if self.stepped && self.phase > u32::MAX - increment {
            // A reversal right after a step: hold the next one for a tick.
            self.phase = u32::MAX - increment;
        }
        rate
    }

    /// Advance one tick; `Some(forward)` when a step is due (the caller
    /// pulses STEP with DIR = forward).
    #[inline]
    pub fn tick(&mut self) -> Option<bool> {
        let (phase, wrapped) = self.phase.overflowing_add(self.increment);
        self.phase = phase;
        self.stepped = wrapped;
        if wrapped {
            Some(self.forward)
        } else {
            None
        }
    }

    /// Advance `ticks` ticks at once; returns the signed steps they emit
    /// (forward positive). The same count, phase and state as `ticks` calls
    /// of [`tick`](Self::tick): the simulator moves its mount with it, so it
    /// runs the firmware's own step generation without simulating every
    /// tick.
    pub fn advance(&mut self, ticks: u64) -> i64 {
        if ticks == 0 || self.increment == 0 {
            if ticks > 0 {
                self.stepped = false;
            }
            return 0;
        }
        let total = self.phase as u128 + ticks as u128 * self.increment as u128;
        let steps = (total >> 32) as i64;
        let phase = total as u32;
        self.phase = phase;
        // The last tick wrapped exactly when less than one increment is left.
        self.stepped = phase < self.increment;
        if self.forward {
            steps
        } else {
            -steps
        }
    }

    /// The increment per tick, |rate| / tick_hz in Q0.32.
    pub fn increment(&self) -> u32 {
        self.increment
    }

    /// The direction of the next steps (true = forward).
    pub fn is_forward(&self) -> bool {
        self.forward
    }

    /// The phase, Q0.32 (progress towards the next step in the current
    /// direction, starting from one half).
    pub fn phase(&self) -> u32 {
        self.phase
    }

    /// The signed rate the increment produces exactly, in steps/s.
    pub fn rate_steps_per_s(&self, tick_hz: u32) -> f32 {
        let r = self.increment as f64 * tick_hz as f64 / Q32;
        (if self.forward { r } else { -r }) as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mount::config::MountConfig;
    use crate::testing::SplitMix64;
    use std::println;

    const TICK: u32 = 50_000;
    /// 12 h of ticks at 50 kHz.
    const TICKS_12H: u64 = 12 * 3600 * TICK as u64;

    /// Steps emitted after `t` ticks from phase `p0`: the closed form.
    fn closed_form(p0: u32, inc: u32, t: u64) -> u64 {
        ((p0 as u128 + t as u128 * inc as u128) >> 32) as u64
    }

    /// Runs `t` ticks one by one; returns the signed step count.
    fn run(acc: &mut PhaseAccumulator, t: u64) -> i64 {
        let mut n = 0i64;
        let mut last = acc.stepped;
        for _ in 0..t {
            let s = acc.tick();
            assert!(!(last && s.is_some()), "steps on two consecutive ticks");
            last = s.is_some();
            match s {
                Some(true) => n += 1,
                Some(false) => n -= 1,
                None => {}
            }
        }
        n
    }

    /// 12 h in closed form against `ideal_per_s * 43 200`, and 10 min tick
    /// by tick against the closed form, for an accumulator whose rate was
    /// just set. Returns emitted - ideal after 12 h.
    fn check_12h(name: &str, mut acc: PhaseAccumulator, ideal_per_s: f64) -> f64 {
        let (p0, inc) = (acc.phase(), acc.increment());
        let emitted = closed_form(p0, inc, TICKS_12H);
        let ideal = ideal_per_s * 43_200.0;
        let err = emitted as f64 - ideal;
        println!(
            "{name}: {ideal_per_s:.6} steps/s, increment {inc}, 12 h: emitted {emitted}, ideal {ideal:.3}, error {err:+.3}"
        );
        // Tick by tick for 10 minutes, against the closed form.
        let t = 600 * TICK as u64;
        let n = run(&mut acc, t);
        assert_eq!(n as u64, closed_form(p0, inc, t), "{name}");
        assert_eq!(
            acc.phase(),
            (p0 as u64).wrapping_add(t * inc as u64) as u32,
            "{name}"
        );
        err
    }

    /// `check_12h` through the f32 `set_rate`, asserting one step.
    fn check_rate(name: &str, rate: f32, ideal_per_s: f64) -> f64 {
        let mut acc = PhaseAccumulator::new();
        assert_eq!(acc.set_rate(rate, f32::INFINITY, TICK), rate);
        let err = check_12h(name, acc, ideal_per_s);
        assert!(err.abs() <= 1.0, "{name}: error {err}");
        err
    }

    #[test]
    fn twelve_hours_of_sidereal_tracking_within_one_step() {
        // Against each mount's exact sidereal rate (the f64 quotient of its
        // configured values): the default mount, a 144-tooth worm (600 s)
        // and an odd, fast one (1 234 567 steps per worm turn, 2 864 steps/s).
        let mounts = [
            ("default EQ6-class", MountConfig::default()),
            (
                "144-tooth worm",
                MountConfig {
                    ra_steps_per_worm_turn: 200 * 32 * 4,
                    worm_period_s: 598.361_7,
                    ..MountConfig::default()
                },
            ),
            (
                "odd mount",
                MountConfig {
                    ra_steps_per_worm_turn: 1_234_567,
                    worm_period_s: 431.0,
                    ..MountConfig::default()
                },
            ),
        ];
        let bound = 0.5 + TICKS_12H as f64 / 2f64.powi(33);
        for (name, c) in mounts {
            let m = c.validate().unwrap();
            let ideal = c.ra_steps_per_worm_turn as f64 / c.worm_period_s as f64;
            assert_eq!(m.sidereal_ra_steps_per_s_f64(), ideal);
            // The f64 path: within 0.5 + 2^-33 per tick, on any mount.
            let mut acc = PhaseAccumulator::new();
            acc.set_rate_f64(ideal, m.max_ra_steps_per_s() as f64, TICK);
            let e = check_12h(&std::format!("{name} (f64 rate)"), acc, ideal);
            assert!(e.abs() <= bound, "{name}: {e}");
            // The f32 path: the rate's own rounding adds up to half an ulp
            // per second; within one step for the two slow mounts.
            let mut acc = PhaseAccumulator::new();
            acc.set_rate(m.sidereal_ra_steps_per_s(), m.max_ra_steps_per_s(), TICK);
            let e = check_12h(&std::format!("{name} (f32 rate)"), acc, ideal);
            if m.sidereal_ra_steps_per_s() < 256.0 {
                assert!(e.abs() <= 1.0, "{name}: {e}");
            }
        }
    }

    #[test]
    fn twelve_hours_at_other_rates_within_one_step() {
        let m = MountConfig::default().validate().unwrap();
        let eight = 8.0 * m.sidereal_ra_steps_per_s();
        let rates = [
            ("1 step/s", 1.0f32),
            ("8x sidereal", eight),
            ("1000/3", 1000.0 / 3.0),
            ("awkward fraction", 12_345.679),
            ("tiny", 0.001),
            ("tick / 2", 25_000.0),
        ];
        for (name, r) in rates {
            // The ideal is the f32 rate as given (its own rounding is the
            // caller's precision, not the accumulator's).
            check_rate(name, r, r as f64);
        }
    }

    #[test]
    fn closed_form_error_bound_over_many_rates() {
        // A sweep of rates: |emitted - ideal| <= 0.5 + T * 2^-33 after 12 h.
        let bound = 0.5 + TICKS_12H as f64 / 2f64.powi(33);
        let mut worst = 0.0f64;
        let mut rng = SplitMix64::new(1);
        for _ in 0..10_000 {
            let r = rng.f64_in(0.0, 25_000.0) as f32;
            let mut acc = PhaseAccumulator::new();
            acc.set_rate(r, f32::INFINITY, TICK);
            let e =
                closed_form(acc.phase(), acc.increment(), TICKS_12H) as f64 - r as f64 * 43_200.0;
            worst = worst.max(e.abs());
        }
        println!("sweep of 10 000 rates, 12 h: worst |error| {worst:.4} (bound {bound:.4})");
        assert!(worst <= bound);
    }

    #[test]
    fn rate_changes_carry_the_phase() {
        let mut acc = PhaseAccumulator::new();
        let p0 = acc.phase();
        acc.set_rate(160.438, 1e9, TICK);
        let i1 = acc.increment() as u128;
        let a = run(&mut acc, 123_457);
        acc.set_rate(240.657, 1e9, TICK);
        let i2 = acc.increment() as u128;
        let b = run(&mut acc, 98_765);
        acc.set_rate(0.0, 1e9, TICK);
        let c = run(&mut acc, 50_000);
        assert_eq!(c, 0);
        acc.set_rate(80.2, 1e9, TICK);
        let i3 = acc.increment() as u128;
        let d = run(&mut acc, 77_777);
        let total = p0 as u128 + 123_457 * i1 + 98_765 * i2 + 77_777 * i3;
        assert_eq!((a + b + c + d) as u128, total >> 32);
    }

    #[test]
    fn a_reversal_undoes_the_same_run() {
        for (rate, t) in [(80.2f32, 1_000_003u64), (1283.5, 777_777), (3.3, 99_999)] {
            let mut acc = PhaseAccumulator::new();
            assert_eq!(acc.set_rate(rate, 2000.0, TICK), rate);
            let fwd = run(&mut acc, t);
            assert!(fwd > 0);
            assert_eq!(acc.set_rate(-rate, 2000.0, TICK), -rate);
            assert!(!acc.is_forward());
            let back = run(&mut acc, t);
            assert_eq!(fwd + back, 0, "rate {rate}");
        }
    }

    #[test]
    fn signed_position_follows_the_integral_of_the_rate() {
        // Pseudo-random rates of both signs, each for a random span: the
        // signed step count stays within one step of the integral of the
        // (quantized) rates, and no two steps come on consecutive ticks.
        let mut acc = PhaseAccumulator::new();
        let mut rng = SplitMix64::new(2);
        let mut pos = 0i64;
        let mut integral = 0i128; // Q0.32 steps
        let mut worst = 0.0f64;
        for _ in 0..2_000 {
            let r = rng.f64_in(-1500.0, 1500.0) as f32;
            let t = rng.below(0x4000) + 1;
            acc.set_rate(r, 1283.5, TICK);
            let inc = acc.increment() as i128;
            let sign = if acc.is_forward() { 1 } else { -1 };
            pos += run(&mut acc, t);
            integral += sign * inc * t as i128;
            let err = pos as f64 - integral as f64 / Q32;
            worst = worst.max(err.abs());
            assert!(err.abs() <= 1.0, "{err}");
        }
        println!("random rates and reversals: worst position error {worst:.3} steps");
    }

    #[test]
    fn a_reversal_right_after_a_step_waits_a_tick() {
        let mut acc = PhaseAccumulator::new();
        acc.set_rate(25_000.0, 30_000.0, TICK); // a step every other tick
        assert_eq!(acc.increment(), 1 << 31);
        assert_eq!(acc.tick(), Some(true)); // 2^31 + 2^31 wraps
        acc.set_rate(-25_000.0, 30_000.0, TICK);
        assert_eq!(acc.tick(), None);
        assert_eq!(acc.tick(), Some(false));
        assert_eq!(acc.tick(), None);
        assert_eq!(acc.tick(), Some(false));
    }

    #[test]
    fn nan_inf_and_over_max_rates_clamp() {
        let mut acc = PhaseAccumulator::new();
        assert_eq!(acc.set_rate(f32::NAN, 1000.0, TICK), 0.0);
        assert_eq!(acc.increment(), 0);
        assert_eq!(acc.set_rate(f32::INFINITY, 1000.0, TICK), 1000.0);
        assert!(acc.is_forward());
        assert_eq!(acc.set_rate(f32::NEG_INFINITY, 1000.0, TICK), -1000.0);
        assert!(!acc.is_forward());
        assert_eq!(acc.set_rate(5000.0, 1000.0, TICK), 1000.0);
        assert_eq!(acc.increment(), (1000.0 / 50_000.0 * Q32 + 0.5) as u32);
        assert_eq!(acc.set_rate(-5000.0, 1000.0, TICK), -1000.0);
        // The tick limits too: at most tick_hz / 2.
        assert_eq!(acc.set_rate(1e9, f32::INFINITY, TICK), 25_000.0);
        assert_eq!(acc.increment(), 1 << 31);
        assert_eq!(acc.set_rate(f32::MAX, f32::MAX, TICK), 25_000.0);
        assert_eq!(acc.set_rate(-f32::MAX, f32::MAX, TICK), -25_000.0);
        // A bad max or tick stops the axis.
        assert_eq!(acc.set_rate(100.0, f32::NAN, TICK), 0.0);
        assert_eq!(acc.increment(), 0);
        assert_eq!(acc.set_rate(100.0, -1.0, TICK), 0.0);
        assert_eq!(acc.set_rate(100.0, 1000.0, 0), 0.0);
        assert_eq!(acc.increment(), 0);
        assert_eq!(run(&mut acc, 1_000_000), 0);
        // The exact rate of the increment.
        acc.set_rate(160.438, 1e4, TICK);
        assert!((acc.rate_steps_per_s(TICK) - 160.438).abs() < 1e-5);
        acc.set_rate(-160.438, 1e4, TICK);
        assert!((acc.rate_steps_per_s(TICK) + 160.438).abs() < 1e-5);
    }

    #[test]
    fn advance_matches_tick_by_tick() {
        let mut rng = SplitMix64::new(3);
        let mut by_tick = PhaseAccumulator::new();
        let mut at_once = PhaseAccumulator::new();
        for _ in 0..2_000 {
            let rate = rng.below(50_001) as f32 - 25_000.0;
            let rate = if rng.below(4) == 0 { 0.0 } else { rate };
            by_tick.set_rate(rate, 30_000.0, TICK);
            at_once.set_rate(rate, 30_000.0, TICK);
            let ticks = rng.below(300);
            let n = run(&mut by_tick, ticks);
            assert_eq!(at_once.advance(ticks), n, "rate {rate}, {ticks} ticks");
            assert_eq!(at_once, by_tick, "rate {rate}, {ticks} ticks");
        }
    }

    #[test]
    fn zero_rate_emits_nothing() {
        let mut acc = PhaseAccumulator::new();
        assert_eq!(run(&mut acc, 10_000_000), 0);
        assert_eq!(acc.set_rate(0.0, 1000.0, TICK), 0.0);
        assert_eq!(acc.set_rate(-0.0, 1000.0, TICK), 0.0);
        assert!(acc.is_forward());
        assert_eq!(run(&mut acc, 10_000_000), 0);
        // Stopping keeps the phase and the direction.
        acc.set_rate(-300.0, 1000.0, TICK);
        run(&mut acc, 12_345);
        let (p, f) = (acc.phase(), acc.is_forward());
        acc.set_rate(0.0, 1000.0, TICK);
        assert_eq!(run(&mut acc, 1_000_000), 0);
        assert_eq!((acc.phase(), acc.is_forward()), (p, f));
    }

    #[test]
    fn size_is_a_few_bytes() {
        assert_eq!(core::mem::size_of::<PhaseAccumulator>(), 12);
    }
}
