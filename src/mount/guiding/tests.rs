use super::*;
use crate::mount::config::MountConfig;
use crate::mount::frame::FrameKind;

fn mount() -> Mount {
    MountConfig::default().validate().unwrap()
}

fn start(dir: Direction, at_us: u64) -> St4Event {
    St4Event::PulseStart {
        axis: Axis::Ra,
        direction: dir,
        at_us,
    }
}

fn end(at_us: u64) -> St4Event {
    St4Event::PulseEnd {
        axis: Axis::Ra,
        at_us,
    }
}

/// Drive `g` with the steps its own rates make, every `step_us`, up to
/// `until_us`; returns the step position (fractional).
fn track(g: &mut Guiding, from_us: u64, until_us: u64, pos: &mut f64) -> Rates {
    let mut t = from_us;
    let mut r = g.rates(t, pos.floor() as i64);
    while t < until_us {
        let next = (t + 10_000).min(until_us);
        *pos += r.ra_steps_per_s as f64 * (next - t) as f64 * 1e-6;
        t = next;
        r = g.rates(t, pos.floor() as i64);
    }
    r
}

#[test]
fn rates_follow_pulses() {
    let m = mount();
    let mut g = Guiding::new(&m);
    let sid = m.sidereal_ra_steps_per_s();
    let guide = m.guide_ra_steps_per_s();
    assert!((g.rates(0, 0).ra_steps_per_s - sid).abs() < 1e-3);
    g.on_event(start(Direction::Plus, 1_000));
    let r = g.rates(2_000, 0);
    assert!((r.ra_steps_per_s - (sid + guide)).abs() < 1e-3);
    g.on_event(end(101_000));
    g.on_event(start(Direction::Minus, 200_000));
    let r = g.rates(201_000, 30);
    assert!((r.ra_steps_per_s - (sid - guide)).abs() < 1e-3);
    g.on_event(St4Event::PulseStart {
        axis: Axis::Dec,
        direction: Direction::Minus,
        at_us: 201_000,
    });
    let r = g.rates(202_000, 30);
    assert!((r.dec_steps_per_s + m.guide_dec_steps_per_s()).abs() < 1e-3);
    assert_eq!(g.counters().ra_pulses, 2);
    assert_eq!(g.counters().dec_pulses, 1);
}

#[test]
fn feed_forward_is_checked_and_limited() {
    let m = mount();
    let mut g = Guiding::new(&m);
    g.rates(0, 0);
    g.set_feed_forward(FeedForward {
        rate_arcsec_per_s: f32::NAN,
        from_gear_s: 0.0,
        until_gear_s: 10.0,
        pulse_share: crate::mount::frame::PulseShare::FULL,
    });
    assert_eq!(g.counters().feed_forward_rejected, 1);
    let r = g.rates(1_000, 0);
    assert!((r.ra_steps_per_s - m.sidereal_ra_steps_per_s()).abs() < 1e-3);
    g.set_feed_forward(FeedForward {
        rate_arcsec_per_s: -1e9,
        from_gear_s: 0.0,
        until_gear_s: 10.0,
        pulse_share: crate::mount::frame::PulseShare::FULL,
    });
    assert_eq!(g.counters().feed_forward_limited, 1);
    g.on_event(start(Direction::Minus, 2_000));
    // Sidereal - guide - guide rate of feed-forward: 0 at 0.5x, never below.
    let r = g.rates(3_000, 0);
    assert!(r.ra_steps_per_s >= 0.0 && r.ra_steps_per_s <= m.max_ra_steps_per_s());
    assert!(r.ra_steps_per_s < 1e-3, "{}", r.ra_steps_per_s);
    // Expired after until_gear_s.
    let mut pos = 0.0;
    g.on_event(end(4_000));
    let r = track(&mut g, 4_000, 25_000_000, &mut pos);
    assert_eq!(g.counters().feed_forward_expired, 1);
    assert!((r.ra_steps_per_s - m.sidereal_ra_steps_per_s()).abs() < 1e-3);
}

#[test]
fn a_pulse_makes_an_observation() {
    let m = mount();
    let mut g = Guiding::new(&m);
    let mut pos = 0.0;
    track(&mut g, 0, 2_000_000, &mut pos);
    g.on_event(start(Direction::Plus, 2_000_000));
    track(&mut g, 2_000_000, 2_400_000, &mut pos);
    g.on_event(end(2_400_000));
    let f = g.take_frame().expect("a frame");
    assert_eq!(f.kind, FrameKind::Measured);
    let want = 0.4 * m.guide_rate_arcsec_per_s();
    assert!((f.pulse_arcsec - want).abs() < 1e-4, "{f:?}");
    // Nothing but tracking before the pulse: C = 0 within a step.
    assert!(f.applied_arcsec.abs() < m.arcsec_per_ra_step(), "{f:?}");
    let obs = f.applied_arcsec + want / 0.7;
    assert!((f.gear_error_arcsec - obs).abs() < 1e-4);
    assert!((f.gear_time_s - 2.0).abs() < 0.01, "{f:?}");
    assert!(g.take_frame().is_none());
    // The next frame's applied correction is the mean of C over the
    // interval: the pulse's 0.4 s x guide rate ramp, then constant.
    track(&mut g, 2_400_000, 4_000_000, &mut pos);
    g.on_event(start(Direction::Minus, 4_000_000));
    g.on_event(end(4_100_000));
    let f = g.take_frame().expect("a frame");
    let c = want as f64;
    let mean = (0.5 * c * 0.4 + c * 1.6) / 2.0;
    assert!(
        (f.applied_arcsec as f64 - mean).abs() < 2.0 * m.arcsec_per_ra_step() as f64,
        "{f:?} vs {mean}"
    );
    // Gear time runs with the steps: the 0.4 s RA+ pulse at 0.5x moved
    // the worm 0.2 s ahead.
    assert!((f.interval_s - 2.2).abs() < 0.01, "{f:?}");
    assert!((f.gear_time_s - 4.2).abs() < 0.01, "{f:?}");
}

