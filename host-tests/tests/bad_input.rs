//! Every bad input to the guider has a defined, tested outcome: never a
//! panic, never a NaN or an infinity out, and the fault counters say what
//! happened. Each check runs for `f64` and `f32` and for N = 1 and 2.
//!
//! The guider is first warmed up in a small noise-free closed loop on the
//! single-sinusoid gear error g(t) = 9 sin(2 pi t / 432) + 0.0008 t px
//! (frames every 2 s, SNR 10), long enough for the model to be blended in;
//! the bad input is then injected and the loop continues.

use mkgp_mount::model::gp::grid::{CELL_S, GRID_CELLS};
use mkgp_mount::model::guider::{
    Faults, Guider, GuiderConfig, DITHER_FRAMES, MAX_DITHER_OFFSET_S, MAX_FRAME_GAP_S,
    MAX_TIME_STEP_S,
};
use mkgp_mount::model::numeric::scalar::Scalar;
use std::f64::consts::PI;

const DT: f64 = 2.0;
const SNR: f64 = 10.0;
/// Largest control any frame of these runs may produce (px): the gear error
/// never moves more than 0.13 px/s, and the residuals stay within a few px.
const SANE_PX: f64 = 20.0;

fn gear(t: f64) -> f64 {
    9.0 * (2.0 * PI * t / 432.0).sin() + 0.0008 * t
}

/// A guider in a closed loop: U is the sum of the controls applied.
struct Sim<S: Scalar, const N: usize> {
    guider: Box<Guider<S, N>>,
    t: f64,
    applied: f64,
}

impl<S: Scalar, const N: usize> Sim<S, N> {
    fn new() -> Self {
        Sim {
            guider: Box::new(Guider::new(GuiderConfig::default())),
            t: 0.0,
            applied: 0.0,
        }
    }

    /// The error the camera would measure now.
    fn measured(&self) -> f64 {
        gear(self.t) - self.applied
    }

    /// Apply a control returned for the current frame and advance the clock.
    fn apply(&mut self, control: S) -> f64 {
        let c = control.to_f64();
        assert!(c.is_finite(), "control {c} at {} s", self.t);
        self.applied += c;
        self.t += DT;
        c
    }

    /// One ordinary frame.
    fn step(&mut self) -> f64 {
        let y = S::from_f64(self.measured());
        let c = self
            .guider
            .frame(self.t, y, S::from_f64(SNR), S::from_f64(DT));
        self.apply(c)
    }

    /// Ordinary frames until `until` s; returns the largest |control|.
    fn run_until(&mut self, until: f64) -> f64 {
        let mut max: f64 = 0.0;
        while self.t < until {
            max = max.max(self.step().abs());
        }
        max
    }

    /// RMS of the residual g - U over ordinary frames until `until` s.
    fn residual_rms_until(&mut self, until: f64) -> f64 {
        let (mut sum_sq, mut n) = (0.0, 0);
        while self.t < until {
            let r = self.measured();
            sum_sq += r * r;
            n += 1;
            let c = self.step();
            assert!(c.abs() <= SANE_PX, "control {c} at {} s", self.t);
        }
        (sum_sq / n as f64).sqrt()
    }

    fn faults(&self) -> Faults {
        self.guider.faults()
    }
}

/// Long enough for the period to converge and the model to be blended in.
const WARM_S: f64 = 1800.0;

fn warm<S: Scalar, const N: usize>() -> Sim<S, N> {
    let mut sim = Sim::<S, N>::new();
    let max = sim.run_until(WARM_S);
    assert!(max <= SANE_PX, "warm-up control {max}");
    assert!(
        sim.guider.blend_weight() > 0.0,
        "model not blended in after warm-up"
    );
    assert_eq!(sim.faults(), Faults::default());
    sim
}

