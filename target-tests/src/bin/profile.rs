//! Instructions of the model's parts on the emulated Cortex-M4F, to see
//! where a frame's cost goes (`guide-sim bench` gives the whole frame):
//!
//! ```sh
//! cd target-tests && cargo run --release --bin profile
//! ```
//!
//! A grid of 6000 s of case C8's gear error (1,200 cells), then: 2,048
//! full-kernel evaluations for one and two stages (what the subset
//! selection costs), one spectrum, one inference and prediction for each,
//! and the factorisation and one solve of a 100-point Gram matrix. Counted
//! with SysTick under `-icount shift=0` (resolution 40 instructions).
#![no_std]
#![no_main]
#[path = "../instr.rs"]
mod instr;
#[path = "../support.rs"]
mod support;
use core::hint::black_box;
use cortex_m_rt::{entry, exception, ExceptionFrame};
use cortex_m_semihosting::hprintln;
use mkgp_mount::model::gp::grid::{Averaging, Grid};
use mkgp_mount::model::gp::infer::Gp;
use mkgp_mount::model::gp::kernel::Kernel;
use mkgp_mount::model::spectral::fft::FFT_LEN;
use mkgp_mount::model::spectral::spectrum::Spectrum;
use support::{exit, Slot};

static GRID: Slot<Grid<f32>> = Slot::new();
static GP: Slot<Gp<f32>> = Slot::new();
static BUF: Slot<[f32; FFT_LEN]> = Slot::new();
static L: Slot<mkgp_mount::model::ldlt::Ldlt<f32, 100, 5050>> = Slot::new();

fn g(t: f64) -> f64 {
    let pi2 = 2.0 * core::f64::consts::PI;
    9.0 * libm::sin(pi2 * t / 288.0)
        + 6.0 * libm::sin(pi2 * t / 144.0)
        + 4.5 * libm::sin(pi2 * t / 110.0)
        + 3.6 * libm::sin(pi2 * t / 55.0)
}

#[entry]
fn main() -> ! {
    let grid = GRID.init(Grid::new(Averaging::Exact));
    let mut t = 0.0;
    while t < 6000.0 {
        grid.push(t, g(t), 0.7);
        t += 2.0;
    }
    let buf = BUF.init([0.0; FFT_LEN]);
    let gp = GP.init(Gp::new());
    instr::start();
    let k1: Kernel<f32, 1> = Kernel::new(&[288.0], &[1.0]);
    let k2: Kernel<f32, 2> = Kernel::new(&[288.0, 110.0], &[1.0, 1.0]);
    let a = instr::elapsed_instructions();
    let mut s = 0.0f32;
    for i in 0..2048 {
        s += k1.full(black_box(i as f32 * 5.0 + 1.3));
    }
    let b = instr::elapsed_instructions();
    for i in 0..2048 {
        s += k2.full(black_box(i as f32 * 5.0 + 1.3));
    }
    let c = instr::elapsed_instructions();
    black_box(s);
    hprintln!("kernel full x2048: N1 {} N2 {}", b - a, c - b);
    let a = instr::elapsed_instructions();
    let sp = Spectrum::compute(grid, buf).is_some();
    let b = instr::elapsed_instructions();
    hprintln!(
        "spectrum compute ({} cells): {} ok {}",
        grid.len(),
        b - a,
        sp
    );
    for (name, n) in [("N1", 1usize), ("N2", 2)] {
        let a = instr::elapsed_instructions();
        let r = if n == 1 {
            gp.infer(grid, &k1, 5990.0, buf, true)
        } else {
            gp.infer(grid, &k2, 5990.0, buf, true)
        };
        let b = instr::elapsed_instructions();
        let p = if n == 1 {
            gp.predict_change(grid, &k1, 5989.0, 5992.0)
        } else {
            gp.predict_change(grid, &k2, 5989.0, 5992.0)
        };
        let c = instr::elapsed_instructions();
        hprintln!(
            "infer {}: {} ({:?}); predict {} -> {}",
            name,
            b - a,
            r,
            c - b,
            p
        );
    }
    let l = L.init(mkgp_mount::model::ldlt::Ldlt::new());
    l.set_dim(100);
    for i in 0..100 {
        let row = l.row_mut(i);
        for (j, v) in row.iter_mut().enumerate() {
            *v = k1.full((i as f32 - j as f32) * 17.0 * 5.0);
        }
        row[i] += 0.7;
    }
    let a = instr::elapsed_instructions();
    let r = l.factor();
    let b = instr::elapsed_instructions();
    let mut v = [1.0f32; 100];
    let s = l.solve(&mut v);
    let c = instr::elapsed_instructions();
    hprintln!(
        "ldlt factor 100: {} ({:?}); solve {} ({:?})",
        b - a,
        r,
        c - b,
        s
    );
    exit(true)
}

#[exception]
unsafe fn HardFault(_ef: &ExceptionFrame) -> ! {
    exit(false)
}
#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    exit(false)
}
