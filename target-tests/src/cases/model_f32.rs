//! The `f32` model on the Cortex-M4F: the LDLT solve, the FFT, the
//! spectrum's period estimate, and short noise-free closed loops of
//! `Guider<f32, 1>` and `Guider<f32, 2>` (in statics: about 55 KiB each),
//! each judged against PHD2's hysteresis guider in the same loop.
//!
//! The simulated gear error, the applied sum and the scores are computed in
//! `f64` (soft-float here) outside the guider.

use crate::harness::{check, close_abs, TestResult};
use crate::support::Slot;
use core::f64::consts::PI;
use cortex_m_semihosting::hprintln;
use mkgp_mount::model::gp::grid::{Averaging, Grid};
use mkgp_mount::model::guider::{Guider, GuiderConfig};
use mkgp_mount::model::ldlt::{FactorError, Ldlt};
use mkgp_mount::model::numeric::scalar::Scalar;
use mkgp_mount::model::spectral::fft::{power_spectrum, FFT_LEN};
use mkgp_mount::model::spectral::spectrum::{Spectrum, NYQUIST_BIN};

fn sin64(x: f64) -> f64 {
    <f64 as Scalar>::sin(x)
}

fn exp64(x: f64) -> f64 {
    <f64 as Scalar>::exp(x)
}

fn abs(x: f64) -> f64 {
    if x < 0.0 {
        -x
    } else {
        x
    }
}

/// LDLT of a 6 x 6 Gram-like matrix (squared-exponential kernel on 5 s
/// cells plus a noise diagonal): the solve recovers a known x from b = A x
/// within 1e-4 of max |x|; an indefinite matrix is refused.
pub fn ldlt_known_solve() -> TestResult {
    let mut a = [[0.0f64; 6]; 6];
    for (i, row) in a.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            let d = (i as f64 - j as f64) * 5.0;
            *v = 400.0 * exp64(-d * d / (2.0 * 30.0 * 30.0));
        }
        row[i] += 0.5 + i as f64 * 0.1;
    }
    let x = [1.0, -2.0, 0.5, 3.0, -1.0, 0.25];
    let mut b = [0.0f32; 6];
    for i in 0..6 {
        let mut s = 0.0;
        for j in 0..6 {
            s += a[i][j] * x[j];
        }
        b[i] = s as f32;
    }
    let mut f: Ldlt<f32, 8, 36> = Ldlt::new();
    f.set_dim(6);
    for (i, row) in a.iter().enumerate() {
        for (r, &v) in f.row_mut(i).iter_mut().zip(row) {
            *r = v as f32;
        }
    }
    check(f.factor().is_ok(), "factor refused an SPD matrix")?;
    check(f.solve(&mut b).is_ok(), "solve refused a factored matrix")?;
    let mut worst = 0.0;
    for i in 0..6 {
        worst = if abs(b[i] as f64 - x[i]) > worst {
            abs(b[i] as f64 - x[i])
        } else {
            worst
        };
    }
    hprintln!("    largest |x - x_known|: {:e}", worst);
    close_abs("LDLT solve", worst, 0.0, 1e-4 * 3.0)?;

    let mut g: Ldlt<f32, 2, 3> = Ldlt::new();
    g.set_dim(2);
    g.row_mut(0).copy_from_slice(&[1.0]);
    g.row_mut(1).copy_from_slice(&[2.0, 1.0]);
    check(
        g.factor() == Err(FactorError::NotPositiveDefinite { row: 1 }),
        "indefinite matrix not refused",
    )
}

static FFT_BUF: Slot<[f32; FFT_LEN]> = Slot::new();

