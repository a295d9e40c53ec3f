//! Randomized tests of the safety properties, from the one test RNG
//! (`mkgp_mount::testing::SplitMix64`, fixed seeds). Their size suits CI;
//! `MKGP_RANDOMIZED_SCALE=K` multiplies the iteration counts by K for a
//! longer run (host-tests/README.md).

use mkgp_mount::mount::st4::{Axis, Line, St4, St4Counters, St4Event};
use mkgp_mount::testing::SplitMix64;

/// The iteration multiplier from `MKGP_RANDOMIZED_SCALE` (default 1).
fn scale() -> u64 {
    std::env::var("MKGP_RANDOMIZED_SCALE")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1)
        .max(1)
}

/// Edges of distinct lines at one instant, then a poll at that instant or
/// not.
struct Instant {
    at_us: u64,
    edges: Vec<(Line, bool)>,
    poll: bool,
}

/// A random history of ST4 edges on a coarse time grid, so that edges,
/// confirmations (`glitch_us` a multiple of the grid) and cuts at the cap
/// often fall on the same microsecond.
fn random_history(rng: &mut SplitMix64, quantum: u64) -> Vec<Instant> {
    let mut at_us = 0;
    (0..60)
        .map(|_| {
            at_us += quantum * rng.below(12);
            let mut lines = Line::ALL.to_vec();
            let n = 1 + rng.below(4) as usize;
            let edges = (0..n)
                .map(|_| {
                    let line = lines.remove(rng.below(lines.len() as u64) as usize);
                    (line, rng.below(2) == 1)
                })
                .collect();
            Instant {
                at_us,
                edges,
                poll: rng.below(2) == 1,
            }
        })
        .collect()
}

/// Runs a history, the edges of each instant in the order `order` gives,
/// and returns the events of each axis and the counters. (Events of the two
/// axes at the same microsecond may come in either order: each axis' pulses
/// are applied on their own.)
fn run(
    st4: &mut St4,
    history: &[Instant],
    mut order: impl FnMut(&mut Vec<(Line, bool)>),
) -> ([Vec<St4Event>; 2], St4Counters) {
    let mut events = Vec::new();
    let mut drain = |st4: &mut St4, now| {
        while let Some(ev) = st4.poll(now) {
            events.push(ev);
        }
    };
    for instant in history {
        let mut edges = instant.edges.clone();
        order(&mut edges);
        for (line, asserted) in edges {
            st4.edge(line, asserted, instant.at_us);
        }
        if instant.poll {
            drain(st4, instant.at_us);
        }
    }
    let end = history.last().map_or(0, |i| i.at_us);
    drain(st4, end + 100_000_000);
    let of_axis = |axis| {
        events
            .iter()
            .filter(|ev| match ev {
                St4Event::PulseStart { axis: a, .. } | St4Event::PulseEnd { axis: a, .. } => {
                    *a == axis
                }
            })
            .copied()
            .collect()
    };
    ([of_axis(Axis::Ra), of_axis(Axis::Dec)], st4.counters())
}

/// F7: each axis' events and the counters of the ST4 state machine do not depend
/// on the order in which edges of the same microsecond arrive (once cut at
/// the cap or normal end depended on it). Every history is run in its own
/// order and in four shuffled ones.
#[test]
fn st4_same_instant_edges_in_any_order() {
    let mut rng = SplitMix64::new(7);
    const QUANTUM: u64 = 1_000;
    for history_no in 0..300 * scale() {
        let glitch_us = QUANTUM * rng.below(3);
        let glitch_us = glitch_us.max(QUANTUM) as u32;
        let cap_us = (QUANTUM * (5 + rng.below(20))) as u32;
        let history = random_history(&mut rng, QUANTUM);
        let reference = run(&mut St4::new(glitch_us, cap_us), &history, |_| {});
        for _ in 0..4 {
            let shuffled = run(&mut St4::new(glitch_us, cap_us), &history, |edges| {
                for i in (1..edges.len()).rev() {
                    edges.swap(i, rng.below(i as u64 + 1) as usize);
                }
            });
            assert_eq!(shuffled, reference, "history {history_no}");
        }
    }
}
