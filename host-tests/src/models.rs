//! The one place that decides what the `ppec`, `mkgp` and `mkgp3` columns
//! run: the library's Gaussian-process guider ([`crate::gp::GpAlgorithm`])
//! with 1 periodic stage (PPEC), 2 (MKGP) or 3 (MKGP3).

use crate::gp::{Carry, GpAlgorithm};
use crate::guide_algorithm::GuideAlgorithm;
use mkgp_mount::model::additions::Additions;

/// A Gaussian-process model for the simulators.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Model {
    /// Single periodic stage: the paper's baseline (PHD2/INDIGO's PPEC).
    Ppec,
    /// Two periodic stages: the paper's multi-kernel model.
    Mkgp,
    /// Three periodic stages: a worm, a spur gear and a motor gear.
    Mkgp3,
}

impl Model {
    pub fn stages(self) -> usize {
        match self {
            Model::Ppec => 1,
            Model::Mkgp => 2,
            Model::Mkgp3 => 3,
        }
    }
}

/// A fresh guide algorithm for `model`. `control_gain` and `prediction_gain` as in
/// PHD2 (`None`: the library's defaults, 0.6 and 0.5).
pub fn algorithm(
    model: Model,
    control_gain: Option<f64>,
    prediction_gain: Option<f64>,
) -> Box<dyn GuideAlgorithm> {
    carrying(
        model,
        control_gain,
        prediction_gain,
        Carry::default(),
        Additions::ALL,
    )
}

/// [`algorithm`], carried across a pause in guiding as `carry` says, with
/// the model's `additions` as given.
pub fn carrying(
    model: Model,
    control_gain: Option<f64>,
    prediction_gain: Option<f64>,
    carry: Carry,
    additions: Additions,
) -> Box<dyn GuideAlgorithm> {
    let (c, p, a) = (control_gain, prediction_gain, additions);
    match model {
        Model::Ppec => Box::new(
            GpAlgorithm::<1>::new(c, p)
                .with_carry(carry)
                .with_additions(a),
        ),
        Model::Mkgp => Box::new(
            GpAlgorithm::<2>::new(c, p)
                .with_carry(carry)
                .with_additions(a),
        ),
        Model::Mkgp3 => Box::new(
            GpAlgorithm::<3>::new(c, p)
                .with_carry(carry)
                .with_additions(a),
        ),
    }
}