/// A pure tone in bin 100 (cos, amplitude 1): all its power, (4096 / 2)^2,
/// lands in bin 100, and every other bin holds less than 1e-6 of it.
pub fn fft_pure_tone() -> TestResult {
    const BIN: usize = 100;
    let buf = FFT_BUF.init([0.0; FFT_LEN]);
    for (n, x) in buf.iter_mut().enumerate() {
        // Phase reduced exactly before the f32 cosine.
        let m = (BIN * n) % FFT_LEN;
        *x = Scalar::cos(2.0 * core::f32::consts::PI * m as f32 / FFT_LEN as f32);
    }
    power_spectrum(buf);
    let mut peak_bin = 0;
    for k in 0..=NYQUIST_BIN {
        if buf[k] > buf[peak_bin] {
            peak_bin = k;
        }
    }
    let peak = buf[BIN] as f64;
    let mut leak = 0.0f64;
    for (k, &p) in buf.iter().enumerate().take(NYQUIST_BIN + 1) {
        if k != BIN && p as f64 > leak {
            leak = p as f64;
        }
    }
    hprintln!(
        "    peak bin {}, power {:e}, largest other bin {:e}",
        peak_bin,
        peak,
        leak
    );
    check(peak_bin == BIN, "tone not in its bin")?;
    let full = (FFT_LEN as f64 / 2.0) * (FFT_LEN as f64 / 2.0);
    close_abs("tone power / (N/2)^2", peak / full, 1.0, 1e-4)?;
    check(leak < 1e-6 * peak, "power leaked out of the tone's bin")
}

static GRID: Slot<Grid<f32>> = Slot::new();
static SPECTRUM_BUF: Slot<[f32; FFT_LEN]> = Slot::new();

/// The spectrum of 8,000 s of 9 sin(2 pi t / 432) + 0.001 t on the grid
/// (frames every 2 s) has its strongest line at 432 s (within 2 s).
pub fn spectrum_finds_the_period() -> TestResult {
    let grid = GRID.init(Grid::new(Averaging::Exact));
    let mut t = 0.0;
    while t < 8000.0 {
        grid.push(t, 9.0 * sin64(2.0 * PI * t / 432.0) + 0.001 * t, 1.0);
        t += 2.0;
    }
    let buf = SPECTRUM_BUF.init([0.0; FFT_LEN]);
    let Some(spectrum) = Spectrum::compute(grid, buf) else {
        return Err("spectrum not computed");
    };
    let line = spectrum.strongest(0, NYQUIST_BIN, |_| true);
    let Some(line) = line else {
        return Err("no line");
    };
    hprintln!("    strongest line: {} s", line.period_s);
    close_abs("period", line.period_s, 432.0, 2.0)
}

/// Frames every 2 s.
const LOOP_DT: f64 = 2.0;

/// How long a closed loop runs, and from when it is scored.
#[derive(Clone, Copy)]
struct Run {
    frames: usize,
    score_from_s: f64,
}

/// t = 0 .. 2998 s; scored from 1200 s.
const ONE_STAGE: Run = Run {
    frames: 1500,
    score_from_s: 1200.0,
};
/// t = 0 .. 5998 s, scored from 3600 s (the paper's table): C5's 155 s
/// stage lies 7 % from the 432 s worm's 144 s division, inside its notch,
/// and is admitted once the data spans 1.5 beats against it (3,044 s:
/// `near_harmonic`).
const TWO_STAGES: Run = Run {
    frames: 3000,
    score_from_s: 3600.0,
};

/// Residual RMS over the scored frames of a noise-free closed loop on
/// `gear`, and the open loop's over the same frames (px).
struct Scores {
    residual: f64,
    open: f64,
}

/// Runs a noise-free closed loop: `control(t, input)` gets the residual the
/// camera sees at frame time t and returns the control, which is applied in
/// full. An error (a control that is not finite) ends the run.
fn closed_loop(
    gear: fn(f64) -> f64,
    run: Run,
    mut control: impl FnMut(f64, f64) -> Result<f64, &'static str>,
) -> Result<Scores, &'static str> {
    let mut applied = 0.0f64;
    let (mut sum_sq, mut open_sq, mut n) = (0.0f64, 0.0f64, 0usize);
    for k in 0..run.frames {
        let t = k as f64 * LOOP_DT;
        let g = gear(t);
        let residual = g - applied;
        if t >= run.score_from_s {
            sum_sq += residual * residual;
            open_sq += g * g;
            n += 1;
        }
        applied += control(t, residual)?;
    }
    Ok(Scores {
        residual: <f64 as Scalar>::sqrt(sum_sq / n as f64),
        open: <f64 as Scalar>::sqrt(open_sq / n as f64),
    })
}