/// Non-finite input: handled as a frame without a star (the prediction
/// alone, a fraction of a px here), counted in `bad_input`.
fn non_finite_input<S: Scalar, const N: usize>() {
    // On the very first frame (no model yet): control 0.
    let mut fresh = Sim::<S, N>::new();
    let c = fresh.guider.frame(
        0.0,
        S::from_f64(f64::NAN),
        S::from_f64(SNR),
        S::from_f64(DT),
    );
    assert_eq!(c.to_f64(), 0.0);
    assert_eq!(fresh.faults().bad_input, 1);

    let mut sim = warm::<S, N>();
    let bad = [f64::NAN, f64::INFINITY, f64::NEG_INFINITY];
    for (i, &x) in bad.iter().enumerate() {
        let c = sim
            .guider
            .frame(sim.t, S::from_f64(x), S::from_f64(SNR), S::from_f64(DT));
        let c = sim.apply(c);
        // What a dark frame gives: the predicted change over one frame.
        assert!(c.abs() <= 1.0, "input {x}: control {c}");
        assert_eq!(sim.faults().bad_input, i as u32 + 1);
    }
    // A dark frame called directly is not a fault.
    let c = sim.guider.dark_frame(sim.t, S::from_f64(DT));
    sim.apply(c);
    assert!(c.to_f64().abs() <= 1.0);
    let max = sim.run_until(WARM_S + 600.0);
    assert!(max <= SANE_PX);
    assert_eq!(
        sim.faults(),
        Faults {
            bad_input: 3,
            ..Faults::default()
        }
    );
}

/// NaN, infinite, zero or negative SNR: unknown, i.e. SNR 10. The controls
/// are exactly those of a guider given SNR 10, and nothing is counted.
fn bad_snr_is_unknown<S: Scalar, const N: usize>() {
    let mut reference = Sim::<S, N>::new();
    let mut sim = Sim::<S, N>::new();
    let bad = [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 0.0, -0.0, -5.0];
    let mut k = 0;
    while sim.t < 1500.0 {
        let y = S::from_f64(sim.measured());
        let snr = bad[k % bad.len()];
        let c = sim
            .guider
            .frame(sim.t, y, S::from_f64(snr), S::from_f64(DT));
        let c = sim.apply(c);
        let r = reference.step();
        assert_eq!(c, r, "SNR {snr} at {} s", sim.t);
        k += 1;
    }
    assert_eq!(sim.faults(), Faults::default());
}

/// A frame whose time is not finite or earlier than the last frame's is
/// ignored: control 0, counted in `bad_time`, and the frames after it get
/// exactly the controls they would have got without it. A repeated time is
/// not a fault.
fn bad_time_is_ignored<S: Scalar, const N: usize>() {
    let mut reference = warm::<S, N>();
    let mut sim = warm::<S, N>();
    let bad = [
        f64::NAN,
        f64::INFINITY,
        f64::NEG_INFINITY,
        sim.t - 2.0 * DT,
        -1.0,
    ];
    for (i, &t) in bad.iter().enumerate() {
        let y = S::from_f64(sim.measured());
        let c = sim.guider.frame(t, y, S::from_f64(SNR), S::from_f64(DT));
        assert_eq!(c.to_f64(), 0.0, "time {t}");
        let c = sim.guider.dark_frame(t, S::from_f64(DT));
        assert_eq!(c.to_f64(), 0.0, "dark frame, time {t}");
        assert_eq!(sim.faults().bad_time, 2 * (i as u32 + 1));
        // The good frame after it is unaffected.
        assert_eq!(sim.step(), reference.step(), "after time {t}");
    }
    // The same time twice is accepted (a zero interval).
    let t = sim.t - DT;
    let c = sim
        .guider
        .frame(t, S::from_f64(0.5), S::from_f64(SNR), S::from_f64(DT));
    assert!(c.to_f64().is_finite() && c.to_f64().abs() <= SANE_PX);
    assert_eq!(sim.faults().bad_time, 2 * bad.len() as u32);
    let max = sim.run_until(WARM_S + 600.0);
    assert!(max <= SANE_PX);
    assert_eq!(
        sim.faults(),
        Faults {
            bad_time: 2 * bad.len() as u32,
            ..Faults::default()
        }
    );
}

