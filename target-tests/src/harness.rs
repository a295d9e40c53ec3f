//! A minimal test harness: runs a list of cases, prints one line per case
//! and a closing `N passed, M failed` line.

use core::sync::atomic::{AtomicUsize, Ordering};
use cortex_m_semihosting::hprintln;

static PASSED: AtomicUsize = AtomicUsize::new(0);
static FAILED: AtomicUsize = AtomicUsize::new(0);
/// Index + 1 of the case being run, 0 outside of a case.
static CURRENT: AtomicUsize = AtomicUsize::new(0);
static mut TESTS: &[Test] = &[];

/// What a test case returns: `Err` carries a short reason.
pub type TestResult = Result<(), &'static str>;

/// One named test case.
pub struct Test {
    pub name: &'static str,
    pub run: fn() -> TestResult,
}

/// Builds a [`Test`] named after the function's path, e.g.
/// `case!(scalar_f32::sin_known_points)`.
#[macro_export]
macro_rules! case {
    ($f:path) => {
        $crate::harness::Test {
            name: stringify!($f),
            run: $f,
        }
    };
}

/// Runs every case and returns the number that failed.
pub fn run(tests: &'static [Test]) -> usize {
    // SAFETY: single-threaded; written once before any case runs.
    unsafe { TESTS = tests };
    hprintln!("running {} tests", tests.len());
    for (i, t) in tests.iter().enumerate() {
        CURRENT.store(i + 1, Ordering::SeqCst);
        match (t.run)() {
            Ok(()) => {
                PASSED.fetch_add(1, Ordering::SeqCst);
                hprintln!("test {} ... ok", t.name);
            }
            Err(why) => {
                FAILED.fetch_add(1, Ordering::SeqCst);
                hprintln!("test {} ... FAILED: {}", t.name, why);
            }
        }
    }
    CURRENT.store(0, Ordering::SeqCst);
    let failed = FAILED.load(Ordering::SeqCst);
    hprintln!(
        "{} passed, {} failed",
        PASSED.load(Ordering::SeqCst),
        failed
    );
    failed
}

/// Called by the panic and HardFault handlers: marks the running case (if
/// any) as failed with `why` and prints the closing line. The cases after it
/// are not run.
pub fn abort(why: &str) {
    let current = CURRENT.load(Ordering::SeqCst);
    // SAFETY: only read here, after `run` has set it.
    let tests = unsafe { TESTS };
    let name = match current {
        0 => "(outside of a test case)",
        i => tests.get(i - 1).map_or("?", |t| t.name),
    };
    hprintln!("test {} ... FAILED: {}", name, why);
    let failed = FAILED.load(Ordering::SeqCst) + 1;
    let not_run = tests.len().saturating_sub(current);
    if not_run > 0 {
        hprintln!("({} cases not run)", not_run);
    }
    hprintln!(
        "{} passed, {} failed",
        PASSED.load(Ordering::SeqCst),
        failed
    );
}

/// `Ok` if `|actual - expected| <= tol`; otherwise prints the values and
/// returns `Err(what)`.
pub fn close_abs(what: &'static str, actual: f64, expected: f64, tol: f64) -> TestResult {
    let err = actual - expected;
    if err.is_finite() && (if err < 0.0 { -err } else { err }) <= tol {
        Ok(())
    } else {
        hprintln!(
            "    {}: got {:e}, expected {:e} (abs tol {:e})",
            what,
            actual,
            expected,
            tol
        );
        Err(what)
    }
}

/// `Ok` if `|actual - expected| <= tol * |expected|`; otherwise prints the
/// values and returns `Err(what)`.
pub fn close_rel(what: &'static str, actual: f64, expected: f64, tol: f64) -> TestResult {
    let scale = if expected < 0.0 { -expected } else { expected };
    let err = actual - expected;
    if err.is_finite() && (if err < 0.0 { -err } else { err }) <= tol * scale {
        Ok(())
    } else {
        hprintln!(
            "    {}: got {:e}, expected {:e} (rel tol {:e})",
            what,
            actual,
            expected,
            tol
        );
        Err(what)
    }
}

/// `Ok` if `cond`, else `Err(what)`.
pub fn check(cond: bool, what: &'static str) -> TestResult {
    if cond {
        Ok(())
    } else {
        Err(what)
    }
}
