//! Instructions per guide frame of the `f32` guider on the emulated
//! Cortex-M4F: the QEMU half of `guide-sim bench` (host-tests).
//!
//! `cargo run --release --bin bench` (in target-tests) runs, on the target,
//! the paper's closed loop on case C8 with N(0, 1 px) noise, seed 1, frames
//! every 2 s, for [`FRAMES`] frames (t = 0 .. 4798 s), with
//! `Guider<f32, 1>`, `Guider<f32, 2>` and `Guider<f32, 3>` in turn, and counts the
//! instructions of every `frame` call with the SysTick counter
//! ([`instr`], exact under `-icount shift=0`, resolution 40 instructions;
//! the two counter reads add about one tick). Only the `frame` call is
//! measured: the simulation (gear error, noise, the applied sum) is computed
//! in soft-float `f64` outside it.
//!
//! Measured frames: the active ones, t >= [`ACTIVE_FROM_S`] (1,800 frames),
//! as on the host: the prediction is fully blended in from about 600 s, and
//! the spectrum (FFT), period tracking and stage discovery run from 600 s;
//! the GP fit itself runs from t = 20 s. One line per model:
//!
//! ```text
//! bench stages=1 frames=1800 from_s=1200 median=... p90=... max=... state_bytes=... rms_px=...
//! ```
//! median and p90 are nearest-rank percentiles, `state_bytes` is
//! `size_of::<Guider<f32, N>>()`, `rms_px` the residual RMS over the same
//! frames (a sanity check that the model guides).
//!
//! Then the three-stage model is saved and taken back as after a power
//! cycle, with the phase known, the worm's alone and unknown in turn, and
//! [`RESTORED_FRAMES`] frames after each are counted:
//!
//! ```text
//! restore stages=3 phase=worm frames=300 median=... max=... rms_px=...
//! ```
//!
//! The goals are asserted: the run exits 1, after the result lines, with a
//! `FAILED:` line when the median for `Guider<f32, 2>` or `Guider<f32, 3>`
//! exceeds [`BUDGET_MEDIAN`] instructions (the counts are exact and repeat,
//! so there is no margin to leave) or its state [`BUDGET_STATE_BYTES`], or
//! a frame after a restore [`BUDGET_RESTORED_MAX`]. It also exits 1 if it
//! panics or faults.
#![no_std]
#![no_main]

#[path = "../instr.rs"]
mod instr;
#[path = "../support.rs"]
mod support;

use core::f64::consts::PI;
use core::hint::black_box;
use cortex_m_rt::{entry, exception, ExceptionFrame};
use cortex_m_semihosting::hprintln;
use mkgp_mount::model::guider::{Guider, GuiderConfig};
use mkgp_mount::model::snapshot::{Phase, Snapshot, SNAPSHOT_MAX};
use mkgp_mount::testing::Gaussian;
use support::{exit, Slot};

/// Time between frames (s).
const DT: f64 = 2.0;
/// Frames of the run: t = 0 .. 4798 s.
const FRAMES: usize = 2400;
/// Frames with t >= this (s) are measured.
const ACTIVE_FROM_S: f64 = 1200.0;
const ACTIVE_FROM_FRAME: usize = (ACTIVE_FROM_S / DT) as usize;
const ACTIVE: usize = FRAMES - ACTIVE_FROM_FRAME;
/// The microcontroller budget for the two- and three-stage guiders
/// (docs/reference.md, issue 10): median instructions per active frame.
const BUDGET_MEDIAN: u32 = 1_000_000;
/// ... and bytes of model state (`size_of::<Guider<f32, N>>()`).
const BUDGET_STATE_BYTES: usize = 64 * 1024;
/// A power cycle after the run: the model is saved at its end, the gears
/// turn this long while the mount is off (three of C8's worm periods, so
/// that the worm's phase is where it was and the other stages' are not),
/// and the restored model guides this many frames (two worm periods: past
/// the phase search and the stages' refine, half a worm period each).
const SAVED_AT_S: f64 = FRAMES as f64 * DT;
const TURNED_S: f64 = 3.0 * C8[0].0;
const RESTORED_FRAMES: usize = 300;
/// The most instructions any frame after a restore may take: one 2 s
/// guide cycle (1 s exposures and their download) at the F411's 96 MHz
/// and half an instruction a clock cycle (the median frame's 0.88 M take
/// 10-20 ms there). The placement, the phase search and the stages'
/// refine each run within one frame.
const BUDGET_RESTORED_MAX: u32 = 96_000_000;
/// The SNR the guider is given (as in host-tests' closed loop).
const SNR: f32 = 10.0;
/// Noise: N(0, 1 px) from this seed.
const SEED: u64 = 1;
const SIGMA_PX: f64 = 1.0;

