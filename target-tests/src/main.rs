//! On-target tests of the `mkgp-mount` library, run in QEMU.
//!
//! `cargo run --release` (in this directory) builds this plain cortex-m-rt
//! binary and runs it on `qemu-system-arm -machine mps2-an386 -cpu
//! cortex-m4` (see .cargo/config.toml). Each case prints
//! `test NAME ... ok` or `... FAILED`, the run ends with `N passed, M failed`
//! and exits through semihosting: status 0 if all passed, 1 otherwise. A
//! panic or a HardFault also exits with status 1.
//!
//! Test cases are listed in `src/cases.rs`.
#![no_std]
#![no_main]
// The selfcheck features replace the case list, leaving the real cases unused.
#![cfg_attr(
    any(feature = "selfcheck-fail", feature = "selfcheck-hardfault"),
    allow(dead_code)
)]

mod cases;
mod harness;
pub mod instr;
mod support;

use cortex_m_rt::{entry, exception, ExceptionFrame};
use cortex_m_semihosting::hprintln;
pub use support::exit;

#[entry]
fn main() -> ! {
    let failed = harness::run(cases::CASES);
    exit(failed == 0)
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    hprintln!("PANIC: {}", info);
    harness::abort("panic");
    exit(false)
}

#[exception]
unsafe fn HardFault(frame: &ExceptionFrame) -> ! {
    hprintln!("HARDFAULT: {:?}", frame);
    harness::abort("HardFault");
    exit(false)
}

#[exception]
unsafe fn DefaultHandler(irqn: i16) {
    hprintln!("unexpected exception or interrupt {}", irqn);
    harness::abort("unexpected exception");
    exit(false)
}
