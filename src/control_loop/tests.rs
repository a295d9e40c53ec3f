use super::st4_feed::{EdgeQueue, EdgeSource, RawEdge};
use super::*;
use crate::mount::config::MountConfig;
use crate::mount::guiding::FRAME_QUEUE;
use crate::mount::st4::{Axis, Line};
use crate::testing::SplitMix64;
use std::collections::VecDeque;
use std::vec::Vec;

/// Edges handed over at one wake-up, and the queue's state after them.
struct Edges {
    edges: VecDeque<RawEdge>,
    queue: EdgeQueue,
}

impl EdgeSource for Edges {
    fn next_edge(&mut self) -> Option<RawEdge> {
        self.edges.pop_front()
    }
    fn queue(&self) -> EdgeQueue {
        self.queue
    }
}

fn edges(list: &[(Line, bool, u64)]) -> Edges {
    Edges {
        edges: list
            .iter()
            .map(|&(line, asserted, at_us)| RawEdge {
                line,
                asserted,
                at_us,
            })
            .collect(),
        queue: EdgeQueue::default(),
    }
}

fn mount() -> Mount {
    MountConfig::default().validate().unwrap()
}

#[test]
fn starts_tracking_and_wakes_for_the_periodic_update() {
    let m = mount();
    let (lp, rates) = ControlLoop::start(&m, 1_000, 0);
    assert!((rates.ra_steps_per_s - m.sidereal_ra_steps_per_s()).abs() < 1e-3);
    assert_eq!(rates.dec_steps_per_s, 0.0);
    assert_eq!(lp.next_wake_us(), 1_000 + RATE_UPDATE_US);
}

#[test]
fn a_pulse_changes_the_rates_after_the_debounce_and_is_logged() {
    let m = mount();
    let glitch = u64::from(m.config().glitch_us);
    let (mut lp, _) = ControlLoop::start(&m, 0, 0);
    // The assert edge: the start waits for the debounce deadline.
    let w = lp.wake(5_000, 0, &mut edges(&[(Line::DecPlus, true, 5_000)]), None);
    assert!(w.events.is_empty());
    assert_eq!(lp.next_wake_us(), 5_000 + glitch);
    let w = lp.wake(5_000 + glitch, 0, &mut edges(&[]), None);
    assert_eq!(w.events.len(), 1);
    let rates = w.rates.expect("an event sets the rates");
    assert!((rates.dec_steps_per_s - m.guide_dec_steps_per_s()).abs() < 1e-3);
    assert!(w.st4_counters.is_some());
    // The release is confirmed a debounce later too.
    let w = lp.wake(
        200_000,
        0,
        &mut edges(&[(Line::DecPlus, false, 200_000)]),
        None,
    );
    assert!(w.events.is_empty());
    let w = lp.wake(200_000 + glitch, 0, &mut edges(&[]), None);
    assert_eq!(w.events.len(), 1);
    assert_eq!(w.rates.unwrap().dec_steps_per_s, 0.0);
}

#[test]
fn an_edge_stamped_before_the_last_time_is_taken_then() {
    let m = mount();
    let glitch = u64::from(m.config().glitch_us);
    let (mut lp, _) = ControlLoop::start(&m, 0, 0);
    lp.wake(50_000, 0, &mut edges(&[]), None);
    // Stamped 30 ms in the past: fed at 50 ms, so the start is confirmed
    // a debounce after that, not in the past.
    lp.wake(50_000, 0, &mut edges(&[(Line::RaPlus, true, 20_000)]), None);
    assert_eq!(lp.next_wake_us(), 50_000 + glitch);
    assert_eq!(lp.st4_counters().out_of_order, 0);
}

#[test]
fn lost_edges_are_resynchronised_from_the_levels() {
    let m = mount();
    let glitch = u64::from(m.config().glitch_us);
    let (mut lp, _) = ControlLoop::start(&m, 0, 0);
    // The queue lost the assert edge of Dec-: its level says asserted.
    let mut lost = edges(&[]);
    lost.queue = EdgeQueue {
        dropped: 3,
        levels: [false, false, false, true],
    };
    let w = lp.wake(10_000, 0, &mut lost, None);
    assert_eq!(w.lost_edges, 3);
    // The same count again is no new loss.
    let w = lp.wake(10_000 + glitch, 0, &mut lost, None);
    assert_eq!(w.lost_edges, 0);
    assert!(w.rates.unwrap().dec_steps_per_s < 0.0);
}