/// A gap of up to [`MAX_FRAME_GAP_S`] continues the clock: not a fault,
/// the gap's cells are filled. A clock whose resolution is coarser than a
/// frame (every frame at the same absurd time) never confirms a new clock:
/// every frame is refused (control 0, `bad_time`). Longer gaps:
/// `new_clock_is_confirmed`.
fn time_jumps<S: Scalar, const N: usize>() {
    let mut sim = warm::<S, N>();
    sim.t += MAX_FRAME_GAP_S - DT;
    let max = sim.run_until(sim.t + 600.0);
    assert!(max <= SANE_PX);
    assert_eq!(sim.faults(), Faults::default());
    for k in 0..50 {
        let t = 1e300 + k as f64 * DT;
        let y = S::from_f64(0.5 + 0.5 * (k as f64).sin());
        let c = sim.guider.frame(t, y, S::from_f64(SNR), S::from_f64(DT));
        assert_eq!(c.to_f64(), 0.0, "a frame at {t:e} s");
    }
    assert_eq!(
        sim.faults(),
        Faults {
            bad_time: 50,
            ..Faults::default()
        }
    );
}

/// A time step that is NaN, infinite, zero or negative counts as 0 s: the
/// control stays finite and sane, and nothing is counted.
fn bad_time_step<S: Scalar, const N: usize>() {
    let mut sim = warm::<S, N>();
    let bad = [f64::NAN, f64::INFINITY, 0.0, -2.0, f64::NEG_INFINITY];
    for _ in 0..3 {
        for &dt in &bad {
            let y = S::from_f64(sim.measured());
            let c = sim
                .guider
                .frame(sim.t, y, S::from_f64(SNR), S::from_f64(dt));
            let c = sim.apply(c);
            assert!(c.abs() <= SANE_PX, "time step {dt}: control {c}");
            let c = sim.guider.dark_frame(sim.t, S::from_f64(dt));
            let c = sim.apply(c);
            assert!(c.abs() <= 1.0, "dark frame, time step {dt}: control {c}");
        }
    }
    let rms = sim.residual_rms_until(sim.t + 600.0);
    assert!(rms < 1.0, "residual RMS after bad time steps {rms}");
    assert_eq!(sim.faults(), Faults::default());
}

/// A dither with a zero or non-finite rate or a non-finite amount is
/// refused (counted in `bad_dithers`) and changes nothing; a good dither
/// gives [`DITHER_FRAMES`] frames of proportional control.
fn dithers<S: Scalar, const N: usize>() {
    let mut reference = warm::<S, N>();
    let mut sim = warm::<S, N>();
    let bad = [
        (1.0, 0.0),
        (1.0, -0.0),
        (f64::NAN, 0.01),
        (f64::INFINITY, 0.01),
        (1.0, f64::NAN),
        (0.0, 0.0),
        (f64::NEG_INFINITY, f64::INFINITY),
    ];
    for (i, &(amount, rate)) in bad.iter().enumerate() {
        sim.guider.dithered(S::from_f64(amount), S::from_f64(rate));
        assert_eq!(sim.faults().bad_dithers, i as u32 + 1);
        assert_eq!(sim.step(), reference.step(), "after dither {amount}/{rate}");
    }
    // A good dither: proportional control while settling.
    let gain = sim.guider.config().control_gain;
    sim.guider.dithered(S::from_f64(3.0), S::from_f64(0.01));
    for _ in 0..DITHER_FRAMES {
        let y = S::from_f64(sim.measured() + 3.0);
        let c = sim
            .guider
            .frame(sim.t, y, S::from_f64(SNR), S::from_f64(DT));
        assert_eq!(c, gain * y);
        sim.apply(c);
    }
    // A NaN input while settling is a bad input: no proportional control,
    // and no prediction either (it would span the dither's shift), counted.
    sim.guider.dithered(S::from_f64(1.0), S::from_f64(0.01));
    let c = sim.guider.frame(
        sim.t,
        S::from_f64(f64::NAN),
        S::from_f64(SNR),
        S::from_f64(DT),
    );
    assert_eq!(c.to_f64(), 0.0);
    sim.apply(c);
    let max = sim.run_until(sim.t + 600.0);
    assert!(max <= SANE_PX);
    assert_eq!(
        sim.faults(),
        Faults {
            bad_dithers: bad.len() as u32,
            bad_input: 1,
            ..Faults::default()
        }
    );
}

