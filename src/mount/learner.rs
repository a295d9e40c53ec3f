//! The slow part of the controller: the model. It learns the gear error
//! from the guide frames that [`Guiding`](crate::mount::guiding::Guiding)
//! forms, and returns the feed-forward for the time to the next frame (the
//! module doc of [`crate::mount::guiding`] has the window and the rate).
//!
//! It owns the model (`Guider<f32, N>`: the firmware keeps it in a static)
//! and runs in a task of lower priority than ST4 and stepping, once per
//! frame.

use core::mem::MaybeUninit;

use crate::model::additions::Additions;
use crate::model::guider::stage_watch::StageWatch;
use crate::model::guider::{Faults, Guider, GuiderConfig, DITHER_FRAMES, MAX_TIME_STEP_S};
use crate::model::in_place::{build, init_fields};
use crate::model::numeric::clamp;
use crate::model::snapshot::{
    Phase, Snapshot, SnapshotError, FORMAT_VERSION, SNAPSHOT_MAX, SNAPSHOT_MAX_STAGES,
};
use crate::mount::config::Mount;
use crate::mount::frame::{FeedForward, Frame, FrameKind, PulseShare};
use crate::mount::guiding::bump::{self, Bump};
use crate::mount::guiding::earned_share::{EarnedShare, LongerFrames, SavedShare, SAVED_LEN};
use crate::mount::guiding::feed_forward_weight::FeedForwardWeight;
use crate::mount::guiding::pulse_weight::PulseWeight;

/// Periodic stages of the firmware's model (the worm and two more), and of
/// the simulators that stand for it. Chosen by measurement: the same as two
/// stages on the paper's cases, far better on three-stage gear trains, and
/// within the Cortex-M4's budgets (docs/decisions.md, "Stages in the
/// firmware").
pub const FIRMWARE_STAGES: usize = 3;

/// The store's format of the learner's record ([`Learner::snapshot`]): the
/// configured worm period it was learned under (`f32`, little-endian:
/// [`WORM_LEN`] bytes), the pulse share and weight ([`SavedShare`],
/// [`SAVED_LEN`] bytes) and then the model's snapshot (`model::snapshot`,
/// its format 1). Records of earlier layouts were never written by a
/// board that ran: refused by their format.
pub const RECORD_FORMAT: u16 = 4;
/// Bytes of the configured worm period at the record's head.
pub const WORM_LEN: usize = 4;
/// Largest record: 8,168 bytes for three stages.
pub const RECORD_MAX: usize = WORM_LEN + SAVED_LEN + SNAPSHOT_MAX;
// The record wraps the model's snapshot format 1: a new model layout needs
// a new record format.
const _: () = assert!(FORMAT_VERSION == 1);
/// How far the configured worm period may have moved since the model was
/// saved, as a fraction of it. The model's own periods are learned, the
/// configured one only seeds them, so a correction within this (a measured
/// period replacing the datasheet's) keeps the model; beyond it the
/// configuration describes another worm, and the model learns that one
/// from its prior.
pub const WORM_PERIOD_CHANGE: f32 = 0.01;
// The firmware's snapshot fits the buffers sized for it (and the store's
// record: `persist`).
const _: () = assert!(FIRMWARE_STAGES <= SNAPSHOT_MAX_STAGES);

/// The model's blend weight from which its feed-forward counts as trusted
/// in full, and the pulse share may be earned.
const TRUSTED_BLEND: f64 = 0.9;

crate::counters! {
    /// What the learner did, counted since construction.
    pub struct LearnerCounters {
        /// Frames given to the model (one `observe` call each).
        frames,
        /// Of them learned as observations of the gear error.
        learned,
        /// Not learned: silence, dithers and bumps and the frames settling
        /// after one (passed as unmeasured), and frames the model refused (a bad
        /// observation or time, counted in its `Faults`).
        not_learned,
        /// Dithers the model was told about.
        dithers,
        /// Steps of the star taken out of the observations (`bump`).
        bumps,
    }
}

/// The slow part: the model. Call [`learn`](Self::learn) once per frame
/// from a task of lower priority than the ST4 and stepping task.
pub struct Learner<const N: usize> {
    guider: Guider<f32, N>,
    /// The SNR given to the model with each observation (<= 0: unknown,
    /// the model's default 10): sets the measurement variance.
    pub snr: f32,
    cadence_s: f32,
    last_gear_s: Option<f64>,
    settling: u8,
    share: EarnedShare,
    pulse_weight: PulseWeight,
    feed_forward_weight: FeedForwardWeight,
    /// The model's stages when the feed-forward's weight was last measured
    /// from full.
    weighed_stages: StageWatch<N>,
    bump: Bump,
    counters: LearnerCounters,
}

impl<const N: usize> Learner<N> {
    /// The model with the library's defaults, the worm period of the mount
    /// as its prior period.
    pub fn new(mount: &Mount) -> Self {
        Self::with_config(mount, Self::default_config(mount))
    }

