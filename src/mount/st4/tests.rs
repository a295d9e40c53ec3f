use super::*;
use crate::testing::SplitMix64;
use Axis::*;
use Direction::*;
use Line::*;
use St4Event::*;

const G: u64 = 1_000;
const CAP: u64 = 10_000_000;

fn st4() -> St4 {
    St4::new(G as u32, CAP as u32)
}

fn drain(s: &mut St4, now: u64) -> ([Option<St4Event>; 20], usize) {
    let mut out = [None; 20];
    let mut n = 0;
    while let Some(ev) = s.poll(now) {
        assert!(n < 20, "too many events");
        out[n] = Some(ev);
        n += 1;
    }
    (out, n)
}

fn one(s: &mut St4, now: u64) -> Option<St4Event> {
    let (out, n) = drain(s, now);
    assert!(n <= 1, "{:?}", &out[..n]);
    out[0]
}

#[test]
fn a_clean_pulse() {
    let mut s = st4();
    assert_eq!(s.next_deadline_us(), None);
    s.edge(RaPlus, true, 5_000);
    assert_eq!(s.next_deadline_us(), Some(5_000 + G));
    assert_eq!(one(&mut s, 5_999), None);
    assert_eq!(
        one(&mut s, 6_000),
        Some(PulseStart {
            axis: Ra,
            direction: Plus,
            at_us: 5_000
        })
    );
    assert_eq!(s.active_pulse(Ra), Some((Plus, 5_000)));
    assert_eq!(s.next_deadline_us(), Some(5_000 + CAP));
    s.edge(RaPlus, false, 505_000);
    assert_eq!(one(&mut s, 505_500), None);
    assert_eq!(
        one(&mut s, 506_000),
        Some(PulseEnd {
            axis: Ra,
            at_us: 505_000
        })
    );
    assert_eq!(s.next_deadline_us(), None);
    assert_eq!(s.counters(), St4Counters::default());
    // Dec- the same way.
    s.edge(DecMinus, true, 1_000_000);
    s.edge(DecMinus, false, 1_200_000);
    let (out, n) = drain(&mut s, 1_300_000);
    assert_eq!(n, 2);
    assert_eq!(
        out[0],
        Some(PulseStart {
            axis: Dec,
            direction: Minus,
            at_us: 1_000_000
        })
    );
    assert_eq!(
        out[1],
        Some(PulseEnd {
            axis: Dec,
            at_us: 1_200_000
        })
    );
}

#[test]
fn contact_bounce_then_a_clean_assert() {
    let mut s = st4();
    for (lvl, t) in [(true, 0), (false, 100), (true, 250), (false, 400)] {
        s.edge(DecPlus, lvl, t);
        assert_eq!(one(&mut s, t), None);
    }
    s.edge(DecPlus, true, 600);
    assert_eq!(one(&mut s, 1_599), None);
    assert_eq!(
        one(&mut s, 1_600),
        Some(PulseStart {
            axis: Dec,
            direction: Plus,
            at_us: 600
        })
    );
    assert_eq!(s.counters().glitches, 2);
    // Bounce on release: a dropout inside the pulse is a glitch too.
    s.edge(DecPlus, false, 300_000);
    s.edge(DecPlus, true, 300_050);
    s.edge(DecPlus, false, 300_200);
    assert_eq!(one(&mut s, 301_199), None);
    assert_eq!(
        one(&mut s, 301_200),
        Some(PulseEnd {
            axis: Dec,
            at_us: 300_200
        })
    );
    assert_eq!(s.counters().glitches, 3);
    assert_eq!(s.active_pulse(Dec), None);
}

#[test]
fn a_glitch_alone_is_ignored() {
    let mut s = st4();
    s.edge(RaMinus, true, 10_000);
    s.edge(RaMinus, false, 10_999);
    assert_eq!(s.next_deadline_us(), None);
    assert_eq!(one(&mut s, 100_000_000), None);
    assert_eq!(
        s.counters(),
        St4Counters {
            glitches: 1,
            ..St4Counters::default()
        }
    );
    // Exactly glitch_us is a pulse.
    s.edge(RaMinus, true, 200_000_000);
    s.edge(RaMinus, false, 200_001_000);
    let (_, n) = drain(&mut s, 300_000_000);
    assert_eq!(n, 2);
}

