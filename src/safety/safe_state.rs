//! The fault path: what every fault does, in this order. The board's panic
//! and HardFault handlers and its liveness check call [`enter`] with a port
//! onto the hardware; the QEMU test calls it with one that reports through
//! semihosting.

use core::sync::atomic::{AtomicBool, Ordering};

use crate::safety::fault_record::FaultRecord;

/// What the fault path needs from the board. Each method must work with
/// interrupts off and from any context, and must not panic.
pub trait SafeStatePort {
    /// Disables both stepper drivers (the motors lose holding torque; a
    /// mount on a clutch or a worm does not move).
    fn disable_drivers(&mut self);
    /// Keeps `record` where the next boot finds it.
    fn keep(&mut self, record: &FaultRecord);
    /// Says what happened, if anyone is listening.
    fn report(&mut self, record: &FaultRecord);
    /// Resets the board.
    fn reset(&mut self) -> !;
}

/// Takes the board to the safe state: drivers off first, before anything
/// that could fail again; then the record for the next boot, the report and
/// the reset. `entered` is the caller's flag, false until the first fault:
/// a fault inside the path (a panic while reporting) skips straight from
/// the drivers to the reset, keeping the first fault's record.
pub fn enter(port: &mut impl SafeStatePort, record: &FaultRecord, entered: &AtomicBool) -> ! {
    port.disable_drivers();
    if !entered.swap(true, Ordering::SeqCst) {
        port.keep(record);
        port.report(record);
    }
    port.reset()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::safety::fault_record::Part;

    #[derive(Debug, PartialEq)]
    enum Step {
        Disable,
        Keep(FaultRecord),
        Report(FaultRecord),
        Reset,
    }

    struct Recorder(Vec<Step>);

    /// The reset, as a panic the test catches.
    struct Reset;

    impl SafeStatePort for Recorder {
        fn disable_drivers(&mut self) {
            self.0.push(Step::Disable);
        }
        fn keep(&mut self, record: &FaultRecord) {
            self.0.push(Step::Keep(*record));
        }
        fn report(&mut self, record: &FaultRecord) {
            self.0.push(Step::Report(*record));
        }
        fn reset(&mut self) -> ! {
            self.0.push(Step::Reset);
            std::panic::panic_any(Reset)
        }
    }

    fn run(port: &mut Recorder, record: FaultRecord, entered: &AtomicBool) {
        let caught = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            enter(port, &record, entered)
        }));
        assert!(caught.err().is_some_and(|e| e.is::<Reset>()));
    }

    #[test]
    fn drivers_off_first_then_keep_report_reset() {
        let entered = AtomicBool::new(false);
        let mut port = Recorder(Vec::new());
        let record = FaultRecord::panic("src/x.rs", 3);
        run(&mut port, record, &entered);
        assert_eq!(
            port.0,
            [
                Step::Disable,
                Step::Keep(record),
                Step::Report(record),
                Step::Reset
            ]
        );
    }

    #[test]
    fn a_fault_inside_the_path_only_disables_and_resets() {
        let entered = AtomicBool::new(false);
        let mut port = Recorder(Vec::new());
        run(&mut port, FaultRecord::stalled(Part::Learner), &entered);
        port.0.clear();
        run(&mut port, FaultRecord::hard_fault(1, 2), &entered);
        assert_eq!(port.0, [Step::Disable, Step::Reset]);
    }
}