/// A run long enough to fill the 2048-cell grid and wrap it twice: the
/// controls stay finite and sane, and the model keeps correcting.
fn grid_wraps<S: Scalar, const N: usize>() {
    let window = GRID_CELLS as f64 * CELL_S; // 10,240 s
    let mut sim = Sim::<S, N>::new();
    let max = sim.run_until(2.0 * window);
    assert!(max <= SANE_PX, "{max}");
    let rms = sim.residual_rms_until(2.0 * window + 1800.0);
    assert!(rms < 0.5, "residual RMS after wrapping the grid {rms}");
    assert_eq!(sim.faults(), Faults::default());
}

/// Inputs beyond `max_input` (100 px by default), up to the edge of the
/// scalar's range, are no guide error: each frame is handled as one without
/// a star (counted in `bad_input`), so the model is not poisoned and the
/// controls afterwards stay sane.
fn huge_inputs<S: Scalar, const N: usize>() {
    let edge = if S::from_f64(1e39).is_finite() {
        1e307
    } else {
        3e38
    };
    for &x in &[1e30, -1e30, 1e4, edge] {
        let mut sim = warm::<S, N>();
        for _ in 0..5 {
            let c = sim
                .guider
                .frame(sim.t, S::from_f64(x), S::from_f64(SNR), S::from_f64(DT));
            let c = c.to_f64();
            assert!(c.abs() <= SANE_PX, "input {x:e}: control {c}");
            sim.t += DT;
        }
        let mut max: f64 = 0.0;
        for _ in 0..1000 {
            max = max.max(sim.step().abs());
        }
        assert!(
            max <= SANE_PX,
            "largest control after {x:e} inputs: {max:e}"
        );
        assert_eq!(
            sim.faults(),
            Faults {
                bad_input: 5,
                ..Faults::default()
            }
        );
    }
}

/// One absurd measurement once poisoned the model for the life of the grid
/// (2.8 h): after a single 1e30 px input the controls on sane inputs reached
/// ~1e28 px. It is now a frame without a star.
fn single_outlier<S: Scalar, const N: usize>() {
    let mut sim = warm::<S, N>();
    let c = sim
        .guider
        .frame(sim.t, S::from_f64(1e30), S::from_f64(SNR), S::from_f64(DT));
    assert!(c.to_f64().is_finite());
    sim.t += DT;
    let mut max: f64 = 0.0;
    for _ in 0..1000 {
        max = max.max(sim.step().abs());
    }
    assert!(
        max <= SANE_PX,
        "largest control after one 1e30 px input: {max:e} px"
    );
    assert_eq!(sim.faults().bad_input, 1);
}

/// F1: an input beyond `max_input` while settling after a dither is a bad
/// input like any other (a frame without a star, counted), not 0.6 x 1e30.
fn huge_input_while_settling<S: Scalar, const N: usize>() {
    let mut g = Box::new(Guider::<S, N>::new(GuiderConfig::default()));
    let (snr, dt) = (S::from_f64(SNR), S::from_f64(DT));
    g.frame(0.0, S::from_f64(0.5), snr, dt);
    g.dithered(S::from_f64(1.0), S::from_f64(10.0));
    // Settling: no proportional control on a bad input.
    let c = g.frame(2.0, S::from_f64(1e30), snr, dt);
    assert_eq!(c.to_f64(), 0.0);
    let c = g.frame(4.0, S::from_f64(150.0), snr, dt);
    assert_eq!(c.to_f64(), 0.0);
    assert_eq!(g.faults().bad_input, 2);
    // Warm, the same: while settling the prediction is no control either.
    let mut sim = warm::<S, N>();
    sim.guider.dithered(S::from_f64(1.0), S::from_f64(10.0));
    for (i, &x) in [150.0, -1e30, f64::NAN].iter().enumerate() {
        let c = sim
            .guider
            .frame(sim.t, S::from_f64(x), S::from_f64(SNR), S::from_f64(DT));
        assert_eq!(c.to_f64(), 0.0, "input {x} while settling");
        sim.apply(c);
        assert_eq!(sim.faults().bad_input, i as u32 + 1);
    }
}

