//! What the model keeps when guiding starts again after a pause: a new
//! section of a night (a download, a refocus, a new target, a meridian
//! flip, a guider restarted).

use crate::guide_algorithm::Restart;
use mkgp_mount::model::guider::{Guider, MAX_FRAME_GAP_S};
use mkgp_mount::model::numeric::scalar::Scalar;
use mkgp_mount::model::snapshot::{encode, Phase, SavedStage, Snapshot, SNAPSHOT_MAX};

/// How the model is carried across a pause (docs/results.md, "Nights of
/// several sections", has what each is worth).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Carry {
    /// Nothing: a guider restarted with no memory of the last section.
    Fresh,
    /// The model goes on as the firmware's does through a pause: its clock
    /// runs on (the grid bridges a pause within its window, 2.8 h), and a
    /// gear-time shift the pointing gives is made as a dither's (PHD2's
    /// predictive guider does so, within [`MAX_FRAME_GAP_S`]).
    Continue,
    /// The learned state is saved and taken back (`Guider::snapshot`,
    /// `Guider::restore`): at the gear time the pointing gives
    /// (`Phase::Known`), or found again from the new data where it gives
    /// none (`Phase::Unknown`); its level is met at the first frame.
    Restore,
    /// As [`Restore`](Self::Restore), the phase always found again.
    Search,
    /// The periods, stages and gates kept, the data dropped: learned again
    /// at the new phase.
    Relearn,
    /// By the pointing: on the same target (or with no pointing in the
    /// log: most pauses are a download, a dither or a refocus) the model
    /// goes on ([`Continue`](Self::Continue)); after a slew it is restored
    /// at the gear time the slew gives; after a meridian flip at a phase
    /// found again.
    #[default]
    Pointing,
}

/// A [`Carry`] and what it keeps between sections.
pub(super) struct Carrier {
    carry: Carry,
    /// The last snapshot taken (see [`Saved`]).
    saved: Option<Saved>,
    /// The clock of the last frame the model saw.
    last_s: Option<f64>,
}

/// A snapshot, the gear-time shift since it was taken (`None`: not
/// known) and the change of pixel scale since.
struct Saved {
    bytes: Vec<u8>,
    shift_s: Option<f64>,
    scale_ratio: f64,
}

/// What to do at a restart.
enum Action {
    Forget,
    GoOn,
    Restore(Option<f64>),
    Relearn,
}

impl Carrier {
    pub fn new(carry: Carry) -> Self {
        Carrier {
            carry,
            saved: None,
            last_s: None,
        }
    }

    /// The model saw a frame at clock `t`.
    pub fn saw(&mut self, t: f64) {
        self.last_s = Some(t);
    }

    pub fn restart<S: Scalar, const N: usize>(
        &mut self,
        guider: &mut Box<Guider<S, N>>,
        restart: &Restart,
    ) {
        let shift = restart.gear_shift_s;
        // Only a restore can give the model's px another pixel scale.
        let rescaled = restart.scale_ratio != 1.0;
        let action = match self.carry {
            Carry::Fresh => Action::Forget,
            Carry::Continue => Action::GoOn,
            Carry::Restore => Action::Restore(shift),
            Carry::Search => Action::Restore(None),
            Carry::Relearn => Action::Relearn,
            Carry::Pointing if restart.pier_flip => Action::Relearn,
            Carry::Pointing if rescaled || shift.is_some_and(|s| s != 0.0) => {
                Action::Restore(shift)
            }
            Carry::Pointing => Action::GoOn,
        };
        match action {
            Action::Forget => **guider = Guider::new(*guider.config()),
            Action::GoOn => self.go_on(guider, restart),
            Action::Restore(shift) => self.restore(guider, shift, restart),
            Action::Relearn => relearn(guider),
        }
    }

