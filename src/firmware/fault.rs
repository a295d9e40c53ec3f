//! The board's fault handling: the panic and HardFault handlers, the fault
//! record in RAM that survives the reset, and why the board last started.
//! The order of the fault path is the library's
//! ([`mkgp_mount::safety::safe_state::enter`]); this file only moves it to
//! the pins, the RAM and the log.

use core::mem::MaybeUninit;
use core::panic::PanicInfo;
use core::sync::atomic::AtomicBool;

use mkgp_mount::safety::fault_entry::hard_fault_record;
use mkgp_mount::safety::fault_record::{Fault, FaultRecord, RECORD_WORDS};
use mkgp_mount::safety::reset_cause::{ResetCause, ResetFlags};
use mkgp_mount::safety::safe_state::{self, SafeStatePort};

/// The fault record, in RAM that cortex-m-rt neither zeroes nor initialises
/// (`.uninit`), so it survives the reset that ends the fault path.
#[link_section = ".uninit.FAULT_RECORD"]
static mut FAULT_WORDS: MaybeUninit<[u32; RECORD_WORDS]> = MaybeUninit::uninit();

/// Set by the first fault: a fault inside the fault path skips to the reset.
static IN_FAULT: AtomicBool = AtomicBool::new(false);

/// Why the board last started, for the status log.
#[derive(Clone, Copy)]
pub struct LastReset {
    pub cause: ResetCause,
    pub fault: Option<FaultRecord>,
}

/// The board's side of the fault path.
struct Board;

impl SafeStatePort for Board {
    fn disable_drivers(&mut self) {
        // SAFETY: the fault path never returns to the code that owns the pins.
        unsafe { hal::stepper::force_drivers_off() }
    }

    fn keep(&mut self, record: &FaultRecord) {
        // SAFETY: written only here, with interrupts off, and read once at
        // boot before any fault can happen.
        unsafe {
            core::ptr::write_volatile(
                core::ptr::addr_of_mut!(FAULT_WORDS).cast::<[u32; RECORD_WORDS]>(),
                record.encode(),
            )
        }
    }

    fn report(&mut self, record: &FaultRecord) {
        log_fault("FAULT", record);
    }

    fn reset(&mut self) -> ! {
        hal::reset::reset()
    }
}

/// Takes the board to the safe state for `record` and resets it.
pub fn enter_safe_state(record: &FaultRecord) -> ! {
    cortex_m::interrupt::disable();
    safe_state::enter(&mut Board, record, &IN_FAULT)
}

#[panic_handler]
fn panic(info: &PanicInfo) -> ! {
    enter_safe_state(&FaultRecord::from_panic(info))
}

mkgp_mount::hard_fault_entry!(on_hard_fault);

/// The HardFault handler, on a fresh stack (see `hard_fault_entry!`).
unsafe extern "C" fn on_hard_fault(frame: *const u32) -> ! {
    // SAFETY: entered from `hard_fault_entry!` with its frame.
    enter_safe_state(&unsafe { hard_fault_record(frame) })
}

/// At boot, before anything can fault: reads and clears the reset flags and
/// the fault record, logs why the board started and returns it for the
/// status log.
pub fn take_last_reset() -> LastReset {
    let f = hal::reset::take_reset_flags();
    let cause = ResetCause::from_flags(ResetFlags {
        power_on: f.power_on,
        brown_out: f.brown_out,
        pin: f.pin,
        software: f.software,
        independent_watchdog: f.independent_watchdog,
        window_watchdog: f.window_watchdog,
        low_power: f.low_power,
    });
    // SAFETY: no fault path runs yet; the words may be garbage after a
    // power-on, which `decode` refuses.
    let fault = unsafe {
        let words = core::ptr::addr_of_mut!(FAULT_WORDS).cast::<[u32; RECORD_WORDS]>();
        let record = FaultRecord::decode(&core::ptr::read_volatile(words));
        core::ptr::write_volatile(words, [0; RECORD_WORDS]);
        record
    };
    let last = LastReset { cause, fault };
    log_last_reset(&last);
    last
}

/// Logs why the board last started (at boot and in the status log).
pub fn log_last_reset(last: &LastReset) {
    defmt::info!("last reset: {}", last.cause.name());
    if let Some(record) = &last.fault {
        log_fault("last reset was the fault path's", record);
    }
}

fn log_fault(what: &str, record: &FaultRecord) {
    match record.fault() {
        Fault::Panic { line } => {
            defmt::error!(
                "{}: panic at {}:{}; drivers disabled",
                what,
                record.file(),
                line
            )
        }
        Fault::HardFault { pc, lr } => {
            defmt::error!(
                "{}: HardFault at pc {=u32:#x} (lr {=u32:#x}); drivers disabled",
                what,
                pc,
                lr
            )
        }
        Fault::Stalled(part) => {
            defmt::error!("{}: {} stalled; drivers disabled", what, part.name())
        }
        Fault::StackOverflow => {
            defmt::error!("{}: stack overflow; drivers disabled", what)
        }
    }
}