/// F2: one frame time from the future costs that frame, not the night: it
/// is held (control 0, counted in `bad_time`), and the frames that continue
/// the old clock are guided as if it had not come.
fn future_time_costs_one_frame<S: Scalar, const N: usize>() {
    for jump in [3600.0, 1e9, 0.5 * GRID_CELLS as f64 * CELL_S] {
        let mut reference = warm::<S, N>();
        let mut sim = warm::<S, N>();
        let y = S::from_f64(sim.measured());
        let c = sim
            .guider
            .frame(sim.t + jump, y, S::from_f64(SNR), S::from_f64(DT));
        assert_eq!(c.to_f64(), 0.0, "jump {jump}");
        assert_eq!(sim.faults().bad_time, 1);
        // The next frames continue the old clock: exactly the reference's
        // controls (the held frame taught nothing).
        for k in 0..900 {
            assert_eq!(sim.step(), reference.step(), "jump {jump}, frame {k}");
        }
        assert_eq!(
            sim.faults(),
            Faults {
                bad_time: 1,
                ..Faults::default()
            }
        );
        let rms = sim.residual_rms_until(sim.t + 600.0);
        assert!(rms < 0.5, "jump {jump}: residual RMS {rms}");
    }
}

/// F2: a clock that really moved (forward beyond the frame gap, or back) is
/// taken once a second frame continues it: the first frame is held
/// (`bad_time`), then guiding goes on from the new clock; beyond the
/// window, or backwards, learning starts again (`grid_restarts`).
fn new_clock_is_confirmed<S: Scalar, const N: usize>() {
    let window = GRID_CELLS as f64 * CELL_S;
    for (jump, restarts) in [(1800.0, 0), (3.0 * window, 1), (-1e5, 1)] {
        let mut sim = warm::<S, N>();
        // Only the clock moves: the telescope's error goes on.
        sim.applied += gear(sim.t + jump) - gear(sim.t);
        sim.t += jump;
        let y = S::from_f64(sim.measured());
        let c = sim
            .guider
            .frame(sim.t, y, S::from_f64(SNR), S::from_f64(DT));
        assert_eq!(c.to_f64(), 0.0, "jump {jump}");
        sim.t += DT;
        sim.step();
        let max = sim.run_until(sim.t + 2400.0);
        assert!(max <= SANE_PX, "jump {jump}: control {max}");
        let rms = sim.residual_rms_until(sim.t + 1200.0);
        assert!(rms < 0.5, "jump {jump}: residual RMS {rms}");
        assert_eq!(
            sim.faults(),
            Faults {
                bad_time: 1,
                grid_restarts: restarts,
                ..Faults::default()
            },
            "jump {jump}"
        );
    }
}

/// F3: the time step is bounded by [`MAX_TIME_STEP_S`]: a longer one gives
/// exactly the control of a step of that length, and the guiding after it
/// stays sane.
fn huge_time_step<S: Scalar, const N: usize>() {
    for dark in [false, true] {
        let mut reference = warm::<S, N>();
        let mut sim = warm::<S, N>();
        let y = S::from_f64(0.223);
        let (c, r) = if dark {
            (
                sim.guider.dark_frame(sim.t, S::from_f64(1e6)),
                reference
                    .guider
                    .dark_frame(sim.t, S::from_f64(MAX_TIME_STEP_S)),
            )
        } else {
            (
                sim.guider
                    .frame(sim.t, y, S::from_f64(SNR), S::from_f64(1e6)),
                reference
                    .guider
                    .frame(sim.t, y, S::from_f64(SNR), S::from_f64(MAX_TIME_STEP_S)),
            )
        };
        assert_eq!(c, r, "dark {dark}");
        let c = sim.apply(c);
        assert!(c.abs() <= 5.0, "dark {dark}: control {c}");
        let max = sim.run_until(sim.t + 3600.0);
        assert!(max <= 5.0, "dark {dark}: control {max} in the hour after");
        assert_eq!(sim.faults(), Faults::default());
    }
}

