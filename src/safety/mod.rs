//! What the firmware does when something goes wrong, without the hardware:
//! the board's fault handlers and watchdog glue (`src/firmware/fault.rs`)
//! and the QEMU test of the fault path drive the same code.
//!
//! - [`safe_state::enter`]: the one fault path, for a panic, a HardFault or
//!   a stalled part: drivers off first, then the record kept for the next
//!   boot, the log line, the reset.
//! - `fault_entry` (Cortex-M only): the HardFault entry that survives a
//!   stack overflow.
//! - [`fault_record::FaultRecord`]: what a fault leaves in RAM that survives
//!   the reset, checked on the way back so that power-on garbage is never
//!   taken for a fault.
//! - [`reset_cause::ResetCause`]: why the board last started, from the
//!   chip's reset flags.
//! - [`liveness::Liveness`]: whether the step tick and the learner are
//!   still making progress; the guiding task feeds the independent watchdog
//!   only on its word, so a hung board resets.

#[cfg(all(target_arch = "arm", target_os = "none"))]
pub mod fault_entry;
pub mod fault_record;
pub mod liveness;
pub mod reset_cause;
pub mod safe_state;
