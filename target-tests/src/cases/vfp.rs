//! The hand-scheduled FPU loops (`mkgp_mount::model::numeric::vfp`) against the portable
//! code they replace: bit-identical sums for every length around the
//! four-element passes, on the target where it runs.

use crate::harness::TestResult;
use mkgp_mount::model::numeric::dot::dot_rows_portable;
use mkgp_mount::model::numeric::vfp::dot_rows;
use mkgp_mount::testing::SplitMix64;

/// Uniform values in (-1, 1).
fn fill(rng: &mut SplitMix64, out: &mut [f32]) {
    for x in out {
        *x = rng.f64_in(-1.0, 1.0) as f32;
    }
}

pub fn dot_rows_matches_portable() -> TestResult {
    let mut rng = SplitMix64::new(1);
    let mut data = [[0.0f32; 103]; 5];
    for row in &mut data {
        fill(&mut rng, row);
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

pub fn solve_loops_match_portable() -> TestResult {
    use mkgp_mount::model::numeric::dot::{dot3_portable, sub_scaled3_portable};
    use mkgp_mount::model::numeric::vfp::{dot3, sub_scaled3};
    let mut rng = SplitMix64::new(2);
    let mut data = [[0.0f32; 43]; 4];
    for row in &mut data {
        fill(&mut rng, row);
    }
    let f = [0.75f32, -1.25, 0.5];
    for n in 0..=43 {
        let (l, x, y, z) = (&data[0][..n], &data[1][..n], &data[2][..n], &data[3][..n]);
        let fast = dot3(l, x, y, z);
        let portable = dot3_portable(l, x, y, z);
        if fast.map(f32::to_bits) != portable.map(f32::to_bits) {
            return Err("vfp::dot3 differs from the portable sums");
        }
        let (mut a, mut b) = ([data[1], data[2], data[3]], [data[1], data[2], data[3]]);
        {
            let [a0, a1, a2] = &mut a;
            sub_scaled3(l, [&mut a0[..n], &mut a1[..n], &mut a2[..n]], f);
            let [b0, b1, b2] = &mut b;
            sub_scaled3_portable(l, [&mut b0[..n], &mut b1[..n], &mut b2[..n]], f);
        }
        for r in 0..3 {
            if a[r].map(f32::to_bits) != b[r].map(f32::to_bits) {
                return Err("vfp::sub_scaled3 differs from the portable update");
            }
        }
    }
    Ok(())
}
