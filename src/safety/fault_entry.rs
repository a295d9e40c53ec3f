//! The stack guard and the HardFault entry that survives a stack overflow,
//! on the Cortex-M.
//!
//! The firmware links with flip-link, which puts the stack below the
//! statics: an overflow runs off the bottom of RAM instead of into them.
//! What lies below RAM differs by chip (and QEMU's MPS2 ignores writes
//! there), so [`install_stack_guard`] also makes the megabyte below RAM a
//! no-access MPU region: the first push past the bottom faults, however
//! large the frame. The processor then cannot stack the exception frame
//! either, and enters HardFault with the stack pointer still below RAM,
//! where an ordinary handler's first push faults again and locks the core
//! up. The entry of [`hard_fault_entry!`](crate::hard_fault_entry) first moves the stack pointer back
//! to the top of the stack (the fault path never returns, so what was there
//! is not needed) and only then calls the handler, in Rust.
//!
//! Compiled for the Cortex-M only; the binary that uses it (the firmware,
//! and the QEMU test of the fault path) invokes [`hard_fault_entry!`](crate::hard_fault_entry) once
//! and calls [`install_stack_guard`] first thing.

use crate::safety::fault_record::FaultRecord;

/// The Configurable Fault Status Register.
const CFSR: *const u32 = 0xE000_ED28 as *const u32;
/// CFSR: a MemManage fault while stacking for an exception entry.
const MSTKERR: u32 = 1 << 4;
/// CFSR: a BusFault while stacking for an exception entry.
const STKERR: u32 = 1 << 12;

/// MPU registers (ARMv7-M).
const MPU_CTRL: *mut u32 = 0xE000_ED94 as *mut u32;
const MPU_RNR: *mut u32 = 0xE000_ED98 as *mut u32;
const MPU_RBAR: *mut u32 = 0xE000_ED9C as *mut u32;
const MPU_RASR: *mut u32 = 0xE000_EDA0 as *mut u32;
/// log2 of the guard's size: 1 MiB, more than any stack frame can skip.
const GUARD_SIZE_LOG2: u32 = 20;

/// Makes the megabyte below `ram_origin` (the bottom of the stack under
/// flip-link) a no-access, never-execute MPU region (region 0), and enables
/// the MPU with the default memory map everywhere else.
///
/// # Safety
/// `ram_origin` must be a multiple of 1 MiB with nothing the firmware uses
/// in the megabyte below it; call before the stack can overflow and before
/// anything else configures the MPU.
pub unsafe fn install_stack_guard(ram_origin: u32) {
    let base = ram_origin - (1 << GUARD_SIZE_LOG2);
    // RASR: XN (bit 28), AP = 000 (no access), SIZE = log2 - 1, ENABLE.
    let rasr = (1 << 28) | ((GUARD_SIZE_LOG2 - 1) << 1) | 1;
    // SAFETY: the MPU registers exist on every ARMv7-M core with an MPU
    // (all the supported chips and QEMU's Cortex-M4).
    unsafe {
        core::ptr::write_volatile(MPU_RNR, 0);
        core::ptr::write_volatile(MPU_RBAR, base);
        core::ptr::write_volatile(MPU_RASR, rasr);
        // PRIVDEFENA (bit 2): the default map elsewhere; ENABLE (bit 0).
        core::ptr::write_volatile(MPU_CTRL, (1 << 2) | 1);
    }
    // The new map applies from the next instruction on.
    // SAFETY: barriers only.
    unsafe { core::arch::asm!("dsb", "isb", options(nostack, preserves_flags)) };
}

/// The fault record of a HardFault whose handler was entered through
/// [`hard_fault_entry!`](crate::hard_fault_entry) with the stack pointer of the fault at `frame`:
/// the faulting `pc` and `lr` from the stacked frame, or a stack overflow if
/// the frame could not be stacked.
///
/// # Safety
/// Call only from the handler [`hard_fault_entry!`](crate::hard_fault_entry) branches to, with the
/// `frame` it was given.
pub unsafe fn hard_fault_record(frame: *const u32) -> FaultRecord {
    // SAFETY: CFSR is a readable system register on every ARMv7-M core.
    let cfsr = unsafe { core::ptr::read_volatile(CFSR) };
    if cfsr & (MSTKERR | STKERR) != 0 {
        return FaultRecord::stack_overflow();
    }
    // SAFETY: the frame was stacked (no stacking error): eight words at
    // `frame`, r0-r3, r12, lr, pc, xPSR.
    let (lr, pc) = unsafe {
        (
            core::ptr::read_volatile(frame.add(5)),
            core::ptr::read_volatile(frame.add(6)),
        )
    };
    FaultRecord::hard_fault(pc, lr)
}

/// Defines the `HardFault` exception entry: saves the stack pointer of the
/// fault, resets the stack pointer to `_stack_start` (the top of the stack)
/// and branches to `$handler`, an `unsafe extern "C" fn(frame: *const u32)
/// -> !` that never returns. Replaces cortex-m-rt's own entry (do not also
/// use `#[exception] fn HardFault`).
#[macro_export]
macro_rules! hard_fault_entry {
    ($handler:path) => {
        core::arch::global_asm!(
            ".section .HardFault.entry, \"ax\"",
            ".global HardFault",
            ".type HardFault,%function",
            ".thumb_func",
            "HardFault:",
            "mrs r0, MSP",
            "ldr r1, =_stack_start",
            "msr MSP, r1",
            "b {handler}",
            ".ltorg",
            ".size HardFault, . - HardFault",
            handler = sym $handler,
        );
    };
}
