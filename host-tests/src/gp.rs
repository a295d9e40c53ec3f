//! The library's Gaussian-process guider as a [`Controller`].

use crate::controller::Controller;
use mkgp_mount::guider::{Guider, GuiderConfig};

/// `mkgp_mount::guider::Guider<f64, N>`: N = 1 is PPEC, N = 2 the
/// multi-kernel model. Boxed: the guider is about 100 KiB.
pub struct GpController<const N: usize> {
    guider: Box<Guider<f64, N>>,
}

impl<const N: usize> GpController<N> {
    /// `None` keeps the library's default gain.
    pub fn new(control_gain: Option<f64>, prediction_gain: Option<f64>) -> Self {
        let mut config = GuiderConfig::<f64>::default();
        if let Some(g) = control_gain {
            config.control_gain = g;
        }
        if let Some(g) = prediction_gain {
            config.prediction_gain = g;
        }
        GpController {
            guider: Box::new(Guider::new(config)),
        }
    }

    pub fn guider(&self) -> &Guider<f64, N> {
        &self.guider
    }
}

impl<const N: usize> Controller for GpController<N> {
    fn step(&mut self, t: f64, measured: f64, snr: f64, dt: f64) -> f64 {
        self.guider.frame(t, measured, snr, dt)
    }
}