#[test]
fn both_lines_stop_the_axis_until_both_are_released() {
    let mut s = st4();
    s.edge(RaPlus, true, 0);
    assert!(matches!(one(&mut s, G), Some(PulseStart { .. })));
    s.edge(RaMinus, true, 50_000);
    assert_eq!(
        one(&mut s, 51_000),
        Some(PulseEnd {
            axis: Ra,
            at_us: 50_000
        })
    );
    assert_eq!(s.counters().both_lines, 1);
    // Dec still works meanwhile.
    s.edge(DecPlus, true, 60_000);
    s.edge(DecPlus, false, 70_000);
    assert_eq!(drain(&mut s, 80_000).1, 2);
    // One released, then re-asserted: still the same episode.
    s.edge(RaPlus, false, 100_000);
    s.edge(RaPlus, true, 200_000);
    s.edge(RaPlus, false, 300_000);
    assert_eq!(one(&mut s, 400_000), None);
    assert_eq!(s.counters().both_lines, 1);
    // Both released: a new pulse is accepted.
    s.edge(RaMinus, false, 500_000);
    assert_eq!(one(&mut s, 600_000), None);
    s.edge(RaMinus, true, 700_000);
    assert_eq!(
        one(&mut s, 701_000),
        Some(PulseStart {
            axis: Ra,
            direction: Minus,
            at_us: 700_000
        })
    );
    // Both at once from idle: no pulse at all, counted.
    let mut s = st4();
    s.edge(DecPlus, true, 0);
    s.edge(DecMinus, true, 10);
    let (out, n) = drain(&mut s, 5_000);
    // Dec+ was confirmed first (at 1000), then Dec- ended it.
    assert_eq!(n, 2, "{:?}", &out[..n]);
    assert_eq!(
        out[1],
        Some(PulseEnd {
            axis: Dec,
            at_us: 10
        })
    );
    assert_eq!(s.counters().both_lines, 1);
    let mut s = st4();
    s.edge(DecPlus, true, 0);
    s.edge(DecMinus, true, 0);
    let (out, n) = drain(&mut s, 5_000);
    assert_eq!(n, 2, "{:?}", &out[..n]);
    assert_eq!(
        out[1],
        Some(PulseEnd {
            axis: Dec,
            at_us: 0
        })
    );
}

#[test]
fn a_stuck_line_is_cut_at_the_cap_and_counted_once() {
    let mut s = st4();
    s.edge(RaPlus, true, 1_000);
    assert!(matches!(one(&mut s, 2_000), Some(PulseStart { .. })));
    assert_eq!(s.next_deadline_us(), Some(1_000 + CAP));
    assert_eq!(one(&mut s, CAP), None);
    assert_eq!(
        one(&mut s, 1_000 + CAP),
        Some(PulseEnd {
            axis: Ra,
            at_us: 1_000 + CAP
        })
    );
    let c = s.counters();
    assert_eq!((c.capped, c.stuck), (1, 1));
    assert_eq!(s.next_deadline_us(), None);
    // Stays asserted for an hour: nothing more, counted once.
    for k in 1..100u64 {
        assert_eq!(one(&mut s, k * 36_000_000), None);
    }
    let c = s.counters();
    assert_eq!((c.capped, c.stuck), (1, 1));
    // Its release makes no event; the next pulse is normal.
    s.edge(RaPlus, false, 4_000_000_000);
    assert_eq!(one(&mut s, 4_001_000_000), None);
    s.edge(RaPlus, true, 4_002_000_000);
    s.edge(RaPlus, false, 4_002_500_000);
    assert_eq!(drain(&mut s, 4_003_000_000).1, 2);
    assert_eq!(s.counters().capped, 1);
}

