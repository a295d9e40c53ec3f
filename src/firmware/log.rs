//! The defmt log lines. defmt-rtt holds a critical section while it
//! encodes a line (the step tick waits meanwhile), so the lines are kept
//! short: at most six values each.

use mkgp_mount::control_loop::{FrameRecord, Wake};
use mkgp_mount::mount::config::{ConfigError, Value};
use mkgp_mount::mount::frame::{FeedForward, FrameKind};
use mkgp_mount::mount::learner::Learner;
use mkgp_mount::mount::st4::{Axis, Direction, St4Counters, St4Event};

use crate::firmware::guiding_task::{storms, ST4_COUNTERS};
use crate::firmware::port_io::LINKS;
use crate::firmware::step_tick::{rates_set, step_counts};
use crate::STAGES;

fn axis_name(axis: Axis) -> &'static str {
    match axis {
        Axis::Ra => "RA",
        Axis::Dec => "Dec",
    }
}

fn event(ev: &St4Event) {
    match *ev {
        St4Event::PulseStart {
            axis,
            direction,
            at_us,
        } => defmt::info!(
            "ST4 pulse start {} {} at {} us",
            axis_name(axis),
            match direction {
                Direction::Plus => "+",
                Direction::Minus => "-",
            },
            at_us
        ),
        St4Event::PulseEnd { axis, at_us } => {
            defmt::info!("ST4 pulse end {} at {} us", axis_name(axis), at_us)
        }
    }
}

pub fn counters(c: St4Counters) {
    defmt::info!(
        "ST4 counters: glitches {}, both lines {}, capped {}, stuck {}, out of order {}, events dropped {}",
        c.glitches,
        c.both_lines,
        c.capped,
        c.stuck,
        c.out_of_order,
        c.dropped
    );
}

pub fn wake(wake: &Wake) {
    if wake.lost_edges > 0 {
        defmt::warn!(
            "ST4: {} edges lost (input storm?), resynchronised",
            wake.lost_edges
        );
    }
    for ev in &wake.events {
        event(ev);
    }
    if wake.more_events > 0 {
        defmt::info!("ST4: {} more events not logged", wake.more_events);
    }
    if let Some(c) = wake.st4_counters {
        counters(c);
    }
}

/// The per-frame log.
pub fn frame(learner: &Learner<STAGES>, msg: &FrameRecord, ff: &FeedForward) {
    let f = &msg.frame;
    let model = learner.guider();
    let kind = match f.kind {
        FrameKind::Measured if f.filled => "filled",
        FrameKind::Measured => "measured",
        FrameKind::Unmeasured => "unmeasured",
        FrameKind::Moved => "moved by the port",
        FrameKind::Calibration => "calibration",
        FrameKind::Dither { .. } => "dither",
    };
    defmt::info!(
        "frame {} at gear {} s: gear error {} arcsec (pulse {} arcsec)",
        kind,
        f.gear_time_s,
        f.gear_error_arcsec,
        f.pulse_arcsec
    );
    defmt::info!(
        "model: learning {} %, blend {}, feed-forward {} arcsec/s",
        (model.learning_progress() * 100.0) as f32,
        model.blend_weight() as f32,
        ff.rate_arcsec_per_s
    );
    for stage in 0..STAGES {
        defmt::info!(
            "model stage {}: period {} s, gate {}",
            stage,
            model.period_s(stage) as f32,
            model.gate(stage) as f32
        );
    }
    let l = learner.counters();
    let m = model.faults();
    defmt::info!(
        "model counters: frames {}, learned {}, not learned {}, dithers {}, bumps {}",
        l.frames,
        l.learned,
        l.not_learned,
        l.dithers,
        l.bumps
    );
    defmt::info!(
        "model faults: bad time {}, bad input {}, inference {}, grid restarts {}, bad dithers {}",
        m.bad_time,
        m.bad_input,
        m.inference_failures,
        m.grid_restarts,
        m.bad_dithers
    );
    let g = &msg.guiding;
    defmt::info!(
        "guiding: pulses RA {} Dec {}, frames {} (filled {}, unmeasured {}, dropped {})",
        g.ra_pulses,
        g.dec_pulses,
        g.frames,
        g.filled_frames,
        g.unmeasured_frames,
        g.frames_dropped
    );
    defmt::info!(
        "guiding: dithers {}, calibrations {}, silences {}, backlogs {}, stray ends {}, time backwards {}, clamped RA {} Dec {}",
        g.dithers,
        g.calibrations,
        g.silences,
        g.backlogs,
        g.stray_ends,
        g.time_backwards,
        g.ra_clamped,
        g.dec_clamped
    );
    defmt::info!(
        "feed-forward: rejected {}, limited {}, expired {}, faded {}",
        g.feed_forward_rejected,
        g.feed_forward_limited,
        g.feed_forward_expired,
        g.feed_forward_faded
    );
    counters(msg.st4);
}

/// A refused configuration: the field, its value and the rule.
pub fn config_refused(e: &ConfigError) {
    let field = e.field.name();
    match e.value {
        Value::Count(v) => {
            defmt::error!("mount configuration refused: {} = {}: {}", field, v, e.rule)
        }
        Value::Real(v) => {
            defmt::error!("mount configuration refused: {} = {}: {}", field, v, e.rule)
        }
    }
}

/// The status line: step counts and rates, and the ST4 counters.
pub fn status() {
    let (ra_steps, dec_steps) = step_counts();
    let (ra_rate, dec_rate) = rates_set();
    defmt::info!(
        "status: RA {} steps at {} steps/s, Dec {} steps at {} steps/s",
        ra_steps,
        ra_rate,
        dec_steps,
        dec_rate,
    );
    if let Some(c) = ST4_COUNTERS.lock(|c| c.get()) {
        counters(c);
    }
    let storms = storms();
    if storms > 0 {
        defmt::warn!("ST4: {} edge storms (line masked until quiet)", storms);
    }
    for (port, link) in LINKS.iter().enumerate() {
        let errors = link.errors();
        if errors > 0 {
            defmt::warn!("command port {}: {} receive errors", port, errors);
        }
    }
}
