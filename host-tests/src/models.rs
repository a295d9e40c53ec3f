//! The one place that decides what the `ppec` and `mkgp` columns run.
//!
//! With the `model` feature: the library's Gaussian-process guider
//! ([`crate::gp::GpController`]) with 1 periodic stage (PPEC) or 2 (MKGP).
//! Without it (the library's guider is still being written): a stand-in,
//! hysteresis with the same control gain, hysteresis 0.1 and min move 0.2,
//! and [`warn_if_stand_in`] prints a loud warning.

use crate::controller::Controller;
#[cfg(not(feature = "model"))]
use crate::controller::Hysteresis;

/// A Gaussian-process model for the simulators.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Model {
    /// Single periodic stage: the paper's baseline (PHD2/INDIGO's PPEC).
    Ppec,
    /// Two periodic stages: the paper's multi-kernel model.
    Mkgp,
}

impl Model {
    pub fn stages(self) -> usize {
        match self {
            Model::Ppec => 1,
            Model::Mkgp => 2,
        }
    }
}

/// True when the real model is built in.
pub const MODEL_AVAILABLE: bool = cfg!(feature = "model");

/// A fresh controller for `model`. `control_gain` and `prediction_gain` as in
/// PHD2 (`None`: the library's defaults, 0.6 and 0.5).
pub fn controller(
    model: Model,
    control_gain: Option<f64>,
    prediction_gain: Option<f64>,
) -> Box<dyn Controller + Send> {
    #[cfg(feature = "model")]
    {
        use crate::gp::GpController;
        match model {
            Model::Ppec => Box::new(GpController::<1>::new(control_gain, prediction_gain)),
            Model::Mkgp => Box::new(GpController::<2>::new(control_gain, prediction_gain)),
        }
    }
    #[cfg(not(feature = "model"))]
    {
        let _ = (model, prediction_gain);
        Box::new(Hysteresis::new(control_gain.unwrap_or(0.6), 0.1, 0.2))
    }
}

/// Print a loud warning to stderr when the model columns are stand-ins.
pub fn warn_if_stand_in() {
    if !MODEL_AVAILABLE {
        eprintln!(
            "WARNING: built without the `model` feature: the ppec and mkgp columns are \
             HYSTERESIS STAND-INS, not the Gaussian-process model. \
             Build with `--features model` once mkgp_mount::guider exists."
        );
    }
}