#[test]
fn the_cap() {
    // Exactly the cap: a normal end.
    let mut s = st4();
    s.edge(DecMinus, true, 0);
    s.edge(DecMinus, false, CAP);
    let (out, n) = drain(&mut s, CAP + G);
    assert_eq!(n, 2);
    assert_eq!(
        out[1],
        Some(PulseEnd {
            axis: Dec,
            at_us: CAP
        })
    );
    assert_eq!(s.counters().capped, 0);
    // A release just before the cap, still being debounced when the cap
    // comes: the pulse ends at the release, not at the cap.
    let mut s = st4();
    s.edge(DecMinus, true, 0);
    assert_eq!(drain(&mut s, G).1, 1);
    s.edge(DecMinus, false, CAP - 10);
    assert_eq!(one(&mut s, CAP), None);
    assert_eq!(one(&mut s, CAP + 500), None);
    assert_eq!(
        one(&mut s, CAP - 10 + G),
        Some(PulseEnd {
            axis: Dec,
            at_us: CAP - 10
        })
    );
    assert_eq!(s.counters().capped, 0);
    // ... unless it was a dropout: then the cut comes at the cap.
    let mut s = st4();
    s.edge(DecMinus, true, 0);
    assert_eq!(drain(&mut s, G).1, 1);
    s.edge(DecMinus, false, CAP - 10);
    assert_eq!(one(&mut s, CAP + 100), None);
    s.edge(DecMinus, true, CAP + 200);
    assert_eq!(
        one(&mut s, CAP + 200),
        Some(PulseEnd {
            axis: Dec,
            at_us: CAP
        })
    );
    assert_eq!(s.counters().capped, 1);
    assert_eq!(s.counters().glitches, 1);
    // Not polled for a long time: start and cut come together, in order.
    let mut s = st4();
    s.edge(RaMinus, true, 7);
    let (out, n) = drain(&mut s, 3 * CAP);
    assert_eq!(n, 2);
    assert!(matches!(out[0], Some(PulseStart { at_us: 7, .. })));
    assert_eq!(
        out[1],
        Some(PulseEnd {
            axis: Ra,
            at_us: 7 + CAP
        })
    );
}

#[test]
fn out_of_order_edges_are_ignored_and_counted() {
    let mut s = st4();
    s.edge(RaPlus, true, 50_000);
    s.edge(DecPlus, true, 40_000);
    assert_eq!(s.counters().out_of_order, 1);
    assert!(!s.is_asserted(DecPlus));
    // Equal times are fine.
    s.edge(DecMinus, true, 50_000);
    assert_eq!(s.counters().out_of_order, 1);
    let (_, n) = drain(&mut s, 60_000);
    assert_eq!(n, 2);
    // A poll back in time changes nothing.
    assert_eq!(one(&mut s, 0), None);
    s.edge(RaPlus, false, 70_000);
    assert_eq!(one(&mut s, 65_000), None);
    assert!(matches!(
        one(&mut s, 71_000),
        Some(PulseEnd { axis: Ra, .. })
    ));
    // An edge delivered late (older than the last poll, not older than
    // the last edge) takes effect at the time of that poll.
    s.edge(DecMinus, false, 70_500);
    assert_eq!(s.counters().out_of_order, 1);
    assert_eq!(one(&mut s, 71_999), None, "confirmed at 72_000, not before");
    assert_eq!(
        one(&mut s, 72_000),
        Some(PulseEnd {
            axis: Dec,
            at_us: 71_000
        })
    );
    // A repeated level is ignored.
    s.edge(DecMinus, false, 80_000);
    assert_eq!(s.next_deadline_us(), None);
    assert_eq!(s.counters().out_of_order, 1);
}