    /// The model goes on across the pause: told of it by frames without a
    /// star, at most [`MAX_FRAME_GAP_S`] apart (a frame further than that
    /// from the last would be refused as a clock glitch) and the last a time
    /// step before the next frame (so that the model does not predict the
    /// whole pause into that frame's control: the pause's motion is in no
    /// error the new section measures, its star locked afresh), the shift
    /// of gear time made as a dither's.
    fn go_on<S: Scalar, const N: usize>(&mut self, guider: &mut Guider<S, N>, restart: &Restart) {
        if let Some(last) = self.last_s {
            let last_dark = last + restart.gap_s - restart.step_s;
            let mut t = last;
            while t < last_dark {
                t = (t + 0.5 * MAX_FRAME_GAP_S).min(last_dark);
                guider.dark_frame(t, S::from_f64(restart.step_s));
            }
        }
        if let Some(shift) = restart.gear_shift_s.filter(|&s| s != 0.0) {
            guider.dithered(S::from_f64(shift), S::ONE);
        }
    }

    /// Save the model and take it back at the phase `shift_s` gives.
    fn restore<S: Scalar, const N: usize>(
        &mut self,
        guider: &mut Guider<S, N>,
        shift_s: Option<f64>,
        restart: &Restart,
    ) {
        let mut bytes = vec![0; SNAPSHOT_MAX];
        match guider.snapshot(&mut bytes) {
            Ok(len) => {
                bytes.truncate(len);
                self.saved = Some(Saved {
                    bytes,
                    shift_s,
                    scale_ratio: restart.scale_ratio,
                });
            }
            // Data restored at the last start is not placed yet: the
            // snapshot before it is still the one to keep.
            Err(_) => {
                if let Some(saved) = &mut self.saved {
                    saved.shift_s = saved.shift_s.zip(shift_s).map(|(a, b)| a + b);
                    saved.scale_ratio *= restart.scale_ratio;
                }
            }
        }
        let Some(saved) = &self.saved else {
            return;
        };
        let bytes = rescaled::<N>(&saved.bytes, saved.scale_ratio);
        let Ok(snapshot) = Snapshot::parse(&bytes, N) else {
            return;
        };
        let phase = saved.shift_s.map_or(Phase::Unknown, |s| Phase::Known {
            gear_time_offset_s: s,
        });
        // A refused snapshot changes nothing: the model goes on.
        let _ = guider.restore(&snapshot, phase);
    }
}

/// Keep what the model learned of the gear train (its periods, stages and
/// gates), not its data: restored from a snapshot without cells, it learns
/// the data again from the next frame.
fn relearn<S: Scalar, const N: usize>(guider: &mut Guider<S, N>) {
    let mut bytes = vec![0; SNAPSHOT_MAX];
    let Ok(len) = guider.snapshot(&mut bytes) else {
        return;
    };
    let Ok(snapshot) = Snapshot::parse(&bytes[..len], N) else {
        return;
    };
    let stages: Vec<SavedStage> = (0..N).filter_map(|s| snapshot.stage(s)).collect();
    let mut empty = vec![0; SNAPSHOT_MAX];
    let Ok(len) = encode(&stages, snapshot.origin_s(), std::iter::empty(), &mut empty) else {
        return;
    };
    if let Ok(snapshot) = Snapshot::parse(&empty[..len], N) {
        let _ = guider.restore(&snapshot, Phase::Unknown);
    }
}

/// `bytes` (a snapshot of `N` stages) with its gear error in px of a pixel
/// scale `ratio` times the saved one's: the same arcsec, `1 / ratio` times
/// the px.
fn rescaled<const N: usize>(bytes: &[u8], ratio: f64) -> Vec<u8> {
    if ratio == 1.0 {
        return bytes.to_vec();
    }
    let Ok(snapshot) = Snapshot::parse(bytes, N) else {
        return bytes.to_vec();
    };
    let stages: Vec<SavedStage> = (0..N).filter_map(|s| snapshot.stage(s)).collect();
    let k = (1.0 / ratio) as f32;
    let cells = snapshot.cells().map(|(g, v)| (g * k, v * k * k));
    let mut out = vec![0; bytes.len()];
    match encode(&stages, snapshot.origin_s(), cells, &mut out) {
        Ok(len) => {
            out.truncate(len);
            out
        }
        Err(_) => bytes.to_vec(),
    }
}