/// The guider in [`closed_loop`] (SNR 10); no fault may be counted.
fn guided<const N: usize>(
    guider: &mut Guider<f32, N>,
    gear: fn(f64) -> f64,
    run: Run,
) -> Result<Scores, &'static str> {
    let scores = closed_loop(gear, run, |t, input| {
        let control = guider.frame(t, input as f32, 10.0, LOOP_DT as f32);
        if !control.is_finite() {
            hprintln!("    control {} at {} s", control, t);
            return Err("control not finite");
        }
        Ok(control as f64)
    })?;
    let faults = guider.faults();
    if faults != Default::default() {
        hprintln!("    {:?}", faults);
        return Err("faults counted");
    }
    Ok(scores)
}

/// PHD2's hysteresis guider, the reactive baseline the model must beat:
/// control = aggressiveness x ((1 - hysteresis) x input + hysteresis x
/// previous control), 0 when |input| < min move (as host-tests'
/// `controller::Hysteresis`), with the paper's 0.6 / 0.1 / 0.2.
fn hysteresis(gear: fn(f64) -> f64, run: Run) -> Result<Scores, &'static str> {
    const AGGRESSIVENESS: f64 = 0.6;
    const HYSTERESIS: f64 = 0.1;
    const MIN_MOVE_PX: f64 = 0.2;
    let mut previous = 0.0f64;
    closed_loop(gear, run, |_, input| {
        previous = if abs(input) < MIN_MOVE_PX {
            0.0
        } else {
            AGGRESSIVENESS * ((1.0 - HYSTERESIS) * input + HYSTERESIS * previous)
        };
        Ok(previous)
    })
}

/// The model's residual RMS against hysteresis's in the same loop: at most
/// `max_ratio` of it. The runs are exact and repeat in QEMU, so each test's
/// ratio is the one measured, rounded up a little: a model that learns less
/// fails.
fn score(model: &Scores, reactive: &Scores, max_ratio: f64) -> TestResult {
    let ratio = model.residual / reactive.residual;
    hprintln!(
        "    residual RMS {} px, hysteresis {} px (ratio {}, at most {}), open loop {} px",
        model.residual,
        reactive.residual,
        ratio,
        max_ratio,
        model.open
    );
    check(
        ratio <= max_ratio,
        "the model does not beat hysteresis by the margin",
    )
}

static GUIDER_1: Slot<Guider<f32, 1>> = Slot::new();
static GUIDER_2: Slot<Guider<f32, 2>> = Slot::new();

/// C1: one sinusoid and drift.
fn c1(t: f64) -> f64 {
    9.0 * sin64(2.0 * PI * t / 432.0) + 0.0008 * t
}

/// Two stages: C1 plus a 155 s stage (C5's).
fn two_stage(t: f64) -> f64 {
    c1(t) + 4.5 * sin64(2.0 * PI * t / 155.0)
}

/// `Guider<f32, 1>` on C1, noise-free, 1,500 frames, against hysteresis.
pub fn closed_loop_n1() -> TestResult {
    let guider = GUIDER_1.init(Guider::new(GuiderConfig::default()));
    let model = guided(guider, c1, ONE_STAGE)?;
    hprintln!("    period {} s", guider.period_s(0));
    score(&model, &hysteresis(c1, ONE_STAGE)?, 0.58)
}

/// `Guider<f32, 2>` on the two-stage signal, noise-free, 3,000 frames,
/// against hysteresis.
pub fn closed_loop_n2() -> TestResult {
    let guider = GUIDER_2.init(Guider::new(GuiderConfig::default()));
    let model = guided(guider, two_stage, TWO_STAGES)?;
    hprintln!(
        "    periods {} s, {} s (gate {})",
        guider.period_s(0),
        guider.period_s(1),
        guider.gate(1)
    );
    score(&model, &hysteresis(two_stage, TWO_STAGES)?, 0.40)
}
