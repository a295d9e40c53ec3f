//! Is the firmware still working? The guiding task asks at every wake-up
//! and feeds the independent watchdog only on [`Verdict::Feed`]: a hung
//! guiding task stops asking, and the watchdog resets the board. A part that
//! stalls while the guiding task still runs is named ([`Verdict::Stalled`]),
//! and the caller takes the fault path with that name, so the next boot can
//! say which part it was.

use crate::safety::fault_record::Part;

/// The liveness is judged this often, µs.
pub const CHECK_EVERY_US: u64 = 100_000;
/// The learner may hold frames this long without finishing one before it
/// counts as stalled, µs. A frame takes tens of milliseconds even when the
/// spectrum runs; ten seconds is a hang, not a slow frame.
pub const LEARNER_STALL_US: u64 = 10_000_000;

/// What the caller reads from the running firmware.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Progress {
    /// Step ticks so far (wrapping).
    pub step_ticks: u32,
    /// Frames the learner has finished (wrapping).
    pub frames_learned: u32,
    /// Frames are queued for the learner.
    pub frames_waiting: bool,
    /// Flash operations begun and ended (wrapping; odd while one runs). A
    /// sector erase stalls every flash read, the step tick's and this
    /// check's included, for up to 2 s: across one, progress is not
    /// judged (the watchdog, above the longest erase, still is).
    pub flash_operations: u32,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// Not time to judge yet.
    Wait,
    /// Everything progressed: feed the watchdog.
    Feed,
    /// This part stopped: take the fault path.
    Stalled(Part),
}

/// The judge, with what it saw last.
#[derive(Clone, Debug)]
pub struct Liveness {
    tick_hz: u32,
    last_check_us: u64,
    last_ticks: u32,
    frames_learned: u32,
    learner_idle_since_us: u64,
    flash_operations: u32,
}

impl Liveness {
    /// Starts judging at `now_us`, with the step tick at `tick_hz`.
    pub fn new(tick_hz: u32, now_us: u64, progress: Progress) -> Self {
        Liveness {
            tick_hz,
            last_check_us: now_us,
            last_ticks: progress.step_ticks,
            frames_learned: progress.frames_learned,
            learner_idle_since_us: now_us,
            flash_operations: progress.flash_operations,
        }
    }

    /// When the next judgement is due, µs.
    pub fn next_check_us(&self) -> u64 {
        self.last_check_us.saturating_add(CHECK_EVERY_US)
    }

