//! The feed-forward in effect: checked and limited when installed, expired
//! past its horizon, faded out after the guider falls silent.

use super::{GuidingCounters, FADE_FRAMES};
use crate::model::numeric::clamp;
use crate::mount::frame::{FeedForward, PulseShare};

pub(super) struct FeedForwardState {
    installed: FeedForward,
    active: bool,
    /// Faded out completely since the guider was last heard.
    faded: bool,
    /// The guide rate, arcsec/s: the largest feed-forward accepted.
    limit_arcsec_per_s: f32,
    worm_period_us: u64,
    fade_us: u64,
}

impl FeedForwardState {
    pub fn new(limit_arcsec_per_s: f32, worm_period_us: u64, cadence_us: u64) -> Self {
        FeedForwardState {
            installed: FeedForward::NONE,
            active: false,
            faded: false,
            limit_arcsec_per_s,
            worm_period_us,
            fade_us: cadence_us.saturating_mul(FADE_FRAMES as u64).max(1),
        }
    }

    /// The guider was heard: the fade starts over.
    pub fn heard(&mut self) {
        self.faded = false;
    }

    /// Install the learner's newest feed-forward. A non-finite one is
    /// refused (no feed-forward until the next); the rate is limited to the
    /// guide rate.
    pub fn install(&mut self, ff: FeedForward, counters: &mut GuidingCounters) {
        if !(ff.rate_arcsec_per_s.is_finite()
            && ff.from_gear_s.is_finite()
            && ff.until_gear_s.is_finite())
        {
            counters.feed_forward_rejected = counters.feed_forward_rejected.saturating_add(1);
            self.installed = FeedForward::NONE;
            self.active = false;
            return;
        }
        let limit = self.limit_arcsec_per_s;
        let mut ff = ff;
        let share = ff.pulse_share;
        if !(share.fraction > 0.0 && share.fraction <= 1.0 && share.up_to_arcsec >= 0.0) {
            ff.pulse_share = PulseShare::FULL;
        }
        if ff.rate_arcsec_per_s.abs() > limit {
            counters.feed_forward_limited = counters.feed_forward_limited.saturating_add(1);
            ff.rate_arcsec_per_s = clamp(ff.rate_arcsec_per_s, -limit, limit);
        }
        self.installed = ff;
        self.active = true;
    }

    /// Fade factor at `now_us`: 1 until one worm period after the guider
    /// was last heard, then down to 0 over FADE_FRAMES cadences.
    fn fade(&self, now_us: u64, last_heard_us: Option<u64>) -> f32 {
        let Some(last) = last_heard_us else {
            return 1.0;
        };
        let quiet = now_us.saturating_sub(last);
        if quiet <= self.worm_period_us {
            return 1.0;
        }
        let over = (quiet - self.worm_period_us) as f64 / self.fade_us as f64;
        (1.0 - over).max(0.0) as f32
    }

    /// The rate in effect at `now_us`, arcsec/s.
    pub fn rate(&self, now_us: u64, last_heard_us: Option<u64>) -> f32 {
        if !self.active {
            return 0.0;
        }
        self.installed.rate_arcsec_per_s * self.fade(now_us, last_heard_us)
    }

    /// The share of a pulse starting at `now_us`: the installed one while
    /// the feed-forward is in full effect, else full pulses.
    pub fn share(&self, now_us: u64, last_heard_us: Option<u64>) -> PulseShare {
        if self.active && self.fade(now_us, last_heard_us) >= 1.0 {
            self.installed.pulse_share
        } else {
            PulseShare::FULL
        }
    }

    /// Expire past the horizon at gear time `gear_s`, count a complete fade.
    pub fn update(
        &mut self,
        gear_s: f64,
        now_us: u64,
        last_heard_us: Option<u64>,
        counters: &mut GuidingCounters,
    ) {
        if self.active && gear_s > self.installed.until_gear_s {
            self.active = false;
            counters.feed_forward_expired = counters.feed_forward_expired.saturating_add(1);
        }
        let fade = self.fade(now_us, last_heard_us);
        if fade == 0.0 && !self.faded && self.active {
            self.faded = true;
            counters.feed_forward_faded = counters.feed_forward_faded.saturating_add(1);
        }
    }
}
