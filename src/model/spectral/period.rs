//! Period tracking: the tracked period relaxes towards each new spectral
//! estimate, and the smoothed disagreement between the two says how far the
//! prediction can be trusted (docs/reference.md section 2).

/// Weight of a new estimate in the tracked period.
pub const LEARNING_RATE: f64 = 0.01;
/// Weight of a new relative error in the smoothed disagreement.
pub const DISAGREEMENT_SMOOTHING: f64 = 0.1;
/// Disagreement at or below which the period counts as converged.
pub const CONVERGED_REL: f64 = 0.03;
/// Disagreement at or above which the period counts as diverged.
pub const DIVERGED_REL: f64 = 0.45;

/// One stage's period. `f64`: O(1) per frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PeriodTracker {
    /// Tracked period, seconds.
    pub period_s: f64,
    /// Smoothed |P - P_fft| / P_fft; starts fully diverged.
    pub disagreement: f64,
}

impl PeriodTracker {
    pub fn new(period_s: f64) -> Self {
        Self {
            period_s,
            disagreement: 1.0,
        }
    }

    /// Take one spectral estimate (ignored unless finite and positive).
    pub fn observe(&mut self, estimate_s: f64) {
        if !(estimate_s.is_finite() && estimate_s > 0.0) {
            return;
        }
        let rel = (self.period_s - estimate_s).abs() / estimate_s;
        self.disagreement =
            (1.0 - DISAGREEMENT_SMOOTHING) * self.disagreement + DISAGREEMENT_SMOOTHING * rel;
        self.period_s = (1.0 - LEARNING_RATE) * self.period_s + LEARNING_RATE * estimate_s;
    }

    /// 1 when converged, 0 when diverged, linear in between.
    pub fn convergence(&self) -> f64 {
        ((DIVERGED_REL - self.disagreement) / (DIVERGED_REL - CONVERGED_REL)).clamp(0.0, 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn converges_towards_a_steady_estimate() {
        let mut t = PeriodTracker::new(300.0);
        assert_eq!(t.convergence(), 0.0);
        for _ in 0..2000 {
            t.observe(432.0);
        }
        assert!((t.period_s - 432.0).abs() < 0.01);
        assert_eq!(t.convergence(), 1.0);
    }

    #[test]
    fn ignores_bad_estimates() {
        let mut t = PeriodTracker::new(300.0);
        t.observe(f64::NAN);
        t.observe(-5.0);
        t.observe(0.0);
        assert_eq!(t, PeriodTracker::new(300.0));
    }

    #[test]
    fn convergence_is_linear_between_thresholds() {
        let mut t = PeriodTracker::new(300.0);
        t.disagreement = 0.5 * (CONVERGED_REL + DIVERGED_REL);
        assert!((t.convergence() - 0.5).abs() < 1e-12);
    }
}
