//! Running the model in `f32` (the target) costs nothing that matters
//! against the `f64` reference: on every synthetic case C1..C8 and for
//! N = 1 and 2,
//!
//! (a) per frame: the `f64` guider and the `f32` guider each run the
//!     paper's closed loop (frames every 2 s to 10,798 s, y = g(t) - U +
//!     noise) with the same 1 px noise of seed 1, and every frame's (time,
//!     input, SNR, time step) and control are recorded. Frame by frame the
//!     two guiders get the same time, SNR, time step, gear error and noise;
//!     the `f32` input is the `f64` input corrected for the difference of the
//!     controls already applied, U32 - U64 (checked below). The RMS over all
//!     frames of control_f32 - control_f64 must be <= 0.01 px;
//! (b) closed loop: the residual RMS (frames t >= 3600 s) of `f32` must be
//!     within 1 % of that of `f64`, noise-free and with the noise above.
//!
//! Why not feed the `f32` guider the `f64` inputs unchanged: the guider
//! reconstructs the gear error as (sum of its own controls) + input, so with
//! another guider's inputs it sees g + (U32 - U64). Nothing feeds that
//! difference back, so the per-frame rounding differences (about 0.002 px)
//! add up to a random walk (up to 1.1 px on C5 with N = 1), which the model
//! then learns and predicts as if it were gear error; the control
//! difference grows over the run (C8 N = 1: 0.003 px RMS in the first
//! quarter, 0.025 px in the last). That is an artefact of the replay, not
//! of the precision: a real mount applies its own controls. The figure is
//! still computed and printed ("uncorrected replay"), not asserted.
//!
//! The 16 (case, N) runs are spread over the machine's cores and shared by
//! the two tests; every figure is printed (`--nocapture` to see them).

use host_tests::cases::{self, Case};
use host_tests::closed_loop::{self, Noise};
use host_tests::data;
use host_tests::gp::GpAlgorithm;
use host_tests::guide_algorithm::GuideAlgorithm;
use mkgp_mount::model::guider::{Guider, GuiderConfig};
use rayon::prelude::*;
use std::sync::OnceLock;

/// Largest RMS of control_f32 - control_f64 over the frames (px).
const OUTPUT_RMS_TOLERANCE_PX: f64 = 0.01;
/// Largest |rms_f32 / rms_f64 - 1| of the closed-loop residuals.
const RESIDUAL_RATIO_TOLERANCE: f64 = 0.01;
const NOISE: Noise = Noise::Gaussian {
    sigma_px: 1.0,
    seed: 1,
};

/// One frame as the `f64` guider saw it, and its control.
#[derive(Clone, Copy)]
struct Recorded {
    time_s: f64,
    input: f64,
    snr: f64,
    time_step: f64,
    control: f64,
}

/// Passes the frames through to `inner` and records them.
struct Recorder<C> {
    inner: C,
    frames: Vec<Recorded>,
}

impl<C: GuideAlgorithm> GuideAlgorithm for Recorder<C> {
    fn step(&mut self, t: f64, measured: f64, snr: f64, dt: f64) -> f64 {
        let control = self.inner.step(t, measured, snr, dt);
        self.frames.push(Recorded {
            time_s: t,
            input: measured,
            snr,
            time_step: dt,
            control,
        });
        control
    }
}

/// The figures of one (case, N).
#[derive(Clone, Debug)]
struct Figures {
    case: String,
    stages: usize,
    /// (a): RMS and largest |control_f32 - control_f64| over the frames, the
    /// time of the largest, and the RMS of the `f64` controls for scale.
    output_rms: f64,
    output_max: f64,
    output_max_at_s: f64,
    control_rms: f64,
    /// The `f32` guider fed the `f64` inputs unchanged: RMS of the control
    /// difference and the largest |U32 - U64| (printed only).
    uncorrected_rms: f64,
    uncorrected_max_du: f64,
    /// (b): residual RMS, noise-free and noisy, `f64` then `f32`.
    clean: (f64, f64),
    noisy: (f64, f64),
}

/// `x` is over `tolerance`, or NaN (a figure that cannot be compared fails).
fn exceeds(x: f64, tolerance: f64) -> bool {
    x.is_nan() || x > tolerance
}

fn rel(pair: (f64, f64)) -> f64 {
    pair.1 / pair.0 - 1.0
}

fn recorded<C: GuideAlgorithm>(case: &Case, inner: C, noise: Noise) -> (f64, Vec<Recorded>) {
    let mut rec = Recorder {
        inner,
        frames: Vec::new(),
    };
    let rms = closed_loop::run(case, &mut rec, noise);
    assert_eq!(rec.frames.len(), closed_loop::FRAMES);
    for f in &rec.frames {
        assert!(
            f.control.is_finite(),
            "{}: control at {} s",
            case.name,
            f.time_s
        );
    }
    (rms, rec.frames)
}

/// (a): the per-frame control differences of two recorded runs.
fn compare(case: &str, f64_run: &[Recorded], f32_run: &[Recorded]) -> (f64, f64, f64) {
    let (mut sum_sq, mut max, mut max_at) = (0.0, 0.0, 0.0);
    let (mut u64_applied, mut u32_applied) = (0.0, 0.0);
    for (a, b) in f64_run.iter().zip(f32_run) {
        // Same frame; the inputs differ by exactly the controls applied.
        assert_eq!(
            (a.time_s, a.snr, a.time_step),
            (b.time_s, b.snr, b.time_step)
        );
        let expected = a.input - (u32_applied - u64_applied);
        assert!(
            (b.input - expected).abs() <= 1e-9 * (1.0 + a.input.abs()),
            "{case}: f32 input {} vs {expected} at {} s",
            b.input,
            a.time_s
        );
        u64_applied += a.control;
        u32_applied += b.control;
        let d = b.control - a.control;
        sum_sq += d * d;
        if d.abs() > max {
            max = d.abs();
            max_at = a.time_s;
        }
    }
    ((sum_sq / f64_run.len() as f64).sqrt(), max, max_at)
}

