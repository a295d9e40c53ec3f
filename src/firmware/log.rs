//! The defmt log lines. defmt-rtt holds a critical section while it
//! encodes a line (the step tick waits meanwhile), so the lines are kept
//! short: at most six values each, and a counter a line (`group name
//! value`, from its group's one definition: `mkgp_mount::counters`).

use mkgp_mount::control_loop::{FrameRecord, Wake};
use mkgp_mount::counters::Counters;
use mkgp_mount::mount::config::{ConfigError, Value};
use mkgp_mount::mount::frame::{FeedForward, FrameKind};
use mkgp_mount::mount::learner::Learner;
use mkgp_mount::mount::st4::{Axis, Direction, St4Event};

use crate::firmware::port_io::LINKS;
use crate::firmware::shared::{storms, ST4_COUNTERS};
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

/// The most counters a group has (guiding's).
const MOST: usize = 24;

/// A group's values in index order, 0 beyond its last.
fn values<C: Counters>(c: &C) -> [u32; MOST] {
    let mut v = [0; MOST];
    for (index, slot) in v.iter_mut().enumerate() {
        if let Some((_, value)) = c.get(index) {
            *slot = value;
        }
    }
    v
}

/// The counters of a group whose value differs from `before` (all 0 when
/// nothing was logged before), a line each. One function for every group:
/// a copy per group would cost flash.
#[inline(never)]
fn changed(group: &str, names: &[&str], before: &[u32; MOST], now: &[u32; MOST]) {
    for ((name, was), value) in names.iter().zip(before).zip(now) {
        if value != was {
            defmt::info!("{=str} {=str} {}", group, name, value);
        }
    }
}

/// The counters of `group` that are not 0, a line each.
fn not_zero<C: Counters>(group: &str, now: &C) {
    changed(group, C::NAMES, &[0; MOST], &values(now));
}

/// The counters as the frame log last wrote them: each frame's log writes
/// those that changed since.
pub struct Logged {
    learner: [u32; MOST],
    faults: [u32; MOST],
    guiding: [u32; MOST],
}

impl Logged {
    pub const NONE: Logged = Logged {
        learner: [0; MOST],
        faults: [0; MOST],
        guiding: [0; MOST],
    };

    /// Logs what changed in `group` (`last` its values as last logged).
    fn update<C: Counters>(group: &str, last: &mut [u32; MOST], now: &C) {
        let now = values(now);
        changed(group, C::NAMES, last, &now);
        *last = now;
    }
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
        not_zero("ST4", &c);
    }
}

/// The per-frame log.
pub fn frame(learner: &Learner<STAGES>, msg: &FrameRecord, ff: &FeedForward, logged: &mut Logged) {
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
    Logged::update("model", &mut logged.learner, &learner.counters());
    Logged::update("model faults", &mut logged.faults, &model.faults());
    Logged::update("guiding", &mut logged.guiding, &msg.guiding);
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
        not_zero("ST4", &c);
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
