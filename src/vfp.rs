//! Hand-scheduled inner loop for the Cortex-M4F's FPU.
//!
//! Factoring the Gram matrix is most of a guide frame, and almost all of it
//! is four dot products against a shared row ([`crate::ldlt`]). Compiled
//! from Rust, each multiply-add costs about four instructions: a `VLDR` per
//! operand plus pointer increments, because `VLDR` takes no register offset
//! and the register allocator never lines operands up for `VLDM`. Here each
//! pass loads four elements of every operand with one `VLDMIA` and does
//! sixteen multiply-adds: 23 instructions for 16, 1.4 each.
//!
//! `VMLA.F32` rounds the product before adding, like the portable code's
//! `acc += a * b` (which LLVM also emits as `VMLA`), and the order of the
//! additions is the same, so the results are bit-identical to
//! [`crate::ldlt::dot_rows_portable`].

use crate::ldlt::BLOCK;

/// `rows[r] · c` for the four rows, over the shortest slice.
pub fn dot_rows(rows: [&[f32]; BLOCK], c: &[f32]) -> [f32; BLOCK] {
    let n = rows.iter().fold(c.len(), |n, r| n.min(r.len()));
    let blocks = n / 4;
    let mut acc = [0.0f32; BLOCK];
    if blocks > 0 {
        // SAFETY: each pointer is valid for `4 * blocks <= n` elements, read
        // only; `acc` is valid for four writes; the clobbered FPU registers
        // are declared (s16-s19 are callee-saved: the compiler saves them).
        unsafe {
            core::arch::asm!(
                "vldmia {acc}, {{s16-s19}}",
                "2:",
                "vldmia {c}!, {{s0-s3}}",
                "vldmia {r0}!, {{s4-s7}}",
                "vmla.f32 s16, s4, s0",
                "vmla.f32 s16, s5, s1",
                "vmla.f32 s16, s6, s2",
                "vmla.f32 s16, s7, s3",
                "vldmia {r1}!, {{s4-s7}}",
                "vmla.f32 s17, s4, s0",
                "vmla.f32 s17, s5, s1",
                "vmla.f32 s17, s6, s2",
                "vmla.f32 s17, s7, s3",
                "vldmia {r2}!, {{s4-s7}}",
                "vmla.f32 s18, s4, s0",
                "vmla.f32 s18, s5, s1",
                "vmla.f32 s18, s6, s2",
                "vmla.f32 s18, s7, s3",
                "vldmia {r3}!, {{s4-s7}}",
                "vmla.f32 s19, s4, s0",
                "vmla.f32 s19, s5, s1",
                "vmla.f32 s19, s6, s2",
                "vmla.f32 s19, s7, s3",
                "subs {n}, #1",
                "bne 2b",
                "vstmia {acc}, {{s16-s19}}",
                acc = in(reg) acc.as_mut_ptr(),
                c = inout(reg) c.as_ptr() => _,
                r0 = inout(reg) rows[0].as_ptr() => _,
                r1 = inout(reg) rows[1].as_ptr() => _,
                r2 = inout(reg) rows[2].as_ptr() => _,
                r3 = inout(reg) rows[3].as_ptr() => _,
                n = inout(reg) blocks => _,
                out("s0") _, out("s1") _, out("s2") _, out("s3") _,
                out("s4") _, out("s5") _, out("s6") _, out("s7") _,
                out("s16") _, out("s17") _, out("s18") _, out("s19") _,
                options(nostack),
            );
        }
    }
    // The last n % 4 elements continue the same sums, as the portable code
    // does.
    for k in 4 * blocks..n {
        for (a, row) in acc.iter_mut().zip(&rows) {
            *a += row[k] * c[k];
        }
    }
    acc
}