/// The `f64` run's frames fed unchanged to an `f32` guider (see the module
/// documentation): RMS of the control difference and the largest |U32 - U64|.
fn uncorrected_replay<const N: usize>(frames: &[Recorded]) -> (f64, f64) {
    let mut guider = Box::new(Guider::<f32, N>::new(GuiderConfig::default()));
    let (mut sum_sq, mut du, mut max_du) = (0.0, 0.0, 0.0f64);
    for f in frames {
        let c = guider.frame(f.time_s, f.input as f32, f.snr as f32, f.time_step as f32) as f64;
        assert!(c.is_finite(), "f32 control not finite at {} s", f.time_s);
        let d = c - f.control;
        sum_sq += d * d;
        du += d;
        max_du = max_du.max(du.abs());
    }
    ((sum_sq / frames.len() as f64).sqrt(), max_du)
}

fn figures<const N: usize>(case: &Case) -> Figures {
    let (noisy64, run64) = recorded(case, GpAlgorithm::<N, f64>::new(None, None), NOISE);
    let (noisy32, run32) = recorded(case, GpAlgorithm::<N, f32>::new(None, None), NOISE);
    let (output_rms, output_max, output_max_at_s) = compare(&case.name, &run64, &run32);
    let control_rms =
        (run64.iter().map(|f| f.control * f.control).sum::<f64>() / run64.len() as f64).sqrt();
    let (uncorrected_rms, uncorrected_max_du) = uncorrected_replay::<N>(&run64);
    let clean64 = closed_loop::run(
        case,
        &mut GpAlgorithm::<N, f64>::new(None, None),
        Noise::None,
    );
    let clean32 = closed_loop::run(
        case,
        &mut GpAlgorithm::<N, f32>::new(None, None),
        Noise::None,
    );
    Figures {
        case: case.name.clone(),
        stages: N,
        output_rms,
        output_max,
        output_max_at_s,
        control_rms,
        uncorrected_rms,
        uncorrected_max_du,
        clean: (clean64, clean32),
        noisy: (noisy64, noisy32),
    }
}

/// All 16 runs, computed once on rayon's threads (in the order of the
/// jobs) and shared by the tests.
fn all_figures() -> &'static [Figures] {
    static FIGURES: OnceLock<Vec<Figures>> = OnceLock::new();
    FIGURES.get_or_init(|| {
        let cases = cases::load(&data::cases_file()).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(cases.len(), 8, "expected the cases C1..C8");
        let jobs: Vec<(&Case, usize)> = cases
            .iter()
            .flat_map(|c| [(c, 1), (c, 2)])
            .collect();
        let figures: Vec<Figures> = jobs
            .into_par_iter()
            .map(|(case, n)| match n {
                1 => figures::<1>(case),
                _ => figures::<2>(case),
            })
            .collect();
        println!(
            "case N | ctrl diff RMS   max (at s) | ctrl RMS | clean f64  f32   rel       | \
             noisy f64  f32   rel       | uncorrected replay: diff RMS, max |U32-U64|"
        );
        for f in &figures {
            println!(
                "{:4} {} | {:.2e} {:.2e} ({:5.0}) | {:.3}    | {:.4} {:.4} {:+.2e} | {:.4} {:.4} {:+.2e} | {:.2e} {:.3}",
                f.case,
                f.stages,
                f.output_rms,
                f.output_max,
                f.output_max_at_s,
                f.control_rms,
                f.clean.0,
                f.clean.1,
                rel(f.clean),
                f.noisy.0,
                f.noisy.1,
                rel(f.noisy),
                f.uncorrected_rms,
                f.uncorrected_max_du,
            );
        }
        figures
    })
}

#[test]
fn f32_controls_follow_f64_frame_by_frame() {
    let bad: Vec<String> = all_figures()
        .iter()
        .filter(|f| exceeds(f.output_rms, OUTPUT_RMS_TOLERANCE_PX))
        .map(|f| {
            format!(
                "{} N={}: control RMS difference {:.4} px (max {:.4} px at {} s)",
                f.case, f.stages, f.output_rms, f.output_max, f.output_max_at_s
            )
        })
        .collect();
    assert!(bad.is_empty(), "{}", bad.join("\n"));
}

#[test]
fn f32_closed_loop_residuals_within_one_percent() {
    let mut bad = Vec::new();
    for f in all_figures() {
        for (what, pair) in [("noise-free", f.clean), ("1 px seed 1", f.noisy)] {
            assert!(pair.0.is_finite() && pair.1.is_finite());
            if exceeds(rel(pair).abs(), RESIDUAL_RATIO_TOLERANCE) {
                bad.push(format!(
                    "{} N={} {what}: f32 {:.4} vs f64 {:.4} px ({:+.2} %)",
                    f.case,
                    f.stages,
                    pair.1,
                    pair.0,
                    100.0 * rel(pair)
                ));
            }
        }
    }
    assert!(bad.is_empty(), "{}", bad.join("\n"));
}