#[test]
fn a_new_feed_forward_sets_the_rates_at_once() {
    let m = mount();
    let (mut lp, _) = ControlLoop::start(&m, 0, 0);
    let ff = FeedForward {
        rate_arcsec_per_s: 0.5,
        from_gear_s: 0.0,
        until_gear_s: 1e6,
        pulse_share: crate::mount::frame::PulseShare::FULL,
    };
    let w = lp.wake(1_000, 0, &mut edges(&[]), Some(ff));
    let ra = w
        .rates
        .expect("a feed-forward sets the rates")
        .ra_steps_per_s;
    assert!(ra > m.sidereal_ra_steps_per_s());
}

#[test]
fn frames_wait_for_room_and_the_oldest_are_dropped_when_none_comes() {
    let m = mount();
    let (mut lp, _) = ControlLoop::start(&m, 0, 0);
    let mut t = 0;
    let mut ra_steps = 0i64;
    let sps = f64::from(m.sidereal_ra_steps_per_s());
    // Ten RA pulses two seconds apart, frames never taken; then a second
    // more for the last release to be confirmed.
    for k in 0..10u64 {
        let start = 2_000_000 * (k + 1);
        let mut list = Vec::new();
        list.push((Line::RaPlus, true, start));
        list.push((Line::RaPlus, false, start + 100_000));
        for e in list {
            while lp.next_wake_us() < e.2 {
                t = lp.next_wake_us();
                ra_steps = (sps * t as f64 * 1e-6) as i64;
                lp.wake(t, ra_steps, &mut edges(&[]), None);
            }
            t = e.2;
            lp.wake(t, ra_steps, &mut edges(&[e]), None);
        }
    }
    while t < 22_000_000 {
        t = lp.next_wake_us();
        lp.wake(t, ra_steps, &mut edges(&[]), None);
    }
    let c = lp.guiding().counters();
    assert_eq!(c.ra_pulses, 10);
    assert!(c.frames >= 10, "{c:?}");
    assert_eq!(
        c.frames_dropped,
        c.frames - FRAME_QUEUE as u32,
        "only the newest FRAME_QUEUE wait"
    );
    let mut n = 0;
    while let Some(r) = lp.take_frame() {
        assert!(r.guiding.frames >= r.guiding.frames_dropped);
        n += 1;
    }
    assert_eq!(n, FRAME_QUEUE);
}

/// Random edges, times and feed-forwards (NaN and huge ones too): the loop
/// never sets a non-finite rate or one beyond the mount's limits, never asks
/// to wake in the past, and every pulse start it logs is on a real line.
#[test]
fn random_input_keeps_the_rates_in_range() {
    let m = mount();
    let (mut lp, _) = ControlLoop::start(&m, 0, 0);
    let mut rng = SplitMix64::new(1);
    let mut now = 0u64;
    let mut steps = 0i64;
    let mut dropped = 0u32;
    for _ in 0..200_000 {
        now += rng.below(20_000);
        steps += rng.below(400) as i64;
        let mut list = Vec::new();
        for _ in 0..rng.below(4) {
            let line = Line::ALL[rng.below(4) as usize];
            // Mostly in order, sometimes from the past.
            let at = now.saturating_sub(rng.below(3_000));
            list.push((line, rng.below(2) == 0, at));
        }
        let mut src = edges(&list);
        if rng.below(500) == 0 {
            dropped += 1 + rng.below(5) as u32;
        }
        src.queue = EdgeQueue {
            dropped,
            levels: [0, 1, 2, 3].map(|_| rng.below(2) == 0),
        };
        let ff = match rng.below(50) {
            0 => Some(FeedForward {
                rate_arcsec_per_s: f32::NAN,
                from_gear_s: 0.0,
                until_gear_s: 1e9,
                pulse_share: crate::mount::frame::PulseShare::FULL,
            }),
            1 => Some(FeedForward {
                rate_arcsec_per_s: 1e30,
                from_gear_s: 0.0,
                until_gear_s: 1e9,
                pulse_share: crate::mount::frame::PulseShare::FULL,
            }),
            2 => Some(FeedForward {
                rate_arcsec_per_s: rng.below(200) as f32 / 100.0 - 1.0,
                from_gear_s: 0.0,
                until_gear_s: rng.below(100_000) as f64,
                pulse_share: crate::mount::frame::PulseShare {
                    fraction: [f32::NAN, 0.0, 0.1, 0.5, 1.0, 2.0][rng.below(6) as usize],
                    up_to_arcsec: [f32::NAN, -1.0, 0.0, 1.0, 1e30][rng.below(5) as usize],
                },
            }),
            _ => None,
        };
        let w = lp.wake(now, steps, &mut src, ff);
        if let Some(r) = w.rates {
            assert!(r.ra_steps_per_s.is_finite() && r.dec_steps_per_s.is_finite());
            assert!((0.0..=m.max_ra_steps_per_s()).contains(&r.ra_steps_per_s));
            assert!(r.dec_steps_per_s.abs() <= m.max_dec_steps_per_s());
        }
        assert!(lp.next_wake_us() > now.max(1) - 1);
        for ev in &w.events {
            if let crate::mount::st4::St4Event::PulseStart { axis, .. } = *ev {
                assert!(matches!(axis, Axis::Ra | Axis::Dec));
            }
        }
        while rng.below(3) == 0 && lp.take_frame().is_some() {}
    }
}