#[test]
fn silence_fills_then_freezes_then_fades() {
    let m = mount();
    let cfg = m.config();
    let mut g = Guiding::new(&m);
    let mut pos = 0.0;
    track(&mut g, 0, 1_000_000, &mut pos);
    g.on_event(start(Direction::Plus, 1_000_000));
    g.on_event(end(1_050_000));
    g.set_feed_forward(FeedForward {
        rate_arcsec_per_s: 0.5,
        from_gear_s: 1.0,
        until_gear_s: 1e9,
        pulse_share: crate::mount::frame::PulseShare::FULL,
    });
    // Up to just before one worm period after the pulse (its end, the
    // last the guider was heard): full feed-forward.
    let worm_us = (cfg.worm_period_s as f64 * 1e6) as u64;
    track(&mut g, 1_050_000, 1_050_000 + worm_us - 10_000, &mut pos);
    assert_eq!(g.feed_forward_now(), 0.5);
    let mut kinds = [0u32; 3];
    while let Some(f) = g.take_frame() {
        match f.kind {
            FrameKind::Measured => kinds[0] += 1,
            FrameKind::Unmeasured | FrameKind::Moved | FrameKind::Calibration => kinds[1] += 1,
            FrameKind::Dither { .. } => kinds[2] += 1,
        }
    }
    // One pulse frame and fills every cadence; only the first
    // silence_frames fills are measured (the queue keeps the last 4).
    let c = g.counters();
    assert_eq!(c.silences, 1);
    assert!(c.filled_frames > cfg.silence_frames);
    assert_eq!(c.unmeasured_frames, c.filled_frames - cfg.silence_frames);
    assert!(g.silent());
    // Then faded out within FADE_FRAMES cadences.
    let fade_us = (FADE_FRAMES as f64 * cfg.guide_cadence_s as f64 * 1e6) as u64;
    let r = track(
        &mut g,
        1_050_000 + worm_us - 10_000,
        1_050_000 + worm_us + fade_us + 20_000,
        &mut pos,
    );
    assert_eq!(g.feed_forward_now(), 0.0);
    assert_eq!(g.counters().feed_forward_faded, 1);
    assert!((r.ra_steps_per_s - m.sidereal_ra_steps_per_s()).abs() < 1e-3);
    // A pulse brings it back and ends the silence.
    let t = 1_050_000 + worm_us + fade_us + 20_000;
    g.on_event(start(Direction::Plus, t));
    assert!(!g.silent());
    assert_eq!(g.feed_forward_now(), 0.5);
    assert_eq!(kinds[2], 0);
}

#[test]
fn a_long_pulse_is_a_dither() {
    let m = mount();
    let mut g = Guiding::new(&m);
    let mut pos = 0.0;
    track(&mut g, 0, 1_000_000, &mut pos);
    g.on_event(start(Direction::Minus, 1_000_000));
    track(&mut g, 1_000_000, 5_000_000, &mut pos);
    g.on_event(end(5_000_000));
    let f = g.take_frame().unwrap();
    let amount = -4.0 * m.guide_rate_arcsec_per_s();
    assert_eq!(
        f.kind,
        FrameKind::Dither {
            amount_arcsec: amount
        }
    );
    assert_eq!(g.counters().dithers, 1);
    // The dither's move is not gear error: C is back near 0.
    track(&mut g, 5_000_000, 6_000_000, &mut pos);
    assert!(g.applied_arcsec().abs() < 2.0 * m.arcsec_per_ra_step() as f64);
}

/// RA pulses of 100 ms at `starts_s`; returns the filled frames counted.
fn fills_with_pulses_at(starts_s: &[f64]) -> u32 {
    let m = mount();
    let mut g = Guiding::new(&m);
    let mut pos = 0.0;
    let mut t = 0;
    for &s in starts_s {
        let at = (s * 1e6) as u64;
        track(&mut g, t, at, &mut pos);
        g.on_event(start(Direction::Plus, at));
        track(&mut g, at, at + 100_000, &mut pos);
        g.on_event(end(at + 100_000));
        t = at + 100_000;
        while g.take_frame().is_some() {}
    }
    g.counters().filled_frames
}

