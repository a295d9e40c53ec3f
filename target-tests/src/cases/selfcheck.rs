//! Cases that exercise the harness's failure paths (features
//! `selfcheck-fail` and `selfcheck-hardfault`); never in the normal list.

use crate::harness::TestResult;

pub fn passes() -> TestResult {
    Ok(())
}

pub fn fails() -> TestResult {
    Err("fails on purpose")
}

pub fn panics() -> TestResult {
    let v = core::hint::black_box(3u32);
    assert_eq!(v, 4, "panics on purpose");
    Ok(())
}

#[allow(unreachable_code)]
pub fn hard_faults() -> TestResult {
    // SAFETY: not safe at all: a permanently undefined instruction raises a
    // UsageFault, escalated to HardFault, on purpose.
    unsafe { core::arch::asm!("udf #0") };
    Ok(())
}
