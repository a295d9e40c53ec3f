//! The guider's control law for one frame with a measurement: proportional
//! control blended with the model's prediction, and the hysteresis term the
//! blend falls back on. One law for the guider (`Guider::frame`, in its
//! scalar type) and for the shadow loops of `trust` (in `f64`).

use crate::model::numeric::scalar::Scalar;

#[derive(Clone, Copy, Debug)]
pub(super) struct Law<S> {
    pub control_gain: S,
    pub prediction_gain: S,
    /// Errors smaller than this get no reactive correction.
    pub min_move: S,
    /// Weight of the older control in the hysteresis term.
    pub hysteresis: f64,
}

impl<S: Scalar> Law<S> {
    /// The control for the measured error `input`, given the control of
    /// the frame before the last (`older_control`, which the hysteresis
    /// term reads) and, if the model was consulted, its prediction and
    /// blend weight. Without a prediction, proportional control; a control
    /// that is not finite falls back on the hysteresis term.
    pub fn control(&self, input: S, older_control: S, prediction: Option<(S, S)>) -> S {
        let gain = self.control_gain;
        let mut hysteresis = gain
            * (S::from_f64(1.0 - self.hysteresis) * input
                + S::from_f64(self.hysteresis) * older_control);
        let mut control = gain * input;
        if input.abs() < self.min_move {
            control = S::ZERO;
            hysteresis = S::ZERO;
        }
        if let Some((prediction, blend)) = prediction {
            control += self.prediction_gain * prediction;
            control = blend * control + (S::ONE - blend) * hysteresis;
        }
        if !control.is_finite() {
            control = hysteresis;
        }
        control
    }

    /// The same law in `f64`.
    pub fn to_f64(self) -> Law<f64> {
        Law {
            control_gain: self.control_gain.to_f64(),
            prediction_gain: self.prediction_gain.to_f64(),
            min_move: self.min_move.to_f64(),
            hysteresis: self.hysteresis,
        }
    }
}