#[test]
fn a_full_queue_drops_the_oldest() {
    let mut s = st4();
    // 10 Dec pulses without polling: 20 events, 16 kept.
    for k in 0..10u64 {
        s.edge(DecPlus, true, k * 10_000);
        s.edge(DecPlus, false, k * 10_000 + 5_000);
    }
    let (out, n) = drain(&mut s, 1_000_000);
    assert_eq!(n, ST4_QUEUE_LEN);
    assert_eq!(s.counters().dropped, 4);
    // The first two pulses went; the third pulse's start comes first.
    assert!(matches!(out[0], Some(PulseStart { at_us: 20_000, .. })));
    assert_eq!(
        out[ST4_QUEUE_LEN - 1],
        Some(PulseEnd {
            axis: Dec,
            at_us: 95_000
        })
    );
    assert_eq!(one(&mut s, 2_000_000), None);
}

#[test]
fn zero_glitch_confirms_at_once() {
    let mut s = St4::new(0, CAP as u32);
    s.edge(RaMinus, true, 10);
    assert!(matches!(s.poll(10), Some(PulseStart { at_us: 10, .. })));
    s.edge(RaMinus, false, 11);
    assert_eq!(
        s.poll(11),
        Some(PulseEnd {
            axis: Ra,
            at_us: 11
        })
    );
    assert_eq!(s.counters(), St4Counters::default());
}

/// On the 64-bit host; the queue's two indices are half as wide on the
/// target.
#[test]
fn size() {
    assert_eq!(core::mem::size_of::<St4Event>(), 16);
    assert_eq!(core::mem::size_of::<St4>(), 432);
}

/// Random edges and polls: never panics; per axis the events alternate
/// start/end with non-decreasing times and each pulse lasts at most the
/// cap.
#[test]
fn random_edges_keep_the_invariants() {
    let mut rng = SplitMix64::new(1);
    for glitch in [0u32, 1_000] {
        let mut s = St4::new(glitch, 20_000);
        let mut t = 0u64;
        let mut open: [Option<u64>; 2] = [None, None];
        let mut last: [u64; 2] = [0, 0];
        for _ in 0..200_000 {
            let r = rng.next_u64();
            t += r % 3_000;
            let line = [RaPlus, RaMinus, DecPlus, DecMinus][(r >> 20) as usize % 4];
            let back = if (r >> 30).is_multiple_of(50) {
                5_000
            } else {
                0
            };
            s.edge(line, (r >> 24) & 1 == 1, t.saturating_sub(back));
            if (r >> 40).is_multiple_of(3) {
                let now = t + (r >> 44) % 2_000;
                while let Some(ev) = s.poll(now) {
                    match ev {
                        PulseStart { axis, at_us, .. } => {
                            let i = axis as usize;
                            assert!(open[i].is_none());
                            assert!(at_us >= last[i]);
                            open[i] = Some(at_us);
                            last[i] = at_us;
                        }
                        PulseEnd { axis, at_us } => {
                            let i = axis as usize;
                            let start = open[i].take().unwrap();
                            assert!(at_us >= start && at_us - start <= 20_000);
                            last[i] = at_us;
                        }
                    }
                }
            }
        }
        let c = s.counters();
        assert_eq!(c.dropped, 0);
        assert!(c.out_of_order > 0 && c.both_lines > 0 && c.capped > 0);
        if glitch > 0 {
            assert!(c.glitches > 0);
        }
    }
}

/// A pulse of exactly the cap ends normally whatever edge of another line
/// comes at the same microsecond before its release: the cut at that
/// instant waits for a poll, so the counters do not depend on the order of
/// simultaneous edges.
#[test]
fn a_pulse_of_exactly_the_cap_ends_normally_whatever_comes_first() {
    for first in [None, Some(RaPlus), Some(RaMinus), Some(DecPlus)] {
        let mut s = st4();
        s.edge(DecMinus, true, 0);
        assert_eq!(drain(&mut s, G).1, 1);
        if let Some(line) = first {
            s.edge(line, true, CAP);
        }
        s.edge(DecMinus, false, CAP);
        let (out, n) = drain(&mut s, CAP + G);
        let end = PulseEnd {
            axis: Dec,
            at_us: CAP,
        };
        assert!(out[..n].contains(&Some(end)), "{first:?}: {:?}", &out[..n]);
        let c = s.counters();
        assert_eq!((c.capped, c.stuck), (0, 0), "{first:?}");
    }
}
