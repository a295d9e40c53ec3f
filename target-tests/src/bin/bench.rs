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
//! The goals are asserted: the run exits 1, after the result lines, with a
//! `FAILED:` line when the median for `Guider<f32, 2>` or `Guider<f32, 3>`
//! exceeds [`BUDGET_MEDIAN`] instructions (the counts are exact and repeat,
//! so there is no margin to leave) or its state [`BUDGET_STATE_BYTES`]. It
//! also exits 1 if it panics or faults.
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

/// Runs the closed loop with `guider`, writes the instructions of each
/// active frame to `counts` (sorted on return), prints the result line and
/// returns the median.
fn run<const N: usize>(guider: &mut Guider<f32, N>, counts: &mut [u32; ACTIVE]) -> u32 {
    let mut gauss = Gaussian::new(SEED);
    let mut applied = 0.0f64; // U: the sum of the controls applied
    let mut sum_sq = 0.0f64;
    instr::start();
    for k in 0..FRAMES {
        let t = k as f64 * DT;
        let residual = gear_error(t) - applied;
        let input = (residual + SIGMA_PX * gauss.next()) as f32;
        let (t_in, input, snr, dt) = black_box((t, input, SNR, DT as f32));
        let before = instr::elapsed_instructions();
        let control = guider.frame(t_in, input, snr, dt);
        let after = instr::elapsed_instructions();
        let control = black_box(control);
        applied += control as f64;
        if k >= ACTIVE_FROM_FRAME {
            counts[k - ACTIVE_FROM_FRAME] = (after - before) as u32;
            sum_sq += residual * residual;
        }
    }
    counts.sort_unstable();
    let rank = |p: usize| counts[(p * ACTIVE).div_ceil(100).max(1) - 1];
    hprintln!(
        "bench stages={} frames={} from_s={} median={} p90={} max={} state_bytes={} rms_px={:.4}",
        N,
        ACTIVE,
        ACTIVE_FROM_S as u32,
        rank(50),
        rank(90),
        counts[ACTIVE - 1],
        core::mem::size_of::<Guider<f32, N>>(),
        libm::sqrt(sum_sq / ACTIVE as f64)
    );
    rank(50)
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
    let medians = [
        (
            2,
            run(GUIDER_2.init(Guider::new(GuiderConfig::default())), counts),
        ),
        (
            3,
            run(GUIDER_3.init(Guider::new(GuiderConfig::default())), counts),
        ),
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