/// The loop driven as the board drives it: the RA axis's steps emitted
/// tick by tick between wake-ups, edges at their times; returns the RA
/// steps at `until_us`.
fn drive(
    lp: &mut ControlLoop,
    ra: &mut super::stepping::AxisStepper,
    now: &mut u64,
    list: &[(Line, bool, u64)],
    until_us: u64,
) -> i64 {
    let hz = u64::from(ra.tick_hz());
    let mut pending: VecDeque<(Line, bool, u64)> = list.iter().copied().collect();
    while *now < until_us {
        let next_edge = pending.front().map_or(u64::MAX, |e| e.2);
        let t = lp.next_wake_us().min(next_edge).min(until_us).max(*now + 1);
        ra.advance(t * hz / 1_000_000 - *now * hz / 1_000_000);
        *now = t;
        let mut due = Vec::new();
        while pending.front().is_some_and(|e| e.2 <= t) {
            due.push(pending.pop_front().unwrap());
        }
        if let Some(r) = lp.wake(t, ra.steps(), &mut edges(&due), None).rates {
            ra.set_rate(r.ra_steps_per_s);
        }
    }
    ra.steps()
}

/// Under a learner's pulse share, a calibration (PHD2's: RA+ steps of
/// 750 ms, then RA- back, and a 2.5 s step) moves the mount exactly as far
/// as its pulses ask, and so does a dither (5 s); a guide pulse
/// within the share's bound moves it that share. The calibration's pulses
/// after its third (recognised then) are carried out with no share.
#[test]
fn a_calibration_moves_the_mount_exactly_under_a_pulse_share() {
    let m = mount();
    let (mut lp, rates) = ControlLoop::start(&m, 0, 0);
    let mut ra = super::stepping::AxisStepper::new(m.max_ra_steps_per_s(), m.config().step_tick_hz);
    ra.set_rate(rates.ra_steps_per_s);
    let share = crate::mount::frame::PulseShare {
        fraction: 0.3,
        up_to_arcsec: 1.5,
    };
    let ff = FeedForward {
        rate_arcsec_per_s: 0.0,
        from_gear_s: 0.0,
        until_gear_s: 1e9,
        pulse_share: share,
    };
    let w = lp.wake(1_000, 0, &mut edges(&[]), Some(ff));
    ra.set_rate(w.rates.unwrap().ra_steps_per_s);
    let mut now = 1_000;
    let sid = m.sidereal_ra_steps_per_s_f64();
    let guide = f64::from(m.guide_ra_steps_per_s());
    // Steps beyond sidereal tracking at `t`.
    let beyond = |steps: i64, t: u64| steps as f64 - sid * t as f64 * 1e-6;
    let run = |lp: &mut ControlLoop, ra: &mut _, now: &mut u64, line, ms: u64, at: u64| {
        let before = beyond(drive(lp, ra, now, &[], at), at);
        let end = at + ms * 1_000;
        let list = [(line, true, at), (line, false, end)];
        let after = drive(lp, ra, now, &list, end + 2_000_000);
        beyond(after, end + 2_000_000) - before
    };
    let mut t = 2_000_000;
    for (line, ms, sign) in [
        (Line::RaPlus, 750, 1.0),
        (Line::RaPlus, 750, 1.0),
        (Line::RaPlus, 750, 1.0),
        (Line::RaMinus, 750, -1.0),
        (Line::RaMinus, 2_500, -1.0),
        (Line::RaPlus, 5_000, 1.0),
    ] {
        let moved = run(&mut lp, &mut ra, &mut now, line, ms, t);
        let want = sign * guide * ms as f64 * 1e-3;
        assert!((moved - want).abs() <= 1.0, "{ms} ms: {moved} vs {want}");
        t = now + 1_000_000;
    }
    let c = lp.guiding().counters();
    assert_eq!(
        (c.ra_pulses_made_up, c.ra_pulses_held_back, c.calibrations),
        (4, 0, 1),
        "{c:?}"
    );
    // A guide pulse of 100 ms (0.75 arcsec, within 1.5): 0.3 of it.
    let moved = run(&mut lp, &mut ra, &mut now, Line::RaPlus, 100, t);
    let want = 0.3 * guide * 0.1;
    assert!((moved - want).abs() <= 1.0, "{moved} vs {want}");
    assert_eq!(lp.guiding().counters().ra_pulses_held_back, 1);
}