    /// [`new`](Self::new) in place, e.g. into the firmware's static: the
    /// model (~55 KiB) is written where it lives, with no temporary copy on
    /// the stack.
    pub fn init<'a>(slot: &'a mut MaybeUninit<Self>, mount: &Mount) -> &'a mut Self {
        Self::init_with_config(slot, mount, Self::default_config(mount))
    }

    /// The model with another configuration (the control and prediction
    /// gains are not used: the learner only observes).
    pub fn with_config(mount: &Mount, config: GuiderConfig<f32>) -> Self {
        build(|slot| Self::init_with_config(slot, mount, config))
    }

    /// [`new`](Self::new) with some of the `additions` switched off.
    pub fn with_additions(mount: &Mount, additions: Additions) -> Self {
        Self::with_config(
            mount,
            GuiderConfig {
                additions,
                ..Self::default_config(mount)
            },
        )
    }

    /// [`with_config`](Self::with_config) in place.
    pub fn init_with_config<'a>(
        slot: &'a mut MaybeUninit<Self>,
        mount: &Mount,
        config: GuiderConfig<f32>,
    ) -> &'a mut Self {
        init_fields!(slot, Self {
            guider in |f| Guider::init(f, config),
            snr = 0.0,
            cadence_s = mount.config().guide_cadence_s,
            last_gear_s = None,
            settling = 0,
            share = EarnedShare::new(mount.config().least_pulse_share),
            pulse_weight = PulseWeight::FULL,
            feed_forward_weight = FeedForwardWeight::FULL,
            weighed_stages = StageWatch::NEW,
            bump = Bump::NONE,
            counters = LearnerCounters::default(),
        })
    }

    fn default_config(mount: &Mount) -> GuiderConfig<f32> {
        let c = mount.config();
        GuiderConfig {
            prior_period_s: c.worm_period_s as f64,
            // The step rate turns the worm once per configured period.
            worm_period_known: true,
            control_gain: c.guider_aggressiveness,
            // The feed-forward is a rate over the coming interval.
            prediction_at_gear_time: true,
            max_gear_rate: mount.guide_rate_arcsec_per_s() as f64,
            ..GuiderConfig::default()
        }
    }

    pub fn guider(&self) -> &Guider<f32, N> {
        &self.guider
    }

    pub fn counters(&self) -> LearnerCounters {
        self.counters
    }

    /// Forgets what the model learned (asked on the command port): it
    /// starts again from its prior with the next frame. The counters go on.
    pub fn reset(&mut self) {
        self.guider.reset();
        self.last_gear_s = None;
        self.settling = 0;
        self.share.reset();
        self.pulse_weight = PulseWeight::FULL;
        self.weigh_from_full();
        self.bump = Bump::NONE;
    }

    /// The share of the RA guide pulses carried out now (1: in full).
    pub fn pulse_share(&self) -> f32 {
        self.share.fraction()
    }

    /// The part of a guide pulse the model learns as gear error (1: all).
    pub fn pulse_weight(&self) -> f32 {
        self.pulse_weight.weight()
    }

    /// The share of the model's feed-forward applied (1: all).
    pub fn feed_forward_weight(&self) -> f32 {
        self.feed_forward_weight.weight()
    }

    /// The steps of the star measured and taken off every observation so
    /// far, arcsec (`super::guiding::bump`): a dither below the dither
    /// threshold moves the lock by as much, and is in the data unless
    /// this took it.
    pub fn step_level(&self) -> f64 {
        self.bump.level()
    }

    /// Write the learned model, the pulse share and weight into `out` (at
    /// most [`RECORD_MAX`] bytes; store it as [`RECORD_FORMAT`]); returns the
    /// length. Not per frame: it reads a thousand cells. Refused after a
    /// restore until the saved data is placed (`SnapshotError::Placing`):
    /// half a worm period of guiding with the phase unknown (none before
    /// it starts); with only the worm's, a
    /// twentieth or until the new data picks each stage's phase (a quarter
    /// where no stage can be taken apart). Keep the previous save then.
    pub fn snapshot(&self, out: &mut [u8]) -> Result<usize, SnapshotError> {
        let Some((head, model)) = out.split_at_mut_checked(WORM_LEN + SAVED_LEN) else {
            return Err(SnapshotError::BufferTooSmall { needed: RECORD_MAX });
        };
        let n = self.guider.snapshot(model).map_err(|e| match e {
            SnapshotError::BufferTooSmall { needed } => SnapshotError::BufferTooSmall {
                needed: needed + WORM_LEN + SAVED_LEN,
            },
            e => e,
        })?;
        let (worm, share) = head.split_at_mut(WORM_LEN);
        worm.copy_from_slice(&self.configured_worm_s().to_le_bytes());
        let saved = self.share.saved().with_weight(self.pulse_weight.weight());
        share.copy_from_slice(&saved.to_bytes());
        Ok(WORM_LEN + SAVED_LEN + n)
    }

    /// After a power cycle: take the model back from a record's bytes
    /// stored as `format` ([`RECORD_FORMAT`]), checked first: an error
    /// leaves the learner as it was (another format, a cut or garbled
    /// record, values no learning gives, or a record learned under a
    /// configured worm period more than [`WORM_PERIOD_CHANGE`] from this
    /// one: [`SnapshotError::WormPeriod`]).
    /// `phase`: whether the gear's phase carried over (index or park) and
    /// by how much; see [`Phase`]. The saved share is taken up once the
    /// restored model is trusted. Gear time starts again with the next
    /// frame; the counters stay.
    pub fn restore(
        &mut self,
        bytes: &[u8],
        format: u16,
        phase: Phase,
    ) -> Result<(), SnapshotError> {
        if format != RECORD_FORMAT {
            return Err(SnapshotError::Version(format));
        }
        let too_short = SnapshotError::Length {
            expected: RECORD_MAX,
            found: bytes.len(),
        };
        let (worm, rest) = bytes.split_first_chunk::<WORM_LEN>().ok_or(too_short)?;
        let (share, model) = rest.split_at_checked(SAVED_LEN).ok_or(too_short)?;
        let (saved_worm, worm_now) = (f32::from_le_bytes(*worm), self.configured_worm_s());
        if !((saved_worm - worm_now).abs() <= WORM_PERIOD_CHANGE * worm_now) {
            return Err(SnapshotError::WormPeriod);
        }
        let share = SavedShare::parse(share)?;
        let snapshot = Snapshot::parse(model, N)?;
        self.guider.restore(&snapshot, phase)?;
        self.last_gear_s = None;
        self.settling = 0;
        self.weigh_from_full();
        if self.guider.config().additions.saved_share {
            self.share.restore(share);
            self.pulse_weight = PulseWeight::restored(share.weight());
        } else {
            self.share.reset();
            self.pulse_weight = PulseWeight::FULL;
        }
        Ok(())
    }

    /// Whether the model refused the last frame: a bad observation or
    /// frame time, counted in its faults since `before`.
    fn refused_since(&self, before: Faults) -> bool {
        let now = self.guider.faults();
        now.bad_input != before.bad_input || now.bad_time != before.bad_time
    }

    fn count(&mut self, learned: bool) {
        self.counters.frames = self.counters.frames.saturating_add(1);
        if learned {
            self.counters.learned = self.counters.learned.saturating_add(1);
        } else {
            self.counters.not_learned = self.counters.not_learned.saturating_add(1);
        }
    }

    /// The model's feed-forward is trusted and applied in full.
    fn trusted(&self) -> bool {
        self.guider.blend_weight() >= TRUSTED_BLEND
            && self.feed_forward_weight.weight() >= TRUSTED_BLEND as f32
    }

    /// A new model (a reset, a restore): its feed-forward in full until
    /// measured.
    fn weigh_from_full(&mut self) {
        self.feed_forward_weight = FeedForwardWeight::FULL;
        self.weighed_stages = StageWatch::NEW;
    }

    /// The configured worm period, the model's prior (saved with it).
    fn configured_worm_s(&self) -> f32 {
        self.guider.config().prior_period_s as f32
    }

    /// A frame of the port's slew at gear time `t`: nothing to learn, and
    /// no feed-forward (the slew is no gear correction). The model keeps
    /// what it learned and places it before the next frame
    /// (`Guider::jumped`).
    fn moved(&mut self, t: f64) -> FeedForward {
        self.guider.jumped();
        self.bump.interrupt();
        self.feed_forward_weight.interrupt();
        if t.is_finite() {
            self.last_gear_s = Some(t);
        }
        self.count(false);
        FeedForward::NONE
    }

    /// Settle for a dither's frames without learning. Amount 0: gear time
    /// comes from the steps, which already include a dither's
    /// (`crate::mount::guiding`).
    fn settle(&mut self) {
        self.guider.dithered(0.0, 1.0);
        self.settling = DITHER_FRAMES;
    }

    /// Learn one frame and return the feed-forward for the time to the next.
    pub fn learn(&mut self, frame: Frame) -> FeedForward {
        if frame.kind == FrameKind::Moved {
            return self.moved(frame.gear_time_s);
        }
        let t = frame.gear_time_s;
        let d = match self.last_gear_s {
            Some(prev) if t >= prev => t - prev,
            _ => 0.0,
        };
        if t.is_finite() {
            self.last_gear_s = Some(t);
        }
        let cadence = self.cadence_s as f64;
        // Expected time to the next frame: the last interval, within half
        // to twice the cadence (numeric::clamp: core's asserts its bounds
        // and would bring float formatting into the firmware).
        let next = if d > 0.0 {
            clamp(d, 0.5 * cadence, 2.0 * cadence)
        } else {
            cadence
        };
        let observed = match frame.kind {
            FrameKind::Measured => Some(
                self.pulse_weight
                    .observation(frame.applied_arcsec as f64, frame.gear_error_arcsec as f64),
            ),
            _ => None,
        };
        // An observation the model refuses (its measured part not finite or
        // beyond `max_input`) is no guide error for the bump, the earned share
        // or the pulse weight either: a step measured from it would lower
        // every later observation by as much.
        let sane = observed.filter(|o| self.guider.accepts_input(o - frame.applied_arcsec as f64));
        // A pulse far beyond the recent ones: the star stepped. Settle as
        // after a dither and measure the step, trusted model or not (a step
        // learned before the model is trusted stays in its data).
        let adds = self.guider.config().additions;
        let stepped = adds.bump
            && sane.is_some()
            && self.settling == 0
            && self
                .share
                .bound()
                .is_some_and(|b| frame.pulse_arcsec.abs() > bump::BOUNDS * b);
        if stepped {
            self.settle();
            self.bump.start(DITHER_FRAMES);
            self.counters.bumps = self.counters.bumps.saturating_add(1);
        }
        if let FrameKind::Dither { .. } = frame.kind {
            self.settle();
            self.counters.dithers = self.counters.dithers.saturating_add(1);
        }
        // The guider counts its settling frames itself (the dither frame is
        // the first); this mirror only feeds the counters.
        let settling = self.settling > 0;
        if settling {
            self.settling -= 1;
        }
        self.bump.frame(d, sane, !settling);
        let level = self.bump.level();
        let observation = observed.filter(|_| !settling).map(|o| o - level);
        let step = next + 0.5 * d;
        let faults_before = self.guider.faults();
        let change = self.guider.observe(
            t,
            observation,
            frame.applied_arcsec as f64 - level,
            self.snr,
            step as f32,
        );
        self.count(observation.is_some() && !self.refused_since(faults_before));
        // A model whose stages changed predicts another feed-forward.
        if self.weighed_stages.changed(self.guider.periods_s()) {
            self.feed_forward_weight.remeasure();
        }
        // The shadow of the guider alone sees what the guider measured (the
        // pulse in full, less the step the bump took out). It measures the
        // feed-forward while the pulses were carried out in full: a share
        // held back is no part of the feed-forward's effect. Off, the weight
        // stays in full.
        let pulses_in_full = !adds.earned_share || self.share.fraction() >= 1.0;
        match sane.filter(|_| !settling && adds.feed_forward_weight) {
            Some(_) => {
                if adds.weight_by_time {
                    self.feed_forward_weight
                        .frame_interval(d.min(MAX_TIME_STEP_S) as f32);
                }
                self.feed_forward_weight.measured(
                    frame.gear_error_arcsec - level as f32,
                    frame.applied_arcsec - level as f32,
                    self.guider.config().control_gain,
                    self.guider.blend_weight() > 0.0 && pulses_in_full,
                )
            }
            None => self.feed_forward_weight.interrupt(),
        }
        let weight = self.feed_forward_weight.weight() as f64;
        let rate = weight * change as f64 / (next + d);
        let rate = if rate.is_finite() { rate as f32 } else { 0.0 };
        self.bump.installed(rate);
        // A guide frame's pulse (0 when the guider sent none); the others
        // (dithers, settling, silence) are carried out in full.
        let pulse = sane.filter(|_| !settling).map(|_| frame.pulse_arcsec);
        if frame.kind == FrameKind::Calibration && adds.calibration_share {
            self.share.calibrating(if adds.share_to_interval {
                LongerFrames::Scale
            } else {
                LongerFrames::EarnAgain
            });
        }
        let earned = self
            .share
            .frame(pulse, d as f32, self.trusted() || !adds.trusted_gate);
        let pulse_share = if adds.earned_share {
            earned
        } else {
            PulseShare::FULL
        };
        if pulse.is_some() && adds.pulse_weight {
            self.pulse_weight.frame(self.share.swing());
        }
        // In effect for three frames: of the cadence, or of the guider's
        // own spacing where longer, up to the longest step the model
        // predicts over. A guider that skips exposures below its min move
        // spaces the frames by its own measured cadence (`framer`); a
        // horizon from the expected interval above (at most twice the
        // configured cadence) ran out before nearly every frame there
        // (docs/results.md, "The corners of the ranges").
        let spacing = clamp(d, cadence, MAX_TIME_STEP_S.max(cadence));
        let frames = if adds.feed_forward_horizon { 3.0 } else { 1.0 };
        FeedForward {
            rate_arcsec_per_s: rate,
            from_gear_s: t,
            until_gear_s: t + frames * spacing,
            pulse_share: self.pulse_weight.share(pulse_share),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::snapshot::{crc32, Field};
    use crate::mount::config::MountConfig;
    use crate::testing::SplitMix64;

    /// Measured frame `k` of a 2 s cadence: its observation and its pulse.
    fn measured(k: u32, error: f32, pulse: f32) -> Frame {
        Frame {
            gear_time_s: 2.0 * k as f64,
            interval_s: 2.0,
            kind: FrameKind::Measured,
            gear_error_arcsec: error,
            applied_arcsec: 0.0,
            pulse_arcsec: pulse,
            filled: false,
        }
    }

    #[test]
    fn learner_gives_a_finite_feed_forward() {
        let m = MountConfig::default().validate().unwrap();
        let mut l: std::boxed::Box<Learner<1>> = std::boxed::Box::new(Learner::new(&m));
        for k in 0..50 {
            let t = 2.0 * k as f64;
            let ff = l.learn(Frame {
                gear_time_s: t,
                interval_s: if k == 0 { 0.0 } else { 2.0 },
                kind: FrameKind::Measured,
                gear_error_arcsec: (t * 0.01).sin() as f32,
                applied_arcsec: 0.0,
                pulse_arcsec: 0.0,
                filled: false,
            });
            assert!(ff.rate_arcsec_per_s.is_finite());
            assert!(ff.until_gear_s > t);
        }
        l.learn(Frame {
            gear_time_s: 100.0,
            interval_s: 2.0,
            kind: FrameKind::Dither { amount_arcsec: 5.0 },
            gear_error_arcsec: 0.0,
            applied_arcsec: 0.0,
            pulse_arcsec: 5.0,
            filled: false,
        });
        let c = l.counters();
        assert_eq!((c.frames, c.learned, c.dithers), (51, 50, 1));
    }

    #[test]
    fn the_feed_forward_lasts_three_of_the_guiders_frames() {
        let m = MountConfig::default().validate().unwrap();
        let cadence = m.config().guide_cadence_s as f64;
        let mut l: std::boxed::Box<Learner<1>> = std::boxed::Box::new(Learner::new(&m));
        let mut horizon = |t: f64| {
            let ff = l.learn(Frame {
                gear_time_s: t,
                ..measured(0, 0.0, 0.0)
            });
            ff.until_gear_s - t
        };
        assert_eq!(horizon(0.0), 3.0 * cadence);
        // Frames closer than the cadence: still three cadences.
        assert_eq!(horizon(0.5), 3.0 * cadence);
        // A guider that spaces its frames 10 s apart: 30 s.
        assert_eq!(horizon(10.5), 30.0);
        // After a long silence, at most three of the longest steps.
        assert_eq!(horizon(1000.0), 3.0 * MAX_TIME_STEP_S);
    }

    /// A pulse far beyond the recent ones is a step of the star, taken out
    /// before the model has earned any trust too.
    #[test]
    fn a_step_before_trust_is_taken_out() {
        let m = MountConfig::default().validate().unwrap();
        let mut l: std::boxed::Box<Learner<1>> = std::boxed::Box::new(Learner::new(&m));
        let frame = |k: u32, pulse: f32| measured(k, pulse / 0.7, pulse);
        // Small pulses (0.2-0.5 arcsec): their RMS sets the bound, and
        // nothing in them earns the model its trust.
        let small = |k: u32| 0.2 + 0.3 * ((k * 7919) % 13) as f32 / 13.0;
        for k in 0..100 {
            l.learn(frame(k, small(k)));
        }
        assert!(l.guider().blend_weight() < TRUSTED_BLEND);
        assert_eq!(l.counters().bumps, 0);
        l.learn(frame(100, 18.0));
        assert_eq!(l.counters().bumps, 1);
    }

    /// A learner of one stage with the addition `name` switched off.
    fn without(name: &str) -> std::boxed::Box<Learner<1>> {
        let m = MountConfig::default().validate().unwrap();
        let mut config = Learner::<1>::default_config(&m);
        config.additions.set(name, false).unwrap();
        std::boxed::Box::new(Learner::with_config(&m, config))
    }

    /// `n` frames of untrusted small pulses that alternate in sign, in
    /// pairs (`+ + - -`) when `pairs`: neighbours then correlate at 0 and
    /// pulses two apart at -1 (a swing), else neighbours at -1.
    fn alternating(l: &mut Learner<1>, n: u32, pairs: bool) {
        for k in 0..n {
            let sign = if (if pairs { k / 2 } else { k }) % 2 == 0 {
                1.0
            } else {
                -1.0
            };
            l.learn(measured(k, 0.0, 0.3 * sign));
        }
        assert!(l.guider().blend_weight() < TRUSTED_BLEND);
    }

    #[test]
    fn without_the_bump_a_step_is_learned() {
        let mut l = without("bump");
        for k in 0..100 {
            l.learn(measured(k, 0.3, 0.2));
        }
        l.learn(measured(100, 18.0 / 0.7, 18.0));
        assert_eq!((l.counters().bumps, l.counters().not_learned), (0, 0));
    }

    #[test]
    fn without_the_horizon_a_feed_forward_lasts_one_frame() {
        let mut l = without("feed_forward_horizon");
        let ff = l.learn(measured(0, 0.0, 0.0));
        assert_eq!(ff.until_gear_s - ff.from_gear_s, 2.0);
    }

    #[test]
    fn without_the_pulse_weight_a_swing_keeps_every_pulse_learned() {
        let mut on = without("saved_share");
        alternating(&mut on, 300, true);
        assert!(on.pulse_weight() < 1.0, "{}", on.pulse_weight());
        let mut off = without("pulse_weight");
        alternating(&mut off, 300, true);
        assert_eq!(off.pulse_weight(), 1.0);
    }

    #[test]
    fn without_the_trusted_gate_the_share_is_earned_before_trust() {
        let mut on = without("saved_share");
        alternating(&mut on, 300, false);
        assert_eq!(on.pulse_share(), 1.0);
        let mut off = without("trusted_gate");
        alternating(&mut off, 300, false);
        assert!(off.pulse_share() < 0.5, "{}", off.pulse_share());
        // And without the earned share, nothing is earned even so.
        let m = MountConfig::default().validate().unwrap();
        let mut config = Learner::<1>::default_config(&m);
        config.additions.trusted_gate = false;
        config.additions.earned_share = false;
        let mut neither = std::boxed::Box::new(Learner::<1>::with_config(&m, config));
        for k in 0..300 {
            let ff = neither.learn(measured(k, 0.0, if k % 2 == 0 { 0.3 } else { -0.3 }));
            assert_eq!(ff.pulse_share, PulseShare::FULL, "frame {k}");
        }
    }

    /// The share earned from alternating pulses, and the share after a
    /// calibration (its first two steps beyond the recent pulses, 4 RMS,
    /// but within the bump's bound, then the frames of the recognised
    /// calibration) and the guide frame `after`, the addition `name` on or
    /// off.
    fn share_after_calibration(name: &str, on: bool, after: Frame) -> (f32, f32) {
        let m = MountConfig::default().validate().unwrap();
        let mut config = Learner::<1>::default_config(&m);
        config.additions.trusted_gate = false;
        config.additions.set(name, on).unwrap();
        let mut l = std::boxed::Box::new(Learner::<1>::with_config(&m, config));
        alternating(&mut l, 300, false);
        let earned = l.pulse_share();
        for k in 300..302 {
            l.learn(measured(k, 0.0, 2.0));
        }
        for k in 302..310 {
            l.learn(Frame {
                kind: FrameKind::Calibration,
                ..measured(k, 0.0, 2.0)
            });
        }
        l.learn(after);
        (earned, l.pulse_share())
    }

    #[test]
    fn without_the_calibration_share_a_calibration_brings_full_pulses() {
        let after = measured(310, 0.0, -0.3);
        let (earned, on) = share_after_calibration("calibration_share", true, after);
        assert!(earned < 0.5 && (on - earned).abs() < 0.02, "{earned} {on}");
        // Off: full pulses, less what the one plain pulse after earned.
        let (_, off) = share_after_calibration("calibration_share", false, after);
        assert!(off > 0.98, "{off}");
    }

    #[test]
    fn without_share_to_interval_frames_further_apart_after_a_calibration_bring_full_pulses() {
        // Guiding again with frames 4.5 s apart, 2.25 times as far as
        // before the calibration.
        let after = Frame {
            gear_time_s: 2.0 * 309.0 + 4.5,
            interval_s: 4.5,
            ..measured(0, 0.0, -0.3)
        };
        let (earned, on) = share_after_calibration("share_to_interval", true, after);
        assert!(
            earned < 0.5 && (on - 1.5 * earned).abs() < 1e-4,
            "{earned} {on}"
        );
        let (_, off) = share_after_calibration("share_to_interval", false, after);
        assert_eq!(off, 1.0);
    }

    #[test]
    fn without_the_saved_share_a_restored_learner_earns_it_again() {
        let m = MountConfig::default().validate().unwrap();
        let mut a = without("trusted_gate");
        alternating(&mut a, 300, false);
        alternating(&mut a, 300, true);
        let (share, weight) = (a.pulse_share(), a.pulse_weight());
        assert!(share < 1.0 && weight < 1.0, "{share} {weight}");
        let mut bytes = std::vec![0u8; RECORD_MAX];
        let n = a.snapshot(&mut bytes).unwrap();
        let restored = |name: Option<&str>| {
            let mut config = Learner::<1>::default_config(&m);
            if let Some(name) = name {
                config.additions.set(name, false).unwrap();
            }
            let mut b = std::boxed::Box::new(Learner::<1>::with_config(&m, config));
            b.restore(&bytes[..n], RECORD_FORMAT, Phase::Unknown)
                .unwrap();
            (b.pulse_share(), b.pulse_weight())
        };
        assert_eq!(restored(None).1, weight);
        assert!(restored(None).0 < 1.0);
        assert_eq!(restored(Some("saved_share")), (1.0, 1.0));
    }

    /// A closed loop of `frames` frames `frame_s` apart on a worm of 8
    /// arcsec: a proportional guider of the assumed aggressiveness, the
    /// firmware applying `scale` times the feed-forward it is given (a
    /// mount that moves `scale` times what its configuration says).
    /// Returns the feed-forward's weight, the RMS of the guider's measured
    /// error over the last half, and the frame the weight first moved at.
    fn closed_loop(
        l: &mut Learner<1>,
        scale: f64,
        frames: u32,
        frame_s: f64,
    ) -> (f32, f64, Option<u32>) {
        let gear = |t: f64| 8.0 * libm::sin(2.0 * core::f64::consts::PI * t / 478.7);
        let (mut applied, mut rate, mut sum) = (0.0, 0.0, 0.0);
        let mut moved = None;
        for k in 0..frames {
            let t = frame_s * k as f64;
            let pulse = 0.7 * (gear(t) - applied);
            let ff = l.learn(Frame {
                gear_time_s: t,
                interval_s: frame_s as f32,
                gear_error_arcsec: (applied + pulse / 0.7) as f32,
                applied_arcsec: applied as f32,
                ..measured(k, 0.0, pulse as f32)
            });
            if k >= frames / 2 {
                sum += (pulse / 0.7) * (pulse / 0.7);
            }
            if moved.is_none() && l.feed_forward_weight() < 1.0 {
                moved = Some(k);
            }
            applied += pulse + scale * rate * frame_s;
            rate = ff.rate_arcsec_per_s as f64;
        }
        (
            l.feed_forward_weight(),
            libm::sqrt(sum / (frames / 2) as f64),
            moved,
        )
    }

    #[test]
    fn a_feed_forward_that_overshoots_earns_a_part_and_without_the_weight_keeps_all() {
        let m = MountConfig::default().validate().unwrap();
        let mut right: std::boxed::Box<Learner<1>> = std::boxed::Box::new(Learner::new(&m));
        let (weight, good, _) = closed_loop(&mut right, 1.0, 3000, 2.0);
        assert_eq!(weight, 1.0);
        let mut over: std::boxed::Box<Learner<1>> = std::boxed::Box::new(Learner::new(&m));
        let (weight, held, _) = closed_loop(&mut over, 3.0, 3000, 2.0);
        assert!((weight - 1.0 / 3.0).abs() < 0.1, "{weight}");
        let mut off = without("feed_forward_weight");
        let (weight, left, _) = closed_loop(&mut off, 3.0, 3000, 2.0);
        assert_eq!(weight, 1.0);
        assert!(held < left, "{good} {held} {left}");
    }

    #[test]
    fn behind_longer_frames_the_weight_moves_sooner_and_without_weight_by_time_as_late() {
        // The overshooting mount behind 4 s frames: the weight moves after
        // half the scored frames; without the addition, after all of them.
        let m = MountConfig::default().validate().unwrap();
        let mut with: std::boxed::Box<Learner<1>> = std::boxed::Box::new(Learner::new(&m));
        let (_, _, sooner) = closed_loop(&mut with, 3.0, 1500, 4.0);
        let (_, _, later) = closed_loop(&mut without("weight_by_time"), 3.0, 1500, 4.0);
        let (sooner, later) = (sooner.unwrap(), later.unwrap());
        assert_eq!(later - sooner, 100, "{sooner} {later}");
    }

    /// A learner restored from another's bytes holds the same model and
    /// pulse share; bad bytes, another format and a record learned under
    /// another configured worm period are refused and change nothing.
    #[test]
    fn restore_takes_the_model_back_and_refuses_bad_bytes() {
        let m = MountConfig::default().validate().unwrap();
        let mut a: std::boxed::Box<Learner<2>> = std::boxed::Box::new(Learner::new(&m));
        for k in 0..1500 {
            let error = (2.0 * k as f64 * 0.02).sin() as f32;
            // Anti-correlated pulses: a share is earned.
            let pulse = if k % 2 == 0 { 0.2 } else { -0.2 };
            a.learn(measured(k, error, pulse));
        }
        let share = a.pulse_share();
        assert!(share < 0.5, "{share}");
        a.pulse_weight = PulseWeight::restored(0.5);
        let mut bytes = [0u8; RECORD_MAX];
        let n = a.snapshot(&mut bytes).unwrap();
        assert_eq!(
            a.snapshot(&mut [0u8; 8]),
            Err(SnapshotError::BufferTooSmall { needed: RECORD_MAX })
        );
        const HEAD: usize = WORM_LEN + SAVED_LEN;
        let mut b: std::boxed::Box<Learner<2>> = std::boxed::Box::new(Learner::new(&m));
        let unknown = Phase::Unknown;
        // Cut anywhere (in the worm, the share or the model): refused.
        for cut in [0, WORM_LEN - 1, HEAD - 1, HEAD, n - 1] {
            assert!(b.restore(&bytes[..cut], RECORD_FORMAT, unknown).is_err());
        }
        // Garbled in the model, then in the share: refused.
        for at in [100, WORM_LEN + 3] {
            bytes[at] ^= 0x40;
            assert_eq!(
                b.restore(&bytes[..n], RECORD_FORMAT, unknown),
                Err(SnapshotError::Checksum)
            );
            bytes[at] ^= 0x40;
        }
        assert_eq!(
            b.restore(&bytes[..n], 3, unknown),
            Err(SnapshotError::Version(3))
        );
        // The model's snapshot alone read as the record: refused.
        assert!(b.restore(&bytes[HEAD..n], RECORD_FORMAT, unknown).is_err());
        assert_eq!(b.guider().period_s(0), m.config().worm_period_s as f64);
        assert_eq!(b.pulse_share(), 1.0);
        let known = Phase::Known {
            gear_time_offset_s: 1000.0,
        };
        assert_eq!(b.restore(&bytes[..n], RECORD_FORMAT, known), Ok(()));
        assert_eq!(b.pulse_share(), share);
        assert_eq!(b.pulse_weight(), 0.5);
        let mut again = [0u8; RECORD_MAX];
        let n2 = b.snapshot(&mut again).unwrap();
        let (sa, sb) = (
            Snapshot::parse(&bytes[HEAD..n], 2).unwrap(),
            Snapshot::parse(&again[HEAD..n2], 2).unwrap(),
        );
        assert!(sa.cells().eq(sb.cells()));
        assert_eq!((sa.stage(0), sa.stage(1)), (sb.stage(0), sb.stage(1)));
        assert_eq!(bytes[..HEAD], again[..HEAD]);
        // Under a configured worm period 0.5 % off (a corrected figure):
        // restored; 2 % off (another worm): refused, nothing changed.
        let worm = m.config().worm_period_s;
        for (factor, restored) in [(1.005, true), (1.02, false), (0.98, false)] {
            let other = MountConfig {
                worm_period_s: worm * factor,
                ..*m.config()
            };
            let other = other.validate().unwrap();
            let mut c: std::boxed::Box<Learner<2>> = std::boxed::Box::new(Learner::new(&other));
            let r = c.restore(&bytes[..n], RECORD_FORMAT, known);
            if restored {
                assert_eq!(r, Ok(()), "{factor}");
            } else {
                assert_eq!(r, Err(SnapshotError::WormPeriod), "{factor}");
                assert_eq!(c.guider().period_s(0), (worm * factor) as f64);
                assert_eq!(c.pulse_share(), 1.0);
            }
        }
    }

    /// A learner that has learned a worm for an hour, and its record.
    fn learned_record() -> (Mount, std::vec::Vec<u8>) {
        let m = MountConfig::default().validate().unwrap();
        let worm = m.config().worm_period_s as f64;
        let mut a: std::boxed::Box<Learner<2>> = std::boxed::Box::new(Learner::new(&m));
        for k in 0..1800 {
            let t = 2.0 * k as f64;
            let error = 5.0 * (t * core::f64::consts::TAU / worm).sin() + 0.001 * t;
            a.learn(measured(k, error as f32, 0.0));
        }
        let mut bytes = std::vec![0u8; RECORD_MAX];
        let n = a.snapshot(&mut bytes).unwrap();
        bytes.truncate(n);
        (m, bytes)
    }

    /// `record` with its model's cells rewritten by `cell` (index, gear
    /// error) or a stage's period set, and the model's checksum made
    /// right again: only the bounds can refuse it.
    fn rewritten(
        record: &[u8],
        cell: impl Fn(usize, f32) -> f32,
        period: Option<(usize, f64)>,
    ) -> std::vec::Vec<u8> {
        const HEAD: usize = WORM_LEN + SAVED_LEN;
        let mut r = record.to_vec();
        let stages = usize::from(u16::from_le_bytes([r[HEAD + 6], r[HEAD + 7]]));
        let first = HEAD + 20 + 40 * stages;
        let cells = (r.len() - 4 - first) / 8;
        for i in 0..cells {
            let at = first + 8 * i;
            let g = f32::from_le_bytes(r[at..at + 4].try_into().unwrap());
            r[at..at + 4].copy_from_slice(&cell(i, g).to_le_bytes());
        }
        if let Some((s, p)) = period {
            let at = HEAD + 20 + 40 * s;
            r[at..at + 8].copy_from_slice(&p.to_le_bytes());
        }
        let end = r.len() - 4;
        let crc = crc32(&r[HEAD..end]);
        r[end..].copy_from_slice(&crc.to_le_bytes());
        r
    }

    /// A record whose checksums are right but whose values no learning
    /// gives is refused whole: twenty cells at 1e6 arcsec, a period
    /// outside the spectrum's range, cells climbing faster than the mount
    /// can correct. The record as saved is taken.
    #[test]
    fn a_record_with_values_no_learning_gives_is_refused() {
        let (m, record) = learned_record();
        let known = Phase::Known {
            gear_time_offset_s: 0.0,
        };
        let restore = |bytes: &[u8]| {
            let mut l: std::boxed::Box<Learner<2>> = std::boxed::Box::new(Learner::new(&m));
            l.restore(bytes, RECORD_FORMAT, known)
        };
        assert_eq!(restore(&record), Ok(()));
        let spikes = rewritten(
            &record,
            |i, g| if (300..320).contains(&i) { 1e6 } else { g },
            None,
        );
        assert_eq!(
            restore(&spikes),
            Err(SnapshotError::Invalid(Field::CellGear))
        );
        for period in [5.0, 1e5] {
            let r = rewritten(&record, |_, g| g, Some((1, period)));
            assert_eq!(
                restore(&r),
                Err(SnapshotError::Invalid(Field::Period)),
                "{period}"
            );
        }
        // 40 arcsec a cell: each step within two observations' reach, the
        // whole a climb of 8 arcsec/s, beyond the guide rate (7.5).
        let climb = rewritten(&record, |i, g| g + 40.0 * i as f32, None);
        assert_eq!(restore(&climb), Err(SnapshotError::Invalid(Field::Trend)));
        let slower = rewritten(&record, |i, g| g + 30.0 * i as f32, None);
        assert_eq!(restore(&slower), Ok(()));
    }

    /// Observations the model refuses (plus or minus 1e5 arcsec) mixed
    /// with guiding sections at cadences from 0.2 to 60 s, with dithers:
    /// the prediction never beyond what the mount can correct over its
    /// span (the guide rate), and the feed-forward back to the gear's after
    /// a clean section. The refused frames once set the bump's level and
    /// drove the prediction to 24,551 arcsec (seed 11).
    #[test]
    fn refused_observations_at_random_cadences_keep_the_prediction_physical() {
        let m = MountConfig::default().validate().unwrap();
        let guide_rate = m.guide_rate_arcsec_per_s();
        let worm = m.config().worm_period_s as f64;
        let drift = 0.002;
        let mut worst = 0.0f32;
        for seed in 0..16 {
            let mut rng = SplitMix64::new(7 * seed + 1);
            let mut l: std::boxed::Box<Learner<3>> = std::boxed::Box::new(Learner::new(&m));
            let (mut t, mut applied, mut cadence, mut outliers) = (0.0f64, 0.0f64, 2.0, 0);
            let mut ff = FeedForward::NONE;
            for k in 0..5000u32 {
                // A new section every 150 frames or so; the last 500
                // frames a clean one at 2 s.
                let clean = k >= 4500;
                if rng.below(150) == 0 {
                    cadence = rng.f64_in(0.2, 60.0);
                }
                if clean {
                    cadence = 2.0;
                }
                let previous = t;
                t += cadence;
                let gear = 5.0 * (t * core::f64::consts::TAU / worm).sin() + drift * t;
                applied = 0.8 * applied + 0.2 * gear;
                if !clean && outliers == 0 && rng.below(20) == 0 {
                    outliers = 1 + rng.below(30);
                }
                let kind = if rng.below(200) == 0 {
                    FrameKind::Dither { amount_arcsec: 3.0 }
                } else {
                    FrameKind::Measured
                };
                let (error, pulse) = if outliers > 0 {
                    outliers -= 1;
                    let e = if rng.below(2) == 0 { 1e5 } else { -1e5 };
                    (e, 0.7 * e)
                } else {
                    (gear, 0.7 * (gear - applied))
                };
                ff = l.learn(Frame {
                    gear_time_s: t,
                    interval_s: cadence as f32,
                    kind,
                    gear_error_arcsec: error as f32,
                    applied_arcsec: applied as f32,
                    pulse_arcsec: pulse as f32,
                    filled: false,
                });
                // The prediction spans from the previous one's end (at
                // most half this interval back) to the next frame (at most
                // the longest step ahead).
                let span = 0.5 * (t - previous) + MAX_TIME_STEP_S;
                let p = l.guider().prediction();
                assert!(
                    p.abs() <= guide_rate * span as f32,
                    "seed {seed}, frame {k}: {p}"
                );
                assert!(ff.rate_arcsec_per_s.is_finite());
                worst = worst.max(p.abs());
            }
            let gear_rate = 5.0 * core::f64::consts::TAU / worm + drift;
            assert!(
                (ff.rate_arcsec_per_s as f64).abs() < 2.0 * gear_rate,
                "seed {seed}: {ff:?}"
            );
        }
        std::println!("largest prediction {worst} arcsec");
    }

    /// F5 through the learner: an observation the model refuses (beyond
    /// its `max_input`) is counted as not learned, and the feed-forward
    /// stays finite and small.
    #[test]
    fn an_absurd_observation_is_not_learned() {
        let m = MountConfig::default().validate().unwrap();
        let mut l: std::boxed::Box<Learner<1>> = std::boxed::Box::new(Learner::new(&m));
        let frame = |k: u32, error: f32| measured(k, error, 0.0);
        for k in 0..20 {
            l.learn(frame(k, 0.1));
        }
        let ff = l.learn(frame(20, 1e30));
        assert!(ff.rate_arcsec_per_s.abs() < 1.0, "{ff:?}");
        let c = l.counters();
        assert_eq!((c.frames, c.learned, c.not_learned), (21, 20, 1));
        assert_eq!(l.guider().faults().bad_input, 1);
    }

    /// A reset model learns as a new one does: after 400 frames of a worm,
    /// a reset learner and a fresh one give the same feed-forwards.
    #[test]
    fn a_reset_learner_starts_again() {
        let m = MountConfig::default().validate().unwrap();
        let frame = |k: u32| {
            let t = 2.0 * k as f64;
            Frame {
                gear_time_s: t,
                interval_s: if k == 0 { 0.0 } else { 2.0 },
                kind: FrameKind::Measured,
                gear_error_arcsec: (3.0 * (t * core::f64::consts::TAU / 480.0).sin()) as f32,
                applied_arcsec: 0.0,
                pulse_arcsec: 0.0,
                filled: false,
            }
        };
        let mut used: std::boxed::Box<Learner<2>> = std::boxed::Box::new(Learner::new(&m));
        for k in 0..400 {
            used.learn(frame(k));
        }
        let progress = used.guider().learning_progress();
        assert!(progress > 0.0, "{progress}");
        used.reset();
        assert_eq!(used.guider().learning_progress(), 0.0);
        let mut fresh: std::boxed::Box<Learner<2>> = std::boxed::Box::new(Learner::new(&m));
        for k in 0..300 {
            assert_eq!(used.learn(frame(k)), fresh.learn(frame(k)), "frame {k}");
        }
        assert_eq!(used.counters().frames, 700);
    }
}
