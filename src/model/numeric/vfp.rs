//! Hand-scheduled inner loops for the Cortex-M4F's FPU: the factorisation's
//! (`dot_rows`) and the solves' (`dot3`, `sub_scaled3`).
//!
//! Factoring the Gram matrix is most of a guide frame, and almost all of it
//! is four dot products against a shared row ([`crate::model::ldlt`], [`super::dot`]). Compiled
//! from Rust, each multiply-add costs about four instructions: a `VLDR` per
//! operand plus pointer increments, because `VLDR` takes no register offset
//! and the register allocator never lines operands up for `VLDM`. Here each
//! pass loads four elements of every operand with one `VLDMIA` and does
//! sixteen multiply-adds: 23 instructions for 16, 1.4 each.
//!
//! `VMLA.F32` rounds the product before adding, like the portable code's
//! `acc += a * b` (which LLVM also emits as `VMLA`), and the order of the
//! additions is the same, so the results are bit-identical to
//! [`super::dot::dot_rows_portable`].

use super::dot::BLOCK;

/// `rows[r] · c` for the four rows, over the shortest slice.
pub fn dot_rows<'a>(rows: [&'a [f32]; BLOCK], c: &'a [f32]) -> [f32; BLOCK] {
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
    // does (each sum in the same order). Checked slices, as indexing
    // `row[k]` kept a bounds check; one pass per column for the four rows,
    // so that the loop's overhead is paid once per column, not per row,
    // without relying on the compiler to unroll it.
    let from = 4 * blocks;
    let tail = |s: &'a [f32]| s.get(from..n).unwrap_or(&[]);
    let [r0, r1, r2, r3] = rows.map(tail);
    for ((((&ck, &x0), &x1), &x2), &x3) in tail(c).iter().zip(r0).zip(r1).zip(r2).zip(r3) {
        acc[0] += x0 * ck;
        acc[1] += x1 * ck;
        acc[2] += x2 * ck;
        acc[3] += x3 * ck;
    }
    acc
}

// The solves' inner loops, as `dot_rows` does for the factorisation: compiled from Rust each multiply-add costs
// a `VLDR` per operand (and for the back substitution a `VSTR`) plus
// pointer increments; here one `VLDMIA`/`VSTMIA` moves four elements of an
// operand. `VMLA.F32`/`VMLS.F32` round the product before adding, like the
// portable `s += l * a` and `a -= l * f`, and the order of the operations
// per element and sum is the same: bit-identical to
// [`super::dot::dot3_portable`] and [`super::dot::sub_scaled3_portable`].
/// [`super::dot::dot3_portable`] for `f32`.
pub fn dot3(l: &[f32], x: &[f32], y: &[f32], z: &[f32]) -> [f32; 3] {
    let n = l.len().min(x.len()).min(y.len()).min(z.len());
    let blocks = n / 4;
    let mut acc = [0.0f32; 3];
    if blocks > 0 {
        // SAFETY: each pointer is valid for `4 * blocks <= n` elements,
        // read only; `acc` is valid for three writes; the clobbered FPU
        // registers are declared (s16-s18 are callee-saved: the
        // compiler saves them).
        unsafe {
            core::arch::asm!(
                "vldmia {acc}, {{s16-s18}}",
                "2:",
                "vldmia {l}!, {{s0-s3}}",
                "vldmia {x}!, {{s4-s7}}",
                "vmla.f32 s16, s0, s4",
                "vmla.f32 s16, s1, s5",
                "vmla.f32 s16, s2, s6",
                "vmla.f32 s16, s3, s7",
                "vldmia {y}!, {{s4-s7}}",
                "vmla.f32 s17, s0, s4",
                "vmla.f32 s17, s1, s5",
                "vmla.f32 s17, s2, s6",
                "vmla.f32 s17, s3, s7",
                "vldmia {z}!, {{s4-s7}}",
                "vmla.f32 s18, s0, s4",
                "vmla.f32 s18, s1, s5",
                "vmla.f32 s18, s2, s6",
                "vmla.f32 s18, s3, s7",
                "subs {n}, #1",
                "bne 2b",
                "vstmia {acc}, {{s16-s18}}",
                acc = in(reg) acc.as_mut_ptr(),
                l = inout(reg) l.as_ptr() => _,
                x = inout(reg) x.as_ptr() => _,
                y = inout(reg) y.as_ptr() => _,
                z = inout(reg) z.as_ptr() => _,
                n = inout(reg) blocks => _,
                out("s0") _, out("s1") _, out("s2") _, out("s3") _,
                out("s4") _, out("s5") _, out("s6") _, out("s7") _,
                out("s16") _, out("s17") _, out("s18") _,
                options(nostack),
            );
        }
    }
    // The last n % 4 elements continue the same sums.
    for k in 4 * blocks..n {
        acc[0] += l[k] * x[k];
        acc[1] += l[k] * y[k];
        acc[2] += l[k] * z[k];
    }
    acc
}

