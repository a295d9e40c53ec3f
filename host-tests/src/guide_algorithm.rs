//! What the simulators drive: one control per guide frame.

/// A guide algorithm for one axis.
pub trait GuideAlgorithm {
    /// One frame: `measured` is the error the guider sees (px), `snr` the
    /// star's signal-to-noise ratio, `t` the frame time and `dt` the time
    /// step (s). Returns the control: same units and sign as `measured`, the
    /// amount of error to remove (the simulator does U += control).
    fn step(&mut self, t: f64, measured: f64, snr: f64, dt: f64) -> f64;

    /// The guider was dithered by `amount` px at `rate` px per second of
    /// gear time. Default: ignored.
    fn dither(&mut self, _amount: f64, _rate: f64) {}

    /// A frame without a star at `t` (the star lost), `dt` to the next;
    /// returns the control. Default: none.
    fn dark(&mut self, _t: f64, _dt: f64) -> f64 {
        0.0
    }

    /// Guiding starts again after a pause: a new section of a night.
    /// Default: nothing changes.
    fn restart(&mut self, _restart: &Restart) {}
}

/// What is known when guiding starts again.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Restart {
    /// Seconds since the last frame.
    pub gap_s: f64,
    /// The time step of the new section's frames, s.
    pub step_s: f64,
    /// How far gear time moved beyond the clock meanwhile, seconds (a slew
    /// to another target moves it by minus the change of right ascension;
    /// 0 on the same target), if the pointing says.
    pub gear_shift_s: Option<f64>,
    /// The telescope changed sides of the pier (a meridian flip): the RA
    /// axis turned half a turn.
    pub pier_flip: bool,
    /// The new pixel scale over the last (1 when unknown): the same error
    /// measures that many times fewer px.
    pub scale_ratio: f64,
}

impl<C: GuideAlgorithm + ?Sized> GuideAlgorithm for Box<C> {
    fn step(&mut self, t: f64, measured: f64, snr: f64, dt: f64) -> f64 {
        (**self).step(t, measured, snr, dt)
    }
    fn dither(&mut self, amount: f64, rate: f64) {
        (**self).dither(amount, rate)
    }
    fn dark(&mut self, t: f64, dt: f64) -> f64 {
        (**self).dark(t, dt)
    }
    fn restart(&mut self, restart: &Restart) {
        (**self).restart(restart)
    }
}

/// PHD2's hysteresis algorithm: control = aggressiveness x ((1 - hysteresis)
/// x input + hysteresis x previous control), and 0 when |input| < min_move.
/// The previous control is the one returned (0 after a frame below min move):
/// that reproduces all the hysteresis figures of docs/reference.md (tests/closed_loop.rs).
#[derive(Debug, Clone, PartialEq)]
pub struct Hysteresis {
    pub aggressiveness: f64,
    pub hysteresis: f64,
    pub min_move: f64,
    previous: f64,
}

impl Hysteresis {
    pub fn new(aggressiveness: f64, hysteresis: f64, min_move: f64) -> Self {
        Hysteresis {
            aggressiveness,
            hysteresis,
            min_move,
            previous: 0.0,
        }
    }

    /// The paper's reactive column: aggressiveness 0.6, hysteresis 0.1, min move 0.2.
    pub fn paper() -> Self {
        Self::new(0.6, 0.1, 0.2)
    }

    /// PHD2's replay baseline: aggressiveness 0.7, hysteresis 0.1, min move 0.2.
    pub fn phd2_baseline() -> Self {
        Self::new(0.7, 0.1, 0.2)
    }
}

impl GuideAlgorithm for Hysteresis {
    fn step(&mut self, _t: f64, measured: f64, _snr: f64, _dt: f64) -> f64 {
        let control = if measured.abs() < self.min_move {
            0.0
        } else {
            self.aggressiveness
                * ((1.0 - self.hysteresis) * measured + self.hysteresis * self.previous)
        };
        self.previous = control;
        control
    }

    /// The previous control was for the last section's star.
    fn restart(&mut self, _restart: &Restart) {
        self.previous = 0.0;
    }
}

/// No correction at all (the open loop).
#[derive(Debug, Clone, Copy, Default)]
pub struct OpenLoop;

impl GuideAlgorithm for OpenLoop {
    fn step(&mut self, _t: f64, _measured: f64, _snr: f64, _dt: f64) -> f64 {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hysteresis_steps() {
        let mut h = Hysteresis::new(0.6, 0.1, 0.2);
        assert_eq!(h.step(0.0, 0.1, 10.0, 2.0), 0.0);
        let c1 = h.step(2.0, 1.0, 10.0, 2.0);
        assert!((c1 - 0.54).abs() < 1e-15);
        let c2 = h.step(4.0, -1.0, 10.0, 2.0);
        assert!((c2 - 0.6 * (-0.9 + 0.054)).abs() < 1e-15);
        assert_eq!(h.step(6.0, -0.19, 10.0, 2.0), 0.0);
        let c4 = h.step(8.0, 1.0, 10.0, 2.0);
        assert!(
            (c4 - 0.54).abs() < 1e-15,
            "previous resets to 0 below min move"
        );
    }
}