#[test]
fn frames_are_filled_at_the_guiders_own_cadence() {
    // The configured cadence is 2 s. A guider exposing 8 s: after the
    // three intervals that measure it, no frame is filled between its
    // pulses (before: three per exposure, each claiming no error).
    assert_eq!(MountConfig::default().guide_cadence_s, 2.0);
    let slow: std::vec::Vec<f64> = (0..20).map(|k| 8.0 * k as f64).collect();
    assert_eq!(fills_with_pulses_at(&slow), 3 * 3);
    // A 2 s guider that skips every other exposure (below its minimum
    // move) keeps the configured cadence: the skipped exposures are filled.
    let skipping: std::vec::Vec<f64> = (0..20)
        .map(|k| 6.0 * (k / 2) as f64 + 2.0 * (k % 2) as f64)
        .collect();
    assert_eq!(fills_with_pulses_at(&skipping), 9);
}

#[test]
fn pulses_back_to_back_freeze_learning_and_the_feed_forward() {
    let m = mount();
    let mut g = Guiding::new(&m);
    let mut pos = 0.0;
    track(&mut g, 0, 1_000_000, &mut pos);
    g.set_feed_forward(FeedForward {
        rate_arcsec_per_s: 0.5,
        from_gear_s: 0.0,
        until_gear_s: 1e9,
        pulse_share: crate::mount::frame::PulseShare::FULL,
    });
    // A pulse of about `on_us` every 2 s, `n` times from `t` (lengths that
    // differ: equal ones would be a calibration's): the kinds of the frames
    // they made, and the feed-forward at the end.
    let mut pulses = |g: &mut Guiding, t: &mut u64, on_us: u64, n: u32| {
        let mut kinds = std::vec::Vec::new();
        for k in 0..n {
            let on_us = on_us - u64::from(k % 3) * 5_000;
            g.on_event(start(Direction::Plus, *t));
            track(g, *t, *t + on_us, &mut pos);
            g.on_event(end(*t + on_us));
            track(g, *t + on_us, *t + 2_000_000, &mut pos);
            *t += 2_000_000;
            while let Some(f) = g.take_frame() {
                kinds.push(f.kind);
            }
        }
        (kinds, g.feed_forward_now())
    };
    let mut t = 1_000_000;
    let n = framer::BACKLOG_PULSES as u32;
    // Pulses that fit in their cycle: measured, the feed-forward in full.
    let (kinds, ff) = pulses(&mut g, &mut t, 500_000, 2 * n);
    assert!(kinds.iter().all(|k| *k == FrameKind::Measured), "{kinds:?}");
    assert_eq!(ff, 0.5);
    // A bump's few long pulses do not freeze anything.
    let (kinds, _) = pulses(&mut g, &mut t, 1_990_000, n - 1);
    assert!(kinds.iter().all(|k| *k == FrameKind::Measured), "{kinds:?}");
    assert_eq!(g.counters().backlogs, 0);
    // Sustained, they do: unmeasured frames, no feed-forward.
    let (kinds, ff) = pulses(&mut g, &mut t, 1_990_000, n);
    assert_eq!(g.counters().backlogs, 1);
    assert_eq!(kinds.last(), Some(&FrameKind::Unmeasured));
    assert_eq!(ff, 0.0);
    // Pulses that fit again: learning and the feed-forward resume.
    let (kinds, ff) = pulses(&mut g, &mut t, 500_000, n + 1);
    assert_eq!(kinds.last(), Some(&FrameKind::Measured));
    assert_eq!(ff, 0.5);
    assert_eq!(g.counters().backlogs, 1);
}

/// Five equal 750 ms RA pulses, one every 2 s (a calibration's west leg):
/// recognised from the third, its frames not learned; with the watch
/// switched off (`Additions::calibration_watch`), guide frames.
#[test]
fn a_calibrations_frames_are_not_learned_unless_the_watch_is_off() {
    let m = mount();
    let kinds = |additions: crate::model::additions::Additions| {
        let mut g = Guiding::with_additions(&m, additions);
        let mut pos = 0.0;
        let mut kinds = std::vec::Vec::new();
        for k in 0..5u64 {
            let t = 1_000_000 + k * 2_000_000;
            track(&mut g, t.saturating_sub(1_000_000), t, &mut pos);
            g.on_event(start(Direction::Plus, t));
            track(&mut g, t, t + 750_000, &mut pos);
            g.on_event(end(t + 750_000));
            while let Some(f) = g.take_frame() {
                kinds.push(f.kind);
            }
        }
        (kinds, g.counters().calibrations)
    };
    let (on, recognised) = kinds(crate::model::additions::Additions::ALL);
    assert_eq!(recognised, 1);
    assert_eq!(on.first(), Some(&FrameKind::Measured));
    assert_eq!(on.last(), Some(&FrameKind::Calibration), "{on:?}");
    let mut without = crate::model::additions::Additions::ALL;
    without.calibration_watch = false;
    let (off, recognised) = kinds(without);
    assert_eq!(recognised, 0);
    assert!(off.iter().all(|k| *k == FrameKind::Measured), "{off:?}");
}