/// [`super::dot::sub_scaled3_portable`] for `f32`.
pub fn sub_scaled3(l: &[f32], v: [&mut [f32]; 3], f: [f32; 3]) {
    let [x, y, z] = v;
    let n = l.len().min(x.len()).min(y.len()).min(z.len());
    let blocks = n / 4;
    if blocks > 0 {
        // SAFETY: each pointer is valid for `4 * blocks <= n` elements;
        // `l` is only read, `x`, `y`, `z` are exclusive borrows, each
        // element read and then written in place; the clobbered FPU
        // registers are declared (s16-s18 are callee-saved: the
        // compiler saves them).
        unsafe {
            core::arch::asm!(
                "vmov s16, {f0}",
                "vmov s17, {f1}",
                "vmov s18, {f2}",
                "2:",
                "vldmia {l}!, {{s0-s3}}",
                "vldmia {x}, {{s4-s7}}",
                "vmls.f32 s4, s0, s16",
                "vmls.f32 s5, s1, s16",
                "vmls.f32 s6, s2, s16",
                "vmls.f32 s7, s3, s16",
                "vstmia {x}!, {{s4-s7}}",
                "vldmia {y}, {{s8-s11}}",
                "vmls.f32 s8, s0, s17",
                "vmls.f32 s9, s1, s17",
                "vmls.f32 s10, s2, s17",
                "vmls.f32 s11, s3, s17",
                "vstmia {y}!, {{s8-s11}}",
                "vldmia {z}, {{s12-s15}}",
                "vmls.f32 s12, s0, s18",
                "vmls.f32 s13, s1, s18",
                "vmls.f32 s14, s2, s18",
                "vmls.f32 s15, s3, s18",
                "vstmia {z}!, {{s12-s15}}",
                "subs {n}, #1",
                "bne 2b",
                f0 = in(reg) f[0].to_bits(),
                f1 = in(reg) f[1].to_bits(),
                f2 = in(reg) f[2].to_bits(),
                l = inout(reg) l.as_ptr() => _,
                x = inout(reg) x.as_mut_ptr() => _,
                y = inout(reg) y.as_mut_ptr() => _,
                z = inout(reg) z.as_mut_ptr() => _,
                n = inout(reg) blocks => _,
                out("s0") _, out("s1") _, out("s2") _, out("s3") _,
                out("s4") _, out("s5") _, out("s6") _, out("s7") _,
                out("s8") _, out("s9") _, out("s10") _, out("s11") _,
                out("s12") _, out("s13") _, out("s14") _, out("s15") _,
                out("s16") _, out("s17") _, out("s18") _,
                options(nostack),
            );
        }
    }
    for k in 4 * blocks..n {
        x[k] -= l[k] * f[0];
        y[k] -= l[k] * f[1];
        z[k] -= l[k] * f[2];
    }
}
