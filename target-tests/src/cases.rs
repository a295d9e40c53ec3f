//! The list of on-target test cases. To add tests, write
//! `fn name() -> TestResult` functions in a module under `src/cases/`
//! (declare it below) and append `case!(module::name)` to [`CASES`].

use crate::case;
use crate::harness::Test;

mod instr_counter;
mod kernel_f32;
mod model_f32;
mod scalar_f32;
#[cfg(any(feature = "selfcheck-fail", feature = "selfcheck-hardfault"))]
mod selfcheck;
mod vfp;

/// Every case, run in this order.
#[cfg(not(any(feature = "selfcheck-fail", feature = "selfcheck-hardfault")))]
pub static CASES: &[Test] = &[
    case!(scalar_f32::fpu_enabled),
    case!(scalar_f32::constants),
    case!(scalar_f32::sin_known_points),
    case!(scalar_f32::cos_known_points),
    case!(scalar_f32::exp_known_points),
    case!(scalar_f32::sqrt_known_points),
    case!(scalar_f32::f32_matches_f64_sweep),
    case!(kernel_f32::exp_nonpositive_points),
    case!(kernel_f32::sin2_scaled_points),
    case!(kernel_f32::kernel_f32_matches_f64),
    case!(instr_counter::measures_delay_loop),
    case!(instr_counter::longer_loop_measures_more),
    case!(vfp::dot_rows_matches_portable),
    case!(vfp::solve_loops_match_portable),
    case!(model_f32::ldlt_known_solve),
    case!(model_f32::fft_pure_tone),
    case!(model_f32::spectrum_finds_the_period),
    case!(model_f32::closed_loop_n1),
    case!(model_f32::closed_loop_n2),
];

/// Harness self-check: must print `1 passed, 2 failed` and exit 1.
#[cfg(feature = "selfcheck-fail")]
pub static CASES: &[Test] = &[
    case!(selfcheck::passes),
    case!(selfcheck::fails),
    case!(selfcheck::panics),
    case!(selfcheck::passes),
];

/// Harness self-check: must print `1 passed, 1 failed` and exit 1.
#[cfg(feature = "selfcheck-hardfault")]
pub static CASES: &[Test] = &[
    case!(selfcheck::passes),
    case!(selfcheck::hard_faults),
    case!(selfcheck::passes),
];
