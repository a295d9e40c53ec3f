//! The measurements behind docs/decisions.md: our `f32` functions
//! (src/model/numeric/approx.rs) and FFT (src/model/spectral/fft.rs)
//! against the micromath and microfft crates, each scored against `f64`.
//! Ignored by default (they measure crates the library does not use):
//!
//! ```sh
//! cd host-tests && cargo test --release --test decisions -- --ignored --nocapture
//! ```
//!
//! Each asserts what its decision rests on, so a new version of either crate
//! that removes the reason shows up here.

// Called as `F32Ext::sin(x)`: with std, `x.sin()` would be std's.
use micromath::F32Ext;
use mkgp_mount::model::numeric::approx;
use mkgp_mount::model::spectral::fft::{power_spectrum, FFT_LEN};
use std::f64::consts::PI;

/// The largest |f(x) - reference(x)| (divided by |reference(x)| if
/// `relative`) over `points`.
fn worst(
    points: impl Iterator<Item = f32>,
    f: impl Fn(f32) -> f32,
    reference: impl Fn(f64) -> f64,
    relative: bool,
) -> f64 {
    points
        .map(|x| {
            let want = reference(x as f64);
            let err = (f(x) as f64 - want).abs();
            if relative {
                err / want.abs()
            } else {
                err
            }
        })
        .fold(0.0, f64::max)
}

/// `n + 1` evenly spaced points from `a` to `b`.
fn linspace(a: f64, b: f64, n: usize) -> impl Iterator<Item = f32> {
    (0..=n).map(move |i| (a + (b - a) * i as f64 / n as f64) as f32)
}

/// `n + 1` log-spaced points from `a` to `b` (both > 0).
fn logspace(a: f64, b: f64, n: usize) -> impl Iterator<Item = f32> {
    let (la, lb) = (a.ln(), b.ln());
    (0..=n).map(move |i| (la + (lb - la) * i as f64 / n as f64).exp() as f32)
}

/// One function over its range: ours, micromath's; prints both and checks
/// that ours is at least 100 times more accurate.
fn row(
    what: &str,
    points: impl Fn() -> Box<dyn Iterator<Item = f32>>,
    ours: impl Fn(f32) -> f32,
    micromath: impl Fn(f32) -> f32,
    reference: impl Fn(f64) -> f64 + Copy,
    relative: bool,
) {
    let a = worst(points(), ours, reference, relative);
    let m = worst(points(), micromath, reference, relative);
    let kind = if relative { "relative" } else { "absolute" };
    println!("{what}: max {kind} error: approx.rs {a:.1e}, micromath {m:.1e}");
    assert!(100.0 * a < m, "{what}: micromath within 100x of approx.rs");
}

#[test]
#[ignore = "measurement for docs/decisions.md"]
fn approx_against_micromath() {
    // cos in the spectrum's Hamming window, argument in [0, 2 pi].
    row(
        "cos on [0, 2 pi]",
        || Box::new(linspace(0.0, 2.0 * PI, 1_000_000)),
        approx::cos,
        F32Ext::cos,
        f64::cos,
        false,
    );
    row(
        "sin on [-pi, pi]",
        || Box::new(linspace(-PI, PI, 1_000_000)),
        approx::sin,
        F32Ext::sin,
        f64::sin,
        false,
    );
    // The kernel's periodic factor sin^2(pi d / P): lags d = 0, 5, ..,
    // 10,235 s (the grid's window), periods 50 .. 2000 s. Each is scored
    // against its own f32 argument (d / P for ours, pi d / P for
    // micromath's sin), as sin and cos above: the rounding of that product
    // (up to about 2e-5 at P = 50 s) is paid by any f32 code.
    for period in [50.0f64, 155.0, 432.0, 2000.0] {
        let inv = (1.0 / period) as f32;
        let factor = (PI / period) as f32;
        let lags = || (0..2048).map(|i| (5 * i) as f32);
        let a = worst(
            lags(),
            |d| approx::sin2_scaled(d, inv, 1.0),
            |d| (PI * (d as f32 * inv) as f64).sin().powi(2),
            false,
        );
        let m = worst(
            lags(),
            |d| F32Ext::sin(factor * d).powi(2),
            |d| ((factor * d as f32) as f64).sin().powi(2),
            false,
        );
        println!(
            "kernel sin^2(pi d / {period}), d <= 10,235 s: max absolute error: \
             approx.rs {a:.1e}, micromath {m:.1e}"
        );
        assert!(
            100.0 * a < m,
            "sin^2, P = {period}: micromath within 100x of approx.rs"
        );
    }
    // The kernel's exponents.
    row(
        "exp on [-87, 0]",
        || Box::new(linspace(-87.0, 0.0, 1_000_000)),
        approx::exp_nonpositive,
        F32Ext::exp,
        f64::exp,
        true,
    );
    row(
        "sqrt on [1e-6, 1e6]",
        || Box::new(logspace(1e-6, 1e6, 1_000_000)),
        approx::sqrt,
        F32Ext::sqrt,
        f64::sqrt,
        true,
    );
}

/// A grid-like input: 2048 cells of 5 s holding a C8-like gear error and
/// drift, zero-padded to 4096 (as the spectrum does).
fn signal() -> [f64; FFT_LEN] {
    let mut x = [0.0; FFT_LEN];
    for (n, v) in x.iter_mut().enumerate().take(FFT_LEN / 2) {
        let t = 5.0 * n as f64;
        *v = [(288.0, 9.0), (144.0, 6.0), (110.0, 4.5), (55.0, 3.6)]
            .iter()
            .map(|&(p, a)| a * (2.0 * PI * t / p).sin())
            .sum::<f64>()
            + 0.0008 * (t - 5120.0);
    }
    x
}

#[test]
#[ignore = "measurement for docs/decisions.md"]
fn fft_against_microfft() {
    let x = signal();
    let mut reference = x;
    power_spectrum::<f64>(&mut reference);
    let peak = reference[..=FFT_LEN / 2]
        .iter()
        .cloned()
        .fold(0.0, f64::max);

    let mut ours = x.map(|v| v as f32);
    power_spectrum::<f32>(&mut ours);

    // microfft: f32 only, one function per power-of-two size; the Nyquist
    // term is packed into the imaginary part of bin 0.
    let mut input = x.map(|v| v as f32);
    let bins = microfft::real::rfft_4096(&mut input);
    let micro = |k: usize| -> f64 {
        match k {
            0 => (bins[0].re as f64).powi(2),
            k if k == FFT_LEN / 2 => (bins[0].im as f64).powi(2),
            k => bins[k].norm_sqr() as f64,
        }
    };

    let (mut e_ours, mut e_micro) = (0.0f64, 0.0f64);
    for (k, &want) in reference.iter().enumerate().take(FFT_LEN / 2 + 1) {
        e_ours = e_ours.max((ours[k] as f64 - want).abs() / peak);
        e_micro = e_micro.max((micro(k) - want).abs() / peak);
    }
    println!(
        "power spectrum of 4096 reals, max |error| / peak power against fft.rs in f64: \
         fft.rs in f32 {e_ours:.1e}, microfft {e_micro:.1e}"
    );
    // Same accuracy class: the choice rests on the f64 reference, not on
    // accuracy.
    assert!(e_ours < 1e-5 && e_micro < 1e-5);
}
