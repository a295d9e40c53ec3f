//! The hand-scheduled FPU loop (`mkgp_mount::vfp`) against the portable
//! code it replaces: bit-identical sums for every length around the
//! four-element passes, on the target where it runs.

use crate::harness::TestResult;
use mkgp_mount::ldlt::dot_rows_portable;
use mkgp_mount::vfp::dot_rows;

/// xorshift32 values in [-1, 1).
fn fill(state: &mut u32, out: &mut [f32]) {
    for x in out {
        *state ^= *state << 13;
        *state ^= *state >> 17;
        *state ^= *state << 5;
        *x = (*state >> 8) as f32 / (1u32 << 23) as f32 - 1.0;
    }
}

pub fn dot_rows_matches_portable() -> TestResult {
    let mut state = 0x1234_5678u32;
    let mut data = [[0.0f32; 103]; 5];
    for row in &mut data {
        fill(&mut state, row);
    }
    for n in 0..=103 {
        let rows = [&data[0][..n], &data[1][..n], &data[2][..n], &data[3][..n]];
        let c = &data[4][..n];
        let fast = dot_rows(rows, c);
        let portable = dot_rows_portable(rows, c);
        for r in 0..4 {
            if fast[r].to_bits() != portable[r].to_bits() {
                return Err("vfp::dot_rows differs from the portable sums");
            }
        }
    }
    // Unequal lengths: the shortest slice counts.
    let fast = dot_rows([&data[0][..10], &data[1], &data[2], &data[3]], &data[4]);
    let portable = dot_rows_portable(
        [
            &data[0][..10],
            &data[1][..10],
            &data[2][..10],
            &data[3][..10],
        ],
        &data[4][..10],
    );
    if fast != portable {
        return Err("vfp::dot_rows: unequal lengths not cut to the shortest");
    }
    Ok(())
}
