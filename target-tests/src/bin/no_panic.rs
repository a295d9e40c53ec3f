//! Link-time proof that the model's entry points, as the firmware calls
//! them, hold no panic path on the target (the "panic-never" technique).
//!
//! The panic handler calls `model_code_may_panic`, a function defined
//! nowhere. The linker drops unreferenced code, so the build links only if
//! no panic call survives optimisation in anything this binary runs:
//! `Guider<f32, 2>`'s `frame`, `dark_frame` and `dithered` (the PC-guider
//! entry points), and the mount's `MountConfig::validate`, `Learner::new`
//! and `Learner::learn` (which runs `Guider::observe`), `Learner::snapshot`
//! and `Learner::restore` (and the first frames after it), on inputs the
//! compiler cannot see through (`black_box`). A link error
//! naming `model_code_may_panic` means a panic path is back; the firmware's
//! own count (`panic_sites` in test.sh) shows where.
//!
//! Only `--release` builds link (a debug build keeps every check).
//! `cargo run --release --bin no_panic` also runs the frames in QEMU (about
//! half an hour of guiding, so that the fit, the spectrum and the stage
//! discovery all run) and exits 0.
#![no_std]
#![no_main]

#[path = "../support.rs"]
#[allow(dead_code)] // Slot: the other binaries' storage, not needed here.
mod support;

use core::hint::black_box;
use cortex_m_rt::entry;
use cortex_m_semihosting::hio;
use mkgp_mount::model::guider::{Guider, GuiderConfig};
use mkgp_mount::model::snapshot::{Phase, SNAPSHOT_MAX};
use mkgp_mount::mount::config::MountConfig;
use mkgp_mount::mount::frame::{Frame, FrameKind};
use mkgp_mount::mount::learner::Learner;
use support::exit;

extern "C" {
    /// Deliberately undefined: see the module documentation.
    fn model_code_may_panic() -> !;
}

/// Seconds between frames.
const DT: f32 = 2.0;
/// Frames to run: 1,000 frames of 2 s.
const FRAMES: u32 = 1000;
/// Frames after each restore: past half the default worm period.
const RESTORED_FRAMES: u32 = 150;

/// A gear error the compiler cannot fold: a triangle wave of 288 s period
/// and 5 px amplitude (no libm: this binary links nothing it does not test).
fn gear_error(t: f32) -> f32 {
    let phase = t / 288.0 - (t / 288.0) as u32 as f32;
    20.0 * (phase - 0.5).abs() - 5.0
}

#[entry]
fn main() -> ! {
    let mut pc: Guider<f32, 2> = Guider::new(GuiderConfig::default());
    let Ok(mount) = black_box(MountConfig::default()).validate() else {
        exit(false)
    };
    let mut learner: Learner<2> = Learner::new(&mount);
    let mut applied = 0.0f32;
    let mut sum = 0.0f32;
    for k in 0..FRAMES {
        let t = black_box(k as f32 * DT);
        let input = black_box(gear_error(t) - applied);
        let (snr, dt) = black_box((10.0f32, DT));
        // PC-guider style, with a dark frame and a dither now and then.
        let control = match k % 100 {
            50 => pc.dark_frame(t as f64, dt),
            75 => {
                pc.dithered(black_box(1.5), black_box(7.5));
                0.0
            }
            _ => pc.frame(t as f64, input, snr, dt),
        };
        applied += control;
        // Mount side: the learner, with unmeasured frames and dithers.
        let kind = match k % 50 {
            10 => FrameKind::Unmeasured,
            20 => FrameKind::Dither { amount_arcsec: 1.0 },
            _ => FrameKind::Measured,
        };
        let frame = Frame {
            gear_time_s: t as f64,
            interval_s: dt,
            kind,
            gear_error_arcsec: gear_error(t),
            applied_arcsec: 0.0,
            pulse_arcsec: black_box(0.1),
            filled: false,
        };
        sum += learner.learn(black_box(frame)).rate_arcsec_per_s;
    }
    // A power cycle: the model saved, and restored into a learner (the one
    // above again: a second model would not fit the stack) with the phase
    // known, with the worm's and unknown, and the frames that place its
    // data (the phase search after half a worm period).
    let mut bytes = [0u8; SNAPSHOT_MAX];
    let n = learner.snapshot(black_box(&mut bytes)).unwrap_or(0);
    let saved = black_box(bytes.get(..n).unwrap_or(&[]));
    let phases = [
        Phase::Known {
            gear_time_offset_s: 1234.0,
        },
        Phase::Worm {
            gear_time_offset_s: 1234.0,
        },
        Phase::Unknown,
    ];
    for phase in phases {
        if learner.restore(saved, black_box(phase)).is_err() {
            exit(false)
        }
        for k in 0..RESTORED_FRAMES {
            let t = black_box(k as f32 * DT);
            let frame = Frame {
                gear_time_s: t as f64,
                interval_s: DT,
                kind: FrameKind::Measured,
                gear_error_arcsec: gear_error(t + 1234.0),
                applied_arcsec: 0.0,
                pulse_arcsec: black_box(0.1),
                filled: false,
            };
            sum += learner.learn(black_box(frame)).rate_arcsec_per_s;
        }
    }
    black_box((applied, sum));
    if let Ok(mut out) = hio::hstdout() {
        // Nothing to do if the host does not take it: the exit status says it.
        let _ = out.write_all(b"no_panic: ran the guider's and the learner's entry points\n");
    }
    exit(true)
}

#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    // SAFETY: never linked; reaching this line would be a link error.
    unsafe { model_code_may_panic() }
}
