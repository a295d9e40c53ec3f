//! What the model holds after each frame, as CSV rows: the traces
//! `guide-sim table --trace` and `guide-sim replay --trace` write, and the
//! stage columns the night's learner trace shares.

use super::GpAlgorithm;
use crate::guide_algorithm::{GuideAlgorithm, Restart};
use mkgp_mount::model::guider::Guider;
use mkgp_mount::model::numeric::scalar::Scalar;
use std::fmt::Write;

/// The stage columns of a trace: each stage's tracked period (s) and gate.
pub fn stage_header(stages: usize) -> String {
    let mut h = String::new();
    for s in 1..=stages {
        let _ = write!(h, ",period_{s}_s,gate_{s}");
    }
    h
}

/// `guider`'s stage columns, as [`stage_header`] names them.
pub fn stage_values<S: Scalar, const N: usize>(guider: &Guider<S, N>) -> String {
    let mut r = String::new();
    for (s, p) in guider.periods_s().iter().enumerate() {
        let _ = write!(r, ",{p:.3},{:.3}", guider.gate(s));
    }
    r
}

/// A trace's header: the frame's time, the error the model was given (empty
/// on a frame without a star), its control and blend weight, and the
/// stages.
pub fn header(stages: usize) -> String {
    format!(
        "time_s,measured_px,control_px,blend_weight{}",
        stage_header(stages)
    )
}

/// The model as a guide algorithm that writes a row of [`header`] after
/// each frame.
pub struct Traced<const N: usize> {
    model: GpAlgorithm<N>,
    csv: String,
}

impl<const N: usize> Traced<N> {
    pub fn new(model: GpAlgorithm<N>) -> Self {
        Self {
            model,
            csv: header(N) + "\n",
        }
    }

    /// The trace so far, header first.
    pub fn csv(&self) -> &str {
        &self.csv
    }

    fn row(&mut self, t: f64, measured: Option<f64>, control: f64) {
        let g = self.model.guider();
        let measured = measured.map_or(String::new(), |m| format!("{m:.4}"));
        let _ = writeln!(
            self.csv,
            "{t:.3},{measured},{control:.4},{:.4}{}",
            g.blend_weight(),
            stage_values(g)
        );
    }
}

impl<const N: usize> GuideAlgorithm for Traced<N> {
    fn step(&mut self, t: f64, measured: f64, snr: f64, dt: f64) -> f64 {
        let u = self.model.step(t, measured, snr, dt);
        self.row(t, Some(measured), u);
        u
    }

    fn dither(&mut self, amount: f64, rate: f64) {
        self.model.dither(amount, rate);
    }

    fn dark(&mut self, t: f64, dt: f64) -> f64 {
        let u = self.model.dark(t, dt);
        self.row(t, None, u);
        u
    }

    fn restart(&mut self, restart: &Restart) {
        self.model.restart(restart);
    }
}
