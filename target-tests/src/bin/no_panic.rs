//! Link-time proof that the model's entry points, as the firmware calls
//! them, hold no panic path on the target (the "panic-never" technique).
//!
//! The panic handler calls `model_code_may_panic`, a function defined
//! nowhere. The linker drops unreferenced code, so the build links only if
//! no panic call survives optimisation in anything this binary runs:
//! `Guider<f32, 2>`'s `frame`, `dark_frame` and `dithered` (the PC-guider
//! entry points), the mount's `MountConfig::validate`, `Learner::new`,
//! `Learner::learn` of the firmware's stages (which runs `Guider::observe`), `Learner::snapshot`
//! and `Learner::restore` (and the first frames after it), and the
//! command port as the guiding task runs it (`Interpreter::feed` on a
//! `PortMount`, `ControlLoop::wake`, a telemetry line), on inputs the
//! compiler cannot see through (`black_box`): garbage on the port cannot
//! panic. A link error
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
use mkgp_mount::control_loop::port_mount::{LearnedFrame, PortMount, PortState};
use mkgp_mount::control_loop::st4_feed::{EdgeQueue, EdgeSource, RawEdge};
use mkgp_mount::control_loop::ControlLoop;
use mkgp_mount::model::guider::{Guider, GuiderConfig};
use mkgp_mount::model::snapshot::Phase;
use mkgp_mount::mount::config::{Mount, MountConfig};
use mkgp_mount::mount::frame::{FeedForward, Frame, FrameKind};
use mkgp_mount::mount::learner::{Learner, FIRMWARE_STAGES, RECORD_FORMAT, RECORD_MAX};
use mkgp_mount::port::mount_port::{Identity, StepCounts};
use mkgp_mount::port::{Interpreter, ReplySink};
use mkgp_mount::safety::reset_cause::ResetCause;
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
    let mut learner: Learner<FIRMWARE_STAGES> = Learner::new(&mount);
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
    let mut bytes = [0u8; RECORD_MAX];
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
        if learner
            .restore(saved, black_box(RECORD_FORMAT), black_box(phase))
            .is_err()
        {
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
    let replies = command_port(&mount, &learner);
    if let Ok(mut out) = hio::hstdout() {
        // Nothing to do if the host does not take it: the exit status says it.
        let _ = out.write_all(
            b"no_panic: ran the guider's, the learner's, the loop's and the command port's entry points\n",
        );
    }
    if replies == 0 {
        exit(false)
    }
    exit(true)
}

/// Counts the replies, takes every one.
struct Count(u32);

impl ReplySink for Count {
    fn send(&mut self, _: &[u8]) -> bool {
        self.0 += 1;
        true
    }
}

/// No edges: the loop's wake-up with an empty ST4 queue.
struct NoEdges;

impl EdgeSource for NoEdges {
    fn next_edge(&mut self) -> Option<RawEdge> {
        None
    }
    fn queue(&self) -> EdgeQueue {
        EdgeQueue {
            dropped: black_box(0),
            levels: black_box([false; 4]),
        }
    }
}

/// The firmware's command port on its loop, as the guiding task runs it:
/// bytes the compiler cannot see (a command stream, then a byte stream of
/// every value) through `Interpreter::feed` on a `PortMount`, each chunk
/// followed by `ControlLoop::wake`, and a learned frame's telemetry.
/// Returns the replies counted.
fn command_port(mount: &Mount, learner: &Learner<FIRMWARE_STAGES>) -> u32 {
    const CONNECT: &[u8] = b"\x06:GR#:GD#:U#:Gc#:GM#:GT#:Gt#:Gg#:GG#:GL#:GC#:Sr06:00:00#:Sd+10*00:00#:CM#\
        :RG#:Mw#:Qw#:Mgn1000#:RS#:Me#:Q#:Te#:Td#:GU#:GVP#:GVN#:GVD#:GVT#:~L#:~S0#:~Cs#:~Cg#:~Cl#:~Cf#:~Cp#\
        :~F0#:~F1#:~T1#:~R#:~V#:Mgs99999#:Sr99:99:99#\
        :~K#:~K7#:~Kworm_period_s=598.36#:~Kworm_period_s#:~Kglitch_us=x#:~KD#:~KW#";
    let (mut lp, _) = ControlLoop::start(mount, 0, 0);
    let mut state = PortState::new(mount, IDENTITY, ResetCause::PowerOn);
    let mut port = Interpreter::new();
    let mut out = Count(0);
    let mut now_us = 0u64;
    let mut noise = black_box(0x2545_f491u32);
    for round in 0..64u32 {
        let mut chunk = [0u8; 48];
        for (i, b) in chunk.iter_mut().enumerate() {
            noise ^= noise << 13;
            noise ^= noise >> 17;
            noise ^= noise << 5;
            *b = if round % 2 == 0 {
                CONNECT[(round as usize * 48 + i) % CONNECT.len()]
            } else {
                noise as u8
            };
        }
        now_us += black_box(20_000);
        let steps = StepCounts {
            ra: black_box(i64::from(round) * 1000),
            dec: black_box(-i64::from(round)),
        };
        let mut pm = PortMount {
            control: &mut lp,
            state: &mut state,
            now_us,
            steps,
            port: black_box(round as usize % 2),
        };
        port.feed(black_box(&chunk), now_us, &mut pm, &mut out);
        // A save's outcome, for the port that asked.
        port.store_done(black_box(round % 3 == 0), &mut out);
        let _ = lp.wake(now_us, steps.ra, &mut NoEdges, None);
    }
    let learned = LearnedFrame::of(
        learner,
        &black_box(Frame {
            gear_time_s: 2.0,
            interval_s: 2.0,
            kind: FrameKind::Measured,
            gear_error_arcsec: 1.0,
            applied_arcsec: 0.0,
            pulse_arcsec: 0.0,
            filled: false,
        }),
        black_box(FeedForward::NONE),
    );
    state.learner = learned.summary.clone();
    port.send_telemetry(&learned.telemetry(now_us), &mut out);
    black_box(out.0)
}

const IDENTITY: Identity = Identity {
    product: "mkgp-mount",
    version: "0",
    date: "Jan 01 2026",
    time: "00:00:00",
};

#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    // SAFETY: never linked; reaching this line would be a link error.
    unsafe { model_code_may_panic() }
}
