//! An edge storm on an ST4 line (a loose cable, a ground loop, a noisy
//! camera port) must not starve the guiding task, which ends pulses and
//! enforces the cap. Each line gets an edge budget; a line that spends it
//! within one window has its interrupt masked and counts as released (noise
//! is no guide pulse), and the guiding task polls it until its level has
//! held still for [`STORM_QUIET_US`], then unmasks it.
//!
//! The interrupt asks [`StormGuard::on_edge`] before it queues an edge; the
//! guiding task calls [`StormGuard::poll`] for each masked line at every
//! wake-up. Both run the same small, bounded code; the interrupt's work is
//! thus at most [`STORM_EDGES`] edges per line per [`STORM_WINDOW_US`].

use crate::mount::st4::Line;

/// Edges a line may make per window before it is masked. Contact bounce is
/// a few dozen edges within a millisecond; guide pulses are a few edges per
/// second.
pub const STORM_EDGES: u32 = 64;
/// The budget's window, µs.
pub const STORM_WINDOW_US: u64 = 10_000;
/// A masked line is unmasked once its level has held this long, µs.
pub const STORM_QUIET_US: u64 = 200_000;

#[derive(Clone, Copy, Debug)]
struct Budget {
    window_start_us: u64,
    edges: u32,
    masked: bool,
    /// While masked: the level polled last and since when it holds.
    level: bool,
    level_since_us: u64,
}

impl Budget {
    /// A fresh budget, its window starting at `at_us`.
    const fn fresh(at_us: u64) -> Self {
        Budget {
            window_start_us: at_us,
            edges: 0,
            masked: false,
            level: false,
            level_since_us: 0,
        }
    }
}

/// The per-line edge budgets and the storms they caught.
#[derive(Clone, Debug)]
pub struct StormGuard {
    lines: [Budget; 4],
    storms: u32,
}

impl Default for StormGuard {
    fn default() -> Self {
        Self::new()
    }
}

impl StormGuard {
    pub const fn new() -> Self {
        StormGuard {
            lines: [Budget::fresh(0); 4],
            storms: 0,
        }
    }

    /// An edge interrupt of `line` at `at_us`: `true` to queue the edge;
    /// `false` when the line has just spent its budget (the storm is
    /// counted): mask its interrupt and report it released.
    pub fn on_edge(&mut self, line: Line, at_us: u64) -> bool {
        let b = &mut self.lines[line.index()];
        if b.masked {
            return false;
        }
        if at_us.saturating_sub(b.window_start_us) >= STORM_WINDOW_US || at_us < b.window_start_us {
            b.window_start_us = at_us;
            b.edges = 0;
        }
        b.edges += 1;
        if b.edges <= STORM_EDGES {
            return true;
        }
        b.masked = true;
        b.level_since_us = at_us;
        self.storms = self.storms.saturating_add(1);
        false
    }

    /// `line` is masked.
    pub fn is_masked(&self, line: Line) -> bool {
        self.lines[line.index()].masked
    }

    /// A masked `line` polled at `now_us` with its `level`: `true` when it
    /// has held still long enough to unmask (it is unmasked here, with a
    /// fresh budget).
    pub fn poll(&mut self, line: Line, now_us: u64, level: bool) -> bool {
        let b = &mut self.lines[line.index()];
        if !b.masked {
            return false;
        }
        if level != b.level {
            b.level = level;
            b.level_since_us = now_us;
            return false;
        }
        if now_us.saturating_sub(b.level_since_us) < STORM_QUIET_US {
            return false;
        }
        *b = Budget::fresh(now_us);
        true
    }

    /// Storms caught since start.
    pub fn storms(&self) -> u32 {
        self.storms
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::SplitMix64 as Rng;

    #[test]
    fn guide_pulses_and_contact_bounce_stay_unmasked() {
        let mut g = StormGuard::new();
        let mut t = 0u64;
        for _ in 0..1_000 {
            // 40 edges of bounce within 1 ms, then the pulse's end 500 ms on.
            for k in 0..40 {
                assert!(g.on_edge(Line::RaPlus, t + k * 25));
            }
            t += 500_000;
            assert!(g.on_edge(Line::RaPlus, t));
            t += 1_500_000;
        }
        assert_eq!(g.storms(), 0);
    }

    #[test]
    fn a_storm_is_masked_at_its_budget_and_unmasked_after_the_quiet() {
        let mut g = StormGuard::new();
        // 100 kHz of edges on Dec-.
        let mut t = 1_000u64;
        let mut queued = 0;
        while g.on_edge(Line::DecMinus, t) {
            queued += 1;
            t += 10;
        }
        assert_eq!(queued, STORM_EDGES);
        assert!(g.is_masked(Line::DecMinus) && !g.is_masked(Line::DecPlus));
        assert_eq!(g.storms(), 1);
        // Still storming: polls see the level change and keep it masked.
        for k in 0..100 {
            assert!(!g.poll(Line::DecMinus, t + k * 10_000, k % 2 == 0));
        }
        t += 100 * 10_000;
        // Quiet from here: unmasked after STORM_QUIET_US.
        let mut unmasked_at = None;
        for k in 0..100 {
            let now = t + k * 10_000;
            if g.poll(Line::DecMinus, now, true) {
                unmasked_at = Some(now - t);
                break;
            }
        }
        let after = unmasked_at.expect("unmasked");
        assert!(
            (STORM_QUIET_US..STORM_QUIET_US + 20_000).contains(&after),
            "{after}"
        );
        assert!(!g.is_masked(Line::DecMinus));
        assert_eq!(g.storms(), 1);
    }

    /// Whatever the edges, a line never queues more than its budget per
    /// window plus one window's worth at the boundary, and a masked line
    /// queues nothing.
    #[test]
    fn random_edges_never_exceed_the_budget() {
        let mut rng = Rng::new(3);
        let mut g = StormGuard::new();
        let mut t = 0u64;
        let mut queued: [Vec<u64>; 4] = Default::default();
        // Storms on one line at a time, between ordinary edges on all four
        // and long silences.
        let mut storm: Option<Line> = None;
        for _ in 0..2_000_000 {
            if rng.below(2_000) == 0 {
                storm = match storm {
                    Some(_) => None,
                    None => Some(Line::ALL[rng.below(4) as usize]),
                };
            }
            let gap = match (storm, rng.below(100)) {
                (Some(_), _) => 10,
                (None, 0) => 50_000,
                (None, _) => 400,
            };
            t += rng.below(gap);
            let line = storm.unwrap_or(Line::ALL[rng.below(4) as usize]);
            if rng.below(50) == 0 {
                g.poll(line, t, rng.below(2) == 0);
            } else if g.on_edge(line, t) {
                queued[line.index()].push(t);
            }
        }
        for q in &queued {
            for (i, &start) in q.iter().enumerate() {
                let in_window = q[i..]
                    .iter()
                    .take_while(|&&u| u < start + STORM_WINDOW_US)
                    .count();
                assert!(
                    in_window as u32 <= 2 * STORM_EDGES,
                    "{in_window} edges in a window"
                );
            }
        }
        assert!(g.storms() > 0);
    }
}
