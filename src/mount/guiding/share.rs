//! Carrying out a share of an RA guide pulse, and making up what was held
//! back once the pulse turns out longer than a reaction to noise.
//!
//! A pulse runs at `fraction` of the guide rate for its first `held_us`
//! (`up_to_arcsec` of correction). If it lasts longer it is no reaction to
//! noise (a bump, a calibration step, a dither): from then on it runs at
//! `1 + make_up` times the guide rate until what was held back is made
//! up, then at the guide rate; if it ends first, the guide rate goes on
//! after its end until it is made up. Such a pulse moves the mount exactly
//! as far as it asked. A pulse no longer than `held_us` moves it
//! `fraction` of that. The time of each change is a deadline of the loop
//! ([`SharedPulse::next_change_us`]), so the steps come out exact.

use crate::mount::frame::PulseShare;
use crate::mount::st4::Direction;

#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct SharedPulse {
    sign: f32,
    start_us: u64,
    fraction: f32,
    held_us: u64,
    /// Extra guide rate while making up, as a multiple of it.
    make_up: f32,
    /// Elapsed time at which the making up is done within the pulse.
    made_up_us: u64,
    end_us: Option<u64>,
    /// After the end: the guide rate runs on until this time.
    on_until_us: u64,
}

/// Elapsed µs at which a pulse held back for its first `held_us` has
/// made it up at `1 + make_up` times the guide rate (`u64::MAX`: never).
fn made_up_at(fraction: f32, held_us: u64, make_up: f32) -> u64 {
    if make_up <= 0.0 {
        return u64::MAX;
    }
    let held = (1.0 - fraction) as f64 * held_us as f64 / make_up as f64;
    held_us.saturating_add(libm::ceil(held) as u64)
}

impl SharedPulse {
    /// A pulse in `direction` from `start_us` under `share`, the guide rate
    /// `guide_arcsec_per_s` and a `make_up` (> 0) that keeps the RA rate in
    /// range. `None`: the pulse is carried out in full.
    pub fn start(
        direction: Direction,
        start_us: u64,
        share: PulseShare,
        guide_arcsec_per_s: f32,
        make_up: f32,
    ) -> Option<Self> {
        let f = share.fraction;
        if !(f > 0.0 && f < 1.0 && guide_arcsec_per_s > 0.0 && make_up > 0.0) {
            return None;
        }
        let held_s = share.up_to_arcsec / guide_arcsec_per_s;
        if !(held_s > 0.0 && held_s < 60.0) {
            return None;
        }
        let held_us = (held_s * 1e6) as u64;
        Some(SharedPulse {
            sign: direction.sign(),
            start_us,
            fraction: f,
            held_us,
            make_up,
            made_up_us: made_up_at(f, held_us, make_up),
            end_us: None,
            on_until_us: 0,
        })
    }

    /// Guide-rate µs carried out `elapsed` µs into the pulse.
    fn done_us(&self, elapsed: u64) -> f64 {
        let f = self.fraction as f64;
        if elapsed <= self.held_us {
            return f * elapsed as f64;
        }
        let over = (elapsed - self.held_us) as f64;
        let done = f * self.held_us as f64 + (1.0 + self.make_up as f64) * over;
        done.min(elapsed as f64)
    }

    /// The pulse ended at `at_us`; returns whether the guide rate runs on
    /// after it.
    pub fn end(&mut self, at_us: u64) -> bool {
        let elapsed = at_us.saturating_sub(self.start_us);
        self.end_us = Some(at_us);
        if elapsed <= self.held_us {
            return false;
        }
        let owed = elapsed as f64 - self.done_us(elapsed);
        self.on_until_us = at_us.saturating_add(libm::ceil(owed.max(0.0)) as u64);
        self.on_until_us > at_us
    }

    /// Whether the pulse was held back (it ended no longer than the held
    /// part).
    pub fn held_back(&self) -> bool {
        self.end_us
            .is_some_and(|end| end.saturating_sub(self.start_us) <= self.held_us)
    }

    /// Signed multiple of the guide rate at `now_us`.
    pub fn guide(&self, now_us: u64) -> f32 {
        let m = match self.end_us {
            Some(_) if now_us < self.on_until_us => 1.0,
            Some(_) => 0.0,
            None => {
                let elapsed = now_us.saturating_sub(self.start_us);
                if elapsed < self.held_us {
                    self.fraction
                } else if elapsed < self.made_up_us {
                    1.0 + self.make_up
                } else {
                    1.0
                }
            }
        };
        self.sign * m
    }

    /// Whether it still moves the mount after `now_us`.
    pub fn running(&self, now_us: u64) -> bool {
        self.end_us.is_none() || now_us < self.on_until_us
    }

    /// The next time its rate changes, after `now_us` (the end of a
    /// running pulse is the guider's).
    pub fn next_change_us(&self, now_us: u64) -> Option<u64> {
        let t = match self.end_us {
            Some(_) => self.on_until_us,
            None => {
                let held = self.start_us.saturating_add(self.held_us);
                if now_us < held {
                    held
                } else {
                    self.start_us.saturating_add(self.made_up_us)
                }
            }
        };
        (t > now_us).then_some(t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SHARE: PulseShare = PulseShare {
        fraction: 0.25,
        up_to_arcsec: 1.0,
    };

    /// Guide-rate µs carried out from `start` to `until` (exact: the rate
    /// is constant between changes).
    fn carried(p: &mut SharedPulse, end_us: u64, until_us: u64) -> f64 {
        let mut t = 0;
        let mut done = 0.0;
        let mut ended = false;
        while t < until_us {
            let mut next = p.next_change_us(t).unwrap_or(until_us).min(until_us);
            if !ended {
                next = next.min(end_us);
            }
            done += p.guide(t) as f64 * (next - t) as f64;
            t = next;
            if t == end_us && !ended {
                p.end(t);
                ended = true;
            }
        }
        done
    }

    #[test]
    fn a_short_pulse_is_held_back_and_a_long_one_made_up() {
        // 1 arcsec at 10 arcsec/s: held back for 100 ms.
        let start = |make_up| {
            SharedPulse::start(Direction::Plus, 0, SHARE, 10.0, make_up).expect("held back")
        };
        let mut p = start(1.0);
        assert!((carried(&mut p, 80_000, 1_000_000) - 20_000.0).abs() < 1.0);
        assert!(p.held_back());
        // Long enough to make up within: 100 ms at 0.25, then 75 ms at 2x.
        let mut p = start(1.0);
        assert!((carried(&mut p, 750_000, 2_000_000) - 750_000.0).abs() < 2.0);
        assert!(!p.held_back());
        // Ends while making up: the guide rate runs on after the end.
        for make_up in [1.0, 0.5, 0.01] {
            let mut p = start(make_up);
            let done = carried(&mut p, 120_000, 10_000_000);
            assert!((done - 120_000.0).abs() < 2.0, "{make_up}: {done}");
        }
        // RA-: the same, negative.
        let mut p = SharedPulse::start(Direction::Minus, 0, SHARE, 10.0, 0.5).unwrap();
        assert!((carried(&mut p, 750_000, 2_000_000) + 750_000.0).abs() < 2.0);
        // Full pulses need no share.
        for share in [
            PulseShare::FULL,
            PulseShare {
                fraction: f32::NAN,
                ..SHARE
            },
            PulseShare {
                up_to_arcsec: f32::INFINITY,
                ..SHARE
            },
        ] {
            assert!(SharedPulse::start(Direction::Plus, 0, share, 10.0, 1.0).is_none());
        }
    }
}