/// Case C8 of `synthetic_cases.csv`: (period s, amplitude px), phases 0.
const C8: [(f64, f64); 4] = [(288.0, 9.0), (144.0, 6.0), (110.0, 4.5), (55.0, 3.6)];
const C8_DRIFT_PX_PER_S: f64 = 0.0008;

/// g(t) of case C8, px (as host-tests' `Case::gear_error`).
fn gear_error(t: f64) -> f64 {
    let mut periodic = 0.0;
    for (period, amplitude) in C8 {
        periodic += amplitude * libm::sin(2.0 * PI * t / period);
    }
    periodic + C8_DRIFT_PX_PER_S * t
}

// mps2-an386 has 4 MiB of data RAM: the three guiders fit side by side.
static GUIDER_1: Slot<Guider<f32, 1>> = Slot::new();
static GUIDER_2: Slot<Guider<f32, 2>> = Slot::new();
static GUIDER_3: Slot<Guider<f32, 3>> = Slot::new();
static COUNTS: Slot<[u32; ACTIVE]> = Slot::new();
static RESTORED_COUNTS: Slot<[u32; RESTORED_FRAMES]> = Slot::new();
static SAVED: Slot<[u8; SNAPSHOT_MAX]> = Slot::new();

/// Guides `frames` frames of C8 from gear time `gear_from_s` (the star
/// centred at the first) and writes the instructions of each frame from
/// `counted_from` on to `counts` (sorted on return); returns the residual
/// RMS over those frames.
fn guide<const N: usize>(
    guider: &mut Guider<f32, N>,
    frames: usize,
    gear_from_s: f64,
    counted_from: usize,
    counts: &mut [u32],
) -> f64 {
    let mut gauss = Gaussian::new(SEED);
    let mut applied = gear_error(gear_from_s); // U: the sum of the controls applied
    let mut sum_sq = 0.0f64;
    instr::start();
    for k in 0..frames {
        let t = k as f64 * DT;
        let residual = gear_error(gear_from_s + t) - applied;
        let input = (residual + SIGMA_PX * gauss.next()) as f32;
        let (t_in, input, snr, dt) = black_box((t, input, SNR, DT as f32));
        let before = instr::elapsed_instructions();
        let control = guider.frame(t_in, input, snr, dt);
        let after = instr::elapsed_instructions();
        let control = black_box(control);
        applied += control as f64;
        if k >= counted_from {
            counts[k - counted_from] = (after - before) as u32;
            sum_sq += residual * residual;
        }
    }
    counts.sort_unstable();
    libm::sqrt(sum_sq / counts.len() as f64)
}

/// Nearest-rank percentile `p` of sorted `counts`.
fn rank(counts: &[u32], p: usize) -> u32 {
    counts[(p * counts.len()).div_ceil(100).max(1) - 1]
}

/// Runs the closed loop with `guider`, writes the instructions of each
/// active frame to `counts`, prints the result line and returns the
/// median.
fn run<const N: usize>(guider: &mut Guider<f32, N>, counts: &mut [u32; ACTIVE]) -> u32 {
    let rms_px = guide(guider, FRAMES, 0.0, ACTIVE_FROM_FRAME, counts);
    hprintln!(
        "bench stages={} frames={} from_s={} median={} p90={} max={} state_bytes={} rms_px={:.4}",
        N,
        ACTIVE,
        ACTIVE_FROM_S as u32,
        rank(counts, 50),
        rank(counts, 90),
        counts[ACTIVE - 1],
        core::mem::size_of::<Guider<f32, N>>(),
        rms_px
    );
    rank(counts, 50)
}

