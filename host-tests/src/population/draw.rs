//! Drawing a mount from the ranges of [`super::ranges`], one generator per
//! mount, in a fixed order of draws.

use super::ranges::*;
use super::{Fade, Modulation, Mount, Stage, StageKind};
use crate::cases::{Case, Envelope, Sinusoid};
use crate::noise::SplitMix64;
use std::f64::consts::PI;

/// Mount `index` (from 1) from its own generator.
pub fn mount(index: usize, rng: &mut SplitMix64) -> Mount {
    let teeth = whole_in(rng, WORM_TEETH.0 as u64, WORM_TEETH.1 as u64) as u32;
    let worm_period_s = SIDEREAL_DAY_S / teeth as f64;
    let worm_px = rng.f64_in(WORM_AMPLITUDE_PX.0, WORM_AMPLITUDE_PX.1);
    let worm_harmonics = [(); 3].map(|_| rng.f64_in(HARMONIC_SHARE.0, HARMONIC_SHARE.1));
    let modulation = (rng.uniform() < MODULATED_SHARE).then(|| Modulation {
        depth: rng.f64_in(MODULATION_DEPTH.0, MODULATION_DEPTH.1),
        period_s: rng.f64_in(MODULATION_PERIOD_S.0, MODULATION_PERIOD_S.1),
        phase_rad: phase(rng),
    });
    let count = whole_in(rng, STAGES.0 as u64, STAGES.1 as u64) as usize;
    let mut stages: Vec<Stage> = (0..count).map(|_| stage(rng, worm_period_s)).collect();
    if !stages.is_empty() && rng.uniform() < FADING_SHARE {
        let i = rng.below(stages.len() as u64) as usize;
        stages[i].fade = Some(Fade {
            from_s: rng.f64_in(FADE_FROM_S.0, FADE_FROM_S.1),
            over_s: rng.f64_in(FADE_OVER_S.0, FADE_OVER_S.1),
            to: rng.f64_in(FADE_TO.0, FADE_TO.1),
        });
    }
    let drift_px_per_s = rng.f64_in(-DRIFT_PX_PER_S, DRIFT_PX_PER_S);
    let walk_px_per_sqrt_min = rng.f64_in(WALK_PX_PER_SQRT_MIN.0, WALK_PX_PER_SQRT_MIN.1);
    let seeing_px = rng.f64_in(SEEING_PX.0, SEEING_PX.1);
    let exposure_steps = ((EXPOSURE_S.1 - EXPOSURE_S.0) / EXPOSURE_STEP_S).round() as u64;
    let exposure_s = EXPOSURE_S.0 + EXPOSURE_STEP_S * whole_in(rng, 0, exposure_steps) as f64;
    let run_seed = rng.next_u64() >> 1; // room for the runs' seed + k and + 1000

    let worm_envelope = modulation.map_or(Envelope::Steady, |m| Envelope::Modulated {
        depth: m.depth,
        period_s: m.period_s,
        phase_rad: m.phase_rad,
    });
    let mut sinusoids = Vec::new();
    let worm_shares = [1.0, worm_harmonics[0], worm_harmonics[1], worm_harmonics[2]];
    push_harmonics(
        &mut sinusoids,
        rng,
        "worm",
        worm_period_s,
        worm_px,
        &worm_shares,
        worm_envelope,
    );
    for (i, s) in stages.iter().enumerate() {
        let envelope = s.fade.map_or(Envelope::Steady, |f| Envelope::Fade {
            from_s: f.from_s,
            over_s: f.over_s,
            to: f.to,
        });
        let shares = [1.0, s.harmonics[0], s.harmonics[1]];
        let name = format!("stage{}", i + 1);
        push_harmonics(
            &mut sinusoids,
            rng,
            &name,
            s.period_s,
            s.amplitude_px,
            &shares,
            envelope,
        );
    }
    Mount {
        index,
        teeth,
        worm_period_s,
        worm_px,
        worm_harmonics,
        modulation,
        stages,
        drift_px_per_s,
        walk_px_per_sqrt_min,
        seeing_px,
        exposure_s,
        run_seed,
        case: Case {
            name: index.to_string(),
            sinusoids,
            drift_px_per_s,
        },
    }
}

/// A further stage of a worm turning every `worm_period_s`.
fn stage(rng: &mut SplitMix64, worm_period_s: f64) -> Stage {
    let kind = if rng.uniform() < BELT_SHARE {
        StageKind::Belt
    } else if rng.uniform() < NEAR_HARMONIC_SHARE {
        // Drawn again when below the 2nd harmonic: out of GEAR_RATIO.
        StageKind::Gear {
            ratio: loop {
                let k = whole_in(rng, NEAR_HARMONIC.0 as u64, NEAR_HARMONIC.1 as u64);
                let offset = rng.f64_in(NEAR_HARMONIC_OFFSET.0, NEAR_HARMONIC_OFFSET.1);
                let sign = if rng.uniform() < 0.5 { -1.0 } else { 1.0 };
                let r = k as f64 * (1.0 + sign * offset);
                if r >= GEAR_RATIO.0 {
                    break r;
                }
            },
        }
    } else {
        StageKind::Gear {
            ratio: loop {
                let r = rng.f64_in(GEAR_RATIO.0, GEAR_RATIO.1);
                if (r / r.round() - 1.0).abs() >= WHOLE_RATIO_MARGIN {
                    break r;
                }
            },
        }
    };
    let period_s = match kind {
        StageKind::Belt => rng.f64_in(BELT_PERIOD_S.0, BELT_PERIOD_S.1),
        StageKind::Gear { ratio } => worm_period_s / ratio,
    };
    Stage {
        kind,
        period_s,
        amplitude_px: rng.f64_in(STAGE_AMPLITUDE_PX.0, STAGE_AMPLITUDE_PX.1),
        harmonics: [(); 2].map(|_| rng.f64_in(HARMONIC_SHARE.0, HARMONIC_SHARE.1)),
        fade: None,
    }
}

/// A fundamental of `amplitude_px` at `period_s` and its harmonics (the
/// k-th at `shares[k - 1]` of it), each at a phase of its own.
fn push_harmonics(
    out: &mut Vec<Sinusoid>,
    rng: &mut SplitMix64,
    name: &str,
    period_s: f64,
    amplitude_px: f64,
    shares: &[f64],
    envelope: Envelope,
) {
    for (k, share) in (1..).zip(shares) {
        out.push(Sinusoid {
            component: if k == 1 {
                name.to_string()
            } else {
                format!("{name}_h{k}")
            },
            period_s: period_s / k as f64,
            amplitude_px: amplitude_px * share,
            phase_rad: phase(rng),
            envelope,
        });
    }
}

fn phase(rng: &mut SplitMix64) -> f64 {
    rng.f64_in(0.0, 2.0 * PI)
}

/// A whole number in `lo..=hi`.
fn whole_in(rng: &mut SplitMix64, lo: u64, hi: u64) -> u64 {
    lo + rng.below(hi - lo + 1)
}
