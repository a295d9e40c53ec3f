//! What every QEMU binary here needs: static storage for values too large
//! for the stack, and ending the run with a status. The test binary
//! (`main.rs`) and the `bench` and `profile` binaries include this file.

use core::cell::UnsafeCell;
use core::mem::MaybeUninit;
use core::sync::atomic::{AtomicBool, Ordering};
use cortex_m_semihosting::debug;

/// Static storage for one value, handed out once (a minimal `StaticCell`):
/// guiders, grids and spectrum buffers are too large to keep on the stack
/// comfortably, and there is no heap.
pub struct Slot<T> {
    taken: AtomicBool,
    value: UnsafeCell<MaybeUninit<T>>,
}

// SAFETY: the value is reachable only through the one `&mut` that `init`
// hands out.
unsafe impl<T> Sync for Slot<T> {}

impl<T> Slot<T> {
    pub const fn new() -> Self {
        Slot {
            taken: AtomicBool::new(false),
            value: UnsafeCell::new(MaybeUninit::uninit()),
        }
    }

    /// Store `value` and hand out the only reference to it; a second call
    /// panics (a test bug, reported as a failure).
    #[allow(clippy::mut_from_ref)]
    pub fn init(&'static self, value: T) -> &'static mut T {
        assert!(!self.taken.swap(true, Ordering::SeqCst), "Slot used twice");
        // SAFETY: first and only use (checked above).
        unsafe { (*self.value.get()).write(value) }
    }
}

/// Ends the QEMU run with status 0 (`success`) or 1.
pub fn exit(success: bool) -> ! {
    debug::exit(if success {
        debug::EXIT_SUCCESS
    } else {
        debug::EXIT_FAILURE
    });
    // Only reached without a semihosting host (e.g. on real hardware with no
    // debugger attached).
    loop {
        cortex_m::asm::bkpt();
    }
}