/// Takes `saved` back into `guider` as a power cycle would, with the phase
/// as `phase` gives it (the gears turned [`TURNED_S`] while off), guides
/// [`RESTORED_FRAMES`] frames and prints the instructions of each; returns
/// their maximum, or `u32::MAX` if the model was refused.
fn restored<const N: usize>(
    guider: &mut Guider<f32, N>,
    saved: &[u8],
    (name, phase): (&str, Phase),
    counts: &mut [u32; RESTORED_FRAMES],
) -> u32 {
    let taken = Snapshot::parse(saved, N).and_then(|s| guider.restore(&s, phase));
    if taken.is_err() {
        hprintln!(
            "FAILED: the model saved after the run was refused ({})",
            name
        );
        return u32::MAX;
    }
    let rms_px = guide(guider, RESTORED_FRAMES, SAVED_AT_S + TURNED_S, 0, counts);
    hprintln!(
        "restore stages={} phase={} frames={} median={} max={} rms_px={:.4}",
        N,
        name,
        RESTORED_FRAMES,
        rank(counts, 50),
        counts[RESTORED_FRAMES - 1],
        rms_px
    );
    counts[RESTORED_FRAMES - 1]
}

#[entry]
fn main() -> ! {
    hprintln!(
        "# guider instructions per frame: case C8, 1 px noise (seed 1), dt {} s, {} frames, active t >= {} s",
        DT as u32,
        FRAMES,
        ACTIVE_FROM_S as u32
    );
    let counts = COUNTS.init([0; ACTIVE]);
    run(GUIDER_1.init(Guider::new(GuiderConfig::default())), counts);
    let guider = GUIDER_3.init(Guider::new(GuiderConfig::default()));
    let medians = [
        (
            2,
            run(GUIDER_2.init(Guider::new(GuiderConfig::default())), counts),
        ),
        (3, run(guider, counts)),
    ];
    let states = [
        core::mem::size_of::<Guider<f32, 2>>(),
        core::mem::size_of::<Guider<f32, 3>>(),
    ];
    let mut ok = true;
    for ((stages, median), state) in medians.into_iter().zip(states) {
        if median > BUDGET_MEDIAN {
            hprintln!(
                "FAILED: Guider<f32, {}> takes a median of {} instructions per frame, over the budget of {}",
                stages,
                median,
                BUDGET_MEDIAN
            );
            ok = false;
        }
        if state > BUDGET_STATE_BYTES {
            hprintln!(
                "FAILED: Guider<f32, {}> state is {} bytes, over the budget of {}",
                stages,
                state,
                BUDGET_STATE_BYTES
            );
            ok = false;
        }
    }
    // The three-stage model after its run, saved and taken back with each
    // kind of phase in turn.
    let saved = SAVED.init([0; SNAPSHOT_MAX]);
    let Ok(n) = guider.snapshot(saved) else {
        hprintln!("FAILED: the three-stage model could not be saved");
        exit(false)
    };
    let saved = &saved[..n];
    let counts = RESTORED_COUNTS.init([0; RESTORED_FRAMES]);
    for phase in [
        (
            "known",
            Phase::Known {
                gear_time_offset_s: SAVED_AT_S + TURNED_S,
            },
        ),
        // Right for the worm alone: the other stages turned otherwise.
        (
            "worm",
            Phase::Worm {
                gear_time_offset_s: SAVED_AT_S,
            },
        ),
        ("unknown", Phase::Unknown),
    ] {
        let name = phase.0;
        let max = restored(guider, saved, phase, counts);
        if max > BUDGET_RESTORED_MAX {
            hprintln!(
                "FAILED: a frame after a restore ({} phase) takes {} instructions, over the budget of {}",
                name,
                max,
                BUDGET_RESTORED_MAX
            );
            ok = false;
        }
    }
    exit(ok)
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    hprintln!("PANIC: {}", info);
    exit(false)
}

#[exception]
unsafe fn HardFault(frame: &ExceptionFrame) -> ! {
    hprintln!("HARDFAULT: {:?}", frame);
    exit(false)
}

#[exception]
unsafe fn DefaultHandler(irqn: i16) {
    hprintln!("unexpected exception or interrupt {}", irqn);
    exit(false)
}
