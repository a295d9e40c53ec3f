//! The library's Gaussian-process guider as a [`GuideAlgorithm`].

mod carry;
pub mod trace;

use crate::guide_algorithm::{GuideAlgorithm, Restart};
use mkgp_mount::model::additions::Additions;
use mkgp_mount::model::guider::{Guider, GuiderConfig};
use mkgp_mount::model::numeric::scalar::Scalar;

pub use carry::Carry;

/// `mkgp_mount::model::guider::Guider<S, N>`: N = 1 is PPEC, N = 2 the
/// multi-kernel model; `S` is `f64` (the host reference, the default) or
/// `f32` (what runs on the target). The simulators work in `f64`: the
/// measurement is rounded to `S` on the way in and the control widened on
/// the way out. Boxed: the guider is about 100 KiB.
pub struct GpAlgorithm<const N: usize, S: Scalar = f64> {
    guider: Box<Guider<S, N>>,
    carry: carry::Carrier,
}

impl<const N: usize, S: Scalar> GpAlgorithm<N, S> {
    /// `None` keeps the library's default gain.
    pub fn new(control_gain: Option<f64>, prediction_gain: Option<f64>) -> Self {
        let mut config = GuiderConfig::<S>::default();
        if let Some(g) = control_gain {
            config.control_gain = S::from_f64(g);
        }
        if let Some(g) = prediction_gain {
            config.prediction_gain = S::from_f64(g);
        }
        GpAlgorithm {
            guider: Box::new(Guider::new(config)),
            carry: carry::Carrier::new(Carry::default()),
        }
    }

    /// With some of the model's `additions` switched off.
    pub fn with_additions(mut self, additions: Additions) -> Self {
        let config = GuiderConfig {
            additions,
            ..*self.guider.config()
        };
        self.guider = Box::new(Guider::new(config));
        self
    }

    /// What the model keeps when guiding starts again ([`Carry`]).
    pub fn with_carry(mut self, carry: Carry) -> Self {
        self.carry = carry::Carrier::new(carry);
        self
    }

    pub fn guider(&self) -> &Guider<S, N> {
        &self.guider
    }
}

impl<const N: usize, S: Scalar> GuideAlgorithm for GpAlgorithm<N, S> {
    fn step(&mut self, t: f64, measured: f64, snr: f64, dt: f64) -> f64 {
        self.carry.saw(t);
        self.guider
            .frame(t, S::from_f64(measured), S::from_f64(snr), S::from_f64(dt))
            .to_f64()
    }

    fn dither(&mut self, amount: f64, rate: f64) {
        self.guider.dithered(S::from_f64(amount), S::from_f64(rate));
    }

    fn dark(&mut self, t: f64, dt: f64) -> f64 {
        self.carry.saw(t);
        self.guider.dark_frame(t, S::from_f64(dt)).to_f64()
    }

    fn restart(&mut self, restart: &Restart) {
        self.carry.restart(&mut self.guider, restart);
    }
}