/// F4: a dither whose gear-time offset is beyond [`MAX_DITHER_OFFSET_S`]
/// is refused (`bad_dithers`) and changes nothing: learning and the
/// reported progress go on exactly as without it.
fn absurd_dither<S: Scalar, const N: usize>() {
    let mut reference = warm::<S, N>();
    let mut sim = warm::<S, N>();
    for (amount, rate) in [
        (1e30, 1e-30),
        (-1e30, 1e-30),
        (1.01 * MAX_DITHER_OFFSET_S, 1.0),
    ] {
        sim.guider.dithered(S::from_f64(amount), S::from_f64(rate));
    }
    assert_eq!(sim.faults().bad_dithers, 3);
    while sim.t < WARM_S + 4.0 * 3600.0 {
        assert_eq!(sim.step(), reference.step(), "at {} s", sim.t);
        assert_eq!(
            sim.guider.learning_progress(),
            reference.guider.learning_progress()
        );
    }
    assert!(sim.guider.prediction().to_f64() != 0.0);
}

/// F5: `observe` gives an observation whose measured part (the gear error
/// less the applied corrections) is not finite or beyond `max_input` the
/// same treatment as `frame`: not learned (an unmeasured frame), counted in
/// `bad_input`; the feed-forwards after it stay sane.
fn observe_huge_gear_error<S: Scalar, const N: usize>() {
    let mut g = Box::new(Guider::<S, N>::new(GuiderConfig::default()));
    let (snr, dt) = (S::from_f64(SNR), S::from_f64(DT));
    let mut t = 0.0;
    while t < WARM_S {
        g.observe(t, Some(gear(t)), 0.0, snr, dt);
        t += DT;
    }
    // A large applied correction is not an error: only the measured part counts.
    g.observe(t, Some(gear(t) + 500.0), 500.0, snr, dt);
    t += DT;
    for (i, &x) in [1e30, -150.0, f64::NAN].iter().enumerate() {
        let ff = g.observe(t, Some(gear(t) + x), 0.0, snr, dt).to_f64();
        assert!(ff.abs() <= 1.0, "observation {x}: feed-forward {ff}");
        assert_eq!(g.faults().bad_input, i as u32 + 1);
        t += DT;
    }
    let mut max: f64 = 0.0;
    while t < WARM_S + 3.0 * 3600.0 {
        max = max.max(g.observe(t, Some(gear(t)), 0.0, snr, dt).to_f64().abs());
        t += DT;
    }
    // The gear error moves at most 0.13 px/s: 0.26 px a frame.
    assert!(max <= 0.5, "feed-forward {max} after a huge observation");
    assert_eq!(
        g.faults(),
        Faults {
            bad_input: 3,
            ..Faults::default()
        }
    );
}

macro_rules! for_each_variant {
    ($($check:ident),* $(,)?) => {
        $(mod $check {
            #[test]
            fn f64_n1() {
                super::$check::<f64, 1>();
            }
            #[test]
            fn f64_n2() {
                super::$check::<f64, 2>();
            }
            #[test]
            fn f32_n1() {
                super::$check::<f32, 1>();
            }
            #[test]
            fn f32_n2() {
                super::$check::<f32, 2>();
            }
        })*
    };
}

for_each_variant!(
    non_finite_input,
    bad_snr_is_unknown,
    bad_time_is_ignored,
    time_jumps,
    bad_time_step,
    dithers,
    grid_wraps,
    huge_inputs,
    single_outlier,
    huge_input_while_settling,
    future_time_costs_one_frame,
    new_clock_is_confirmed,
    huge_time_step,
    absurd_dither,
    observe_huge_gear_error,
);