    /// Judges the progress at `now_us`.
    pub fn check(&mut self, now_us: u64, progress: Progress) -> Verdict {
        if now_us < self.next_check_us() {
            return Verdict::Wait;
        }
        if progress.flash_operations != self.flash_operations || progress.flash_operations % 2 == 1
        {
            // A flash operation ran since the last check or runs now: judge
            // again from here.
            *self = Liveness::new(self.tick_hz, now_us, progress);
            return Verdict::Wait;
        }
        let elapsed_us = now_us - self.last_check_us;
        let ticks = u64::from(progress.step_ticks.wrapping_sub(self.last_ticks));
        // Half the ticks due: a tick lost now and then to a long critical
        // section is not a stall; a stopped or starved tick is.
        let due = u64::from(self.tick_hz).saturating_mul(elapsed_us) / 1_000_000;
        self.last_check_us = now_us;
        self.last_ticks = progress.step_ticks;
        if ticks.saturating_mul(2) < due {
            return Verdict::Stalled(Part::StepTick);
        }
        if progress.frames_learned != self.frames_learned || !progress.frames_waiting {
            self.frames_learned = progress.frames_learned;
            self.learner_idle_since_us = now_us;
        } else if now_us - self.learner_idle_since_us >= LEARNER_STALL_US {
            return Verdict::Stalled(Part::Learner);
        }
        Verdict::Feed
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const HZ: u32 = 50_000;

    /// Runs `checks` judgements 100 ms apart with the progress `step` gives
    /// for each; returns the verdicts.
    fn run(checks: usize, mut step: impl FnMut(usize) -> Progress) -> Vec<Verdict> {
        let mut l = Liveness::new(HZ, 0, step(0));
        (1..=checks)
            .map(|i| l.check(i as u64 * CHECK_EVERY_US, step(i)))
            .collect()
    }

    fn ticking(i: usize) -> u32 {
        (i as u64 * 5_000) as u32
    }

    #[test]
    fn a_healthy_board_is_fed_every_check() {
        let v = run(1000, |i| Progress {
            step_ticks: ticking(i),
            frames_learned: (i / 20) as u32,
            frames_waiting: i % 20 != 0,
            ..Progress::default()
        });
        assert!(v.iter().all(|&v| v == Verdict::Feed));
    }

    #[test]
    fn nothing_is_judged_between_checks() {
        let mut l = Liveness::new(HZ, 0, Progress::default());
        assert_eq!(
            l.check(CHECK_EVERY_US - 1, Progress::default()),
            Verdict::Wait
        );
        assert_eq!(l.next_check_us(), CHECK_EVERY_US);
    }

    #[test]
    fn a_stopped_step_tick_is_named_at_the_next_check() {
        let v = run(10, |i| Progress {
            step_ticks: ticking(i.min(4)),
            ..Progress::default()
        });
        assert_eq!(v[..4], [Verdict::Feed; 4]);
        assert_eq!(v[4], Verdict::Stalled(Part::StepTick));
    }

    #[test]
    fn a_starved_step_tick_is_a_stall_a_few_lost_ticks_are_not() {
        let slow = run(5, |i| Progress {
            step_ticks: (i as u32) * 2_400,
            ..Progress::default()
        });
        assert!(slow.iter().all(|&v| v == Verdict::Stalled(Part::StepTick)));
        let lossy = run(5, |i| Progress {
            step_ticks: (i as u32) * 4_900,
            ..Progress::default()
        });
        assert!(lossy.iter().all(|&v| v == Verdict::Feed));
    }

    /// Across a flash operation (a sector erase stalls the step tick for
    /// up to 2 s) nothing is judged and nothing fed; the check after it
    /// judges from there, and a stall after it is still caught.
    #[test]
    fn a_flash_operation_is_not_a_stall() {
        let mut l = Liveness::new(HZ, 0, Progress::default());
        let at = |ticks: u32, ops: u32| Progress {
            step_ticks: ticks,
            flash_operations: ops,
            ..Progress::default()
        };
        assert_eq!(l.check(CHECK_EVERY_US, at(5_000, 0)), Verdict::Feed);
        // Begun: the next checks wait; 2 s of stalled ticks pass unjudged.
        assert_eq!(l.check(2 * CHECK_EVERY_US, at(10_000, 1)), Verdict::Wait);
        assert_eq!(l.check(22 * CHECK_EVERY_US, at(10_002, 2)), Verdict::Wait);
        assert_eq!(l.check(23 * CHECK_EVERY_US, at(15_002, 2)), Verdict::Feed);
        assert_eq!(
            l.check(24 * CHECK_EVERY_US, at(15_002, 2)),
            Verdict::Stalled(Part::StepTick)
        );
    }

    #[test]
    fn the_tick_counter_may_wrap() {
        let v = run(10, |i| Progress {
            step_ticks: u32::MAX - 20_000 + ticking(i),
            ..Progress::default()
        });
        assert!(v.iter().all(|&v| v == Verdict::Feed));
    }

    #[test]
    fn a_learner_stuck_on_waiting_frames_is_named_after_the_stall_time() {
        let per_s = (1_000_000 / CHECK_EVERY_US) as usize;
        let stuck_from = 30;
        let v = run(300, |i| Progress {
            step_ticks: ticking(i),
            frames_learned: i.min(stuck_from) as u32,
            frames_waiting: true,
            ..Progress::default()
        });
        let first = v.iter().position(|&v| v != Verdict::Feed);
        assert_eq!(first, Some(stuck_from - 1 + 10 * per_s));
        assert_eq!(v[first.unwrap()], Verdict::Stalled(Part::Learner));
    }

    #[test]
    fn an_idle_learner_with_nothing_to_do_is_alive() {
        let v = run(300, |i| Progress {
            step_ticks: ticking(i),
            frames_learned: 3,
            frames_waiting: false,
            ..Progress::default()
        });
        assert!(v.iter().all(|&v| v == Verdict::Feed));
    }
}
