//! One guiding section of the replay (the conventions are the module's,
//! `replay`).

use super::{measurements, pointing, Options, TimeStep, SLOW_CADENCE};
use crate::guide_algorithm::GuideAlgorithm;
use crate::phd2_log::{EventKind, Section};

/// Replay `section` (at least 3 frames) with `algorithm`: the number of
/// states and the sum of their squares (px²).
pub fn replay(
    section: &Section,
    algorithm: &mut dyn GuideAlgorithm,
    options: &Options,
) -> (usize, f64) {
    let f = &section.frames;
    let (m, c) = measurements(section, options.first_lock);
    let cadence = cadence_s(section);
    let fixed = step_s(section, options.time_step, cadence);
    let step = |t: f64, next: f64| fixed.unwrap_or(next - t);
    let clock = |t: f64| section.start_s + t;
    let frames = f.len() - 2;
    let mut x = m[0];
    let mut sum_sq = 0.0;
    for i in 0..frames {
        tell_before(section, i, algorithm, options);
        let u = algorithm.step(
            clock(f[i].time_s),
            x,
            f[i].snr,
            step(f[i].time_s, f[i + 1].time_s),
        );
        x += (m[i + 1] - (m[i] - c[i])) - u;
        let darks = dark_times(section, i, cadence, options);
        for (k, &t) in darks.iter().enumerate() {
            let next = darks.get(k + 1).copied().unwrap_or(f[i + 1].time_s);
            x -= algorithm.dark(clock(t), step(t, next));
        }
        sum_sq += x * x;
    }
    (frames, sum_sq)
}

/// The time step of `section`'s frames (`None`: each frame's interval to
/// the next), given its `cadence`.
pub fn step_s(section: &Section, time_step: TimeStep, cadence: f64) -> Option<f64> {
    match time_step {
        TimeStep::Exposure => Some(section.exposure_s),
        TimeStep::Cadence => Some(cadence),
        TimeStep::ToNext => None,
        TimeStep::Frames if cadence >= SLOW_CADENCE * section.exposure_s => Some(cadence),
        TimeStep::Frames => Some(section.exposure_s),
    }
}

/// Tell `algorithm` of the dithers and settling before frame `i`.
fn tell_before(section: &Section, i: usize, algorithm: &mut dyn GuideAlgorithm, options: &Options) {
    let before = || section.events.iter().filter(move |e| e.next_frame == i);
    let dithered = before().any(|e| matches!(e.kind, EventKind::Dither { .. }));
    for e in before() {
        match e.kind {
            EventKind::Dither { x, .. } if options.dithers => {
                match pointing::sidereal_px_per_s(section) {
                    Some(rate) => algorithm.dither(x, rate),
                    // Settle, with gear time unmoved.
                    None => algorithm.dither(0.0, 1.0),
                }
            }
            EventKind::SettlingStarted if options.settling && !dithered => {
                algorithm.dither(0.0, 1.0);
            }
            _ => {}
        }
    }
}

/// The times (s of the section's `Time`) of the frames without a star
/// between frame `i` and the next, in order: its DROP rows and, in a pause,
/// one every cadence.
fn dark_times(section: &Section, i: usize, cadence: f64, options: &Options) -> Vec<f64> {
    let drops: Vec<f64> = section
        .drops()
        .filter(|&(next, _)| next == i + 1)
        .map(|(_, t)| t)
        .collect();
    let mut out = Vec::new();
    let mut last = section.frames[i].time_s;
    let until = section.frames[i + 1].time_s;
    for &row in drops.iter().chain(std::iter::once(&until)) {
        if options
            .pause_cadences
            .is_some_and(|k| row - last > k * cadence)
        {
            let mut t = last + cadence;
            while t < row - 0.5 * cadence {
                out.push(t);
                t += cadence;
            }
        }
        if options.drops && row < until {
            out.push(row);
        }
        last = row;
    }
    out
}

/// The section's cadence: the median interval between its rows (frames
/// with a star and without), or its exposure with fewer than two.
pub fn cadence_s(section: &Section) -> f64 {
    let mut times: Vec<f64> = section
        .frames
        .iter()
        .map(|f| f.time_s)
        .chain(section.drops().map(|(_, t)| t))
        .collect();
    times.sort_by(f64::total_cmp);
    let mut intervals: Vec<f64> = times.windows(2).map(|w| w[1] - w[0]).collect();
    if intervals.is_empty() {
        return section.exposure_s;
    }
    intervals.sort_by(f64::total_cmp);
    intervals[intervals.len() / 2]
}
