//! The closed loop's noise against INDIGO's reference traces C1..C8 (noisy,
//! seed 1, time step 2 s). Each trace's input is y = g(t) - U + noise with
//! U the sum of the controls already applied (control = -output), so the
//! whole noise sequence can be reconstructed and compared frame by frame.

mod common;

use host_tests::cases;
use host_tests::data;
use host_tests::noise::Gaussian;

#[test]
fn first_frame_noise_is_the_same_in_every_case() {
    let cases = cases::load(&data::cases_file()).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(cases.len(), 8);
    let first = Gaussian::new(1).next();
    for case in &cases {
        let row = common::trace(&case.name)[0];
        assert_eq!(row.time_s, 0.0);
        assert_eq!(case.gear_error(0.0), 0.0);
        // Exact: one generator per run, seeded with 1, whatever the case.
        assert_eq!(row.input_px - case.gear_error(0.0), first, "{}", case.name);
    }
}

#[test]
fn whole_noise_sequence_matches_frame_by_frame() {
    let cases = cases::load(&data::cases_file()).unwrap_or_else(|e| panic!("{e}"));
    for case in &cases {
        let trace = common::trace(&case.name);
        assert_eq!(trace.len(), 5400, "{}", case.name);
        let mut gen = Gaussian::new(1);
        let mut applied = 0.0;
        let mut worst: f64 = 0.0;
        for (k, row) in trace.iter().enumerate() {
            assert_eq!(row.time_s, 2.0 * k as f64);
            let noise = row.input_px - (case.gear_error(row.time_s) - applied);
            worst = worst.max((noise - gen.next()).abs());
            applied -= row.output_correction_px;
        }
        // Only the rounding of the trace's reconstruction remains.
        assert!(
            worst < 1e-13,
            "{}: worst noise difference {worst:e}",
            case.name
        );
    }
}
