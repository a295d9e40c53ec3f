//! The fault path on the emulated Cortex-M4F: a fault raised while the
//! model runs must end in the library's safe state, in its order.
//!
//! `cargo run --release --bin safe_state` (in target-tests) runs the model
//! (`Guider<f32, 2>` on a two-stage gear error) in the "model task", which
//! panics after [`FRAMES_BEFORE_FAULT`] frames; with `--features
//! safe-state-hardfault` it executes an undefined instruction instead (a
//! HardFault), and with `--features safe-state-stack-overflow` it recurses
//! until the stack runs into flip-link's guard (a HardFault that cannot
//! stack its frame). The handler builds the fault record and calls
//! [`safe_state::enter`] with a port that reports through semihosting, as
//! the board's handlers call it with theirs (`src/firmware/fault.rs`). The
//! port checks that the drivers were disabled first, that the kept record
//! decodes to the fault raised, and that the reset came last; the run
//! prints `1 passed, 0 failed` and exits 0 only then. `../test.sh` runs
//! all three.
#![no_std]
#![no_main]

#[path = "../support.rs"]
mod support;

use core::f64::consts::PI;
use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use cortex_m_rt::{entry, exception};
use cortex_m_semihosting::hprintln;
use mkgp_mount::model::guider::{Guider, GuiderConfig};
use mkgp_mount::safety::fault_entry::{hard_fault_record, install_stack_guard};
use mkgp_mount::safety::fault_record::{Fault, FaultRecord, RECORD_WORDS};
use mkgp_mount::safety::safe_state::{self, SafeStatePort};
use support::{exit, Slot};

/// Frames the model learns before the fault.
const FRAMES_BEFORE_FAULT: usize = 40;

static GUIDER: Slot<Guider<f32, 2>> = Slot::new();
/// The source line of the raised panic, for the check.
static PANIC_LINE: AtomicU32 = AtomicU32::new(0);
static IN_FAULT: AtomicBool = AtomicBool::new(false);
/// A static the stack must never reach: checked after the overflow.
static SENTINEL: AtomicU32 = AtomicU32::new(SENTINEL_VALUE);
const SENTINEL_VALUE: u32 = 0x5AFE_5AFE;

/// The "model task": frames every 2 s, then the fault.
#[entry]
fn main() -> ! {
    // SAFETY: first thing, and nothing lies in the megabyte below RAM
    // (memory.x: RAM at 0x2000_0000).
    unsafe { install_stack_guard(0x2000_0000) };
    let guider = GUIDER.init(Guider::new(GuiderConfig::default()));
    let mut applied = 0.0f64;
    for k in 0..FRAMES_BEFORE_FAULT {
        let t = k as f64 * 2.0;
        let gear = 9.0 * libm::sin(2.0 * PI * t / 432.0) + 4.5 * libm::sin(2.0 * PI * t / 155.0);
        applied += f64::from(guider.frame(t, (gear - applied) as f32, 10.0, 2.0));
    }
    hprintln!(
        "model task: {} frames learned (applied {} px), now the fault",
        FRAMES_BEFORE_FAULT,
        applied
    );
    raise()
}

#[cfg(not(any(
    feature = "safe-state-hardfault",
    feature = "safe-state-stack-overflow"
)))]
fn raise() -> ! {
    PANIC_LINE.store(line!() + 1, Ordering::SeqCst);
    panic!("raised by the test")
}

#[cfg(feature = "safe-state-hardfault")]
fn raise() -> ! {
    cortex_m::asm::udf()
}

#[cfg(feature = "safe-state-stack-overflow")]
fn raise() -> ! {
    /// Recurses until the stack runs out: a frame of 256 bytes each time,
    /// kept alive by `black_box` so that it is neither inlined nor a loop.
    #[inline(never)]
    #[allow(unconditional_recursion)]
    fn deeper(depth: u32) -> u32 {
        let frame = core::hint::black_box([depth; 64]);
        deeper(depth + 1).wrapping_add(frame[(depth % 64) as usize])
    }
    hprintln!("{}", deeper(0));
    exit(false)
}

/// What the port has seen, in order.
#[derive(Clone, Copy, PartialEq)]
enum Seen {
    Nothing,
    Disabled,
    Kept,
    Reported,
}

struct Qemu {
    seen: Seen,
    kept: [u32; RECORD_WORDS],
    failures: u32,
}

impl Qemu {
    fn expect(&mut self, before: Seen, now: Seen, what: &str) {
        if self.seen != before {
            hprintln!("safe state: {} out of order", what);
            self.failures += 1;
        }
        self.seen = now;
    }
}

impl SafeStatePort for Qemu {
    fn disable_drivers(&mut self) {
        self.expect(Seen::Nothing, Seen::Disabled, "disable drivers");
        hprintln!("safe state: drivers disabled");
    }

    fn keep(&mut self, record: &FaultRecord) {
        self.expect(Seen::Disabled, Seen::Kept, "keep record");
        self.kept = record.encode();
    }

    fn report(&mut self, record: &FaultRecord) {
        self.expect(Seen::Kept, Seen::Reported, "report");
        match record.fault() {
            Fault::Panic { line } => hprintln!("FAULT: panic at {}:{}", record.file(), line),
            Fault::HardFault { pc, lr } => {
                hprintln!("FAULT: HardFault at pc {:#x} (lr {:#x})", pc, lr)
            }
            Fault::Stalled(part) => hprintln!("FAULT: {} stalled", part.name()),
            Fault::StackOverflow => hprintln!("FAULT: stack overflow"),
        }
    }

    fn reset(&mut self) -> ! {
        self.expect(Seen::Reported, Seen::Nothing, "reset");
        let expected_kind_ok = match FaultRecord::decode(&self.kept).map(|r| r.fault()) {
            Some(Fault::Panic { line }) => {
                !cfg!(feature = "safe-state-hardfault")
                    && !cfg!(feature = "safe-state-stack-overflow")
                    && line == PANIC_LINE.load(Ordering::SeqCst)
            }
            Some(Fault::HardFault { pc, .. }) => cfg!(feature = "safe-state-hardfault") && pc != 0,
            Some(Fault::StackOverflow) => cfg!(feature = "safe-state-stack-overflow"),
            _ => false,
        };
        if !expected_kind_ok {
            hprintln!("safe state: the kept record is not the fault raised");
            self.failures += 1;
        }
        if SENTINEL.load(Ordering::SeqCst) != SENTINEL_VALUE {
            hprintln!("safe state: a static was overwritten");
            self.failures += 1;
        }
        hprintln!("safe state: reset");
        let ok = self.failures == 0;
        hprintln!("{} passed, {} failed", u32::from(ok), u32::from(!ok));
        exit(ok)
    }
}

fn enter(record: FaultRecord) -> ! {
    cortex_m::interrupt::disable();
    let mut port = Qemu {
        seen: Seen::Nothing,
        kept: [0; RECORD_WORDS],
        failures: 0,
    };
    safe_state::enter(&mut port, &record, &IN_FAULT)
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    enter(FaultRecord::from_panic(info))
}

mkgp_mount::hard_fault_entry!(on_hard_fault);

/// The HardFault handler, on a fresh stack, as the firmware's.
unsafe extern "C" fn on_hard_fault(frame: *const u32) -> ! {
    // SAFETY: entered from `hard_fault_entry!` with its frame.
    enter(unsafe { hard_fault_record(frame) })
}

#[exception]
unsafe fn DefaultHandler(irqn: i16) {
    hprintln!("unexpected exception or interrupt {}", irqn);
    exit(false)
}
