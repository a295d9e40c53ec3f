//! The firmware's closed loop (`guide-sim st4`): the goals, and the
//! bad inputs on the ST4 lines, each with a defined outcome: no step rate
//! outside [0, max] for RA or beyond +-max for Dec, nothing non-finite, no
//! panic, and counters that say what happened.

use host_tests::cases::{self, Case};
use host_tests::data::cases_file;
use host_tests::st4_sim::{self, Firmware, GuiderSettings, Rig, Setup, Sky};
use mkgp_mount::mount::config::{Field, MountConfig};
use mkgp_mount::mount::frame::FrameKind;
use mkgp_mount::mount::st4::Line;

const S: u64 = 1_000_000;

fn case(name: &str) -> Case {
    let cases = cases::load(&cases_file()).unwrap_or_else(|e| panic!("{e}"));
    cases.into_iter().find(|c| c.name == name).unwrap()
}

fn assert_rates_sane(rig: &Rig) {
    let e = rig.extremes;
    assert_eq!(e.non_finite, 0);
    assert!(e.ra_min >= 0.0, "RA rate {} < 0", e.ra_min);
    assert!(
        e.ra_max <= rig.mount.max_ra_steps_per_s(),
        "RA rate {} > max",
        e.ra_max
    );
    assert!(e.dec_abs_max <= rig.mount.max_dec_steps_per_s());
}

/// Every case and noise level against the bars.
#[test]
fn goals() {
    let cases = cases::load(&cases_file()).unwrap_or_else(|e| panic!("{e}"));
    let rows = st4_sim::table(&cases, &[0.0, 1.0]);
    let mut failures = Vec::new();
    for r in &rows {
        let ratio = r.fw_mkgp / r.guider_only;
        println!(
            "{} noise {}: guider only {:.3}, fw ppec {:.3}, fw mkgp {:.3} ({ratio:.3})",
            r.case, r.noise_px, r.guider_only, r.fw_ppec, r.fw_mkgp
        );
        for (name, v) in [("fw_ppec", r.fw_ppec), ("fw_mkgp", r.fw_mkgp)] {
            if v > r.guider_only {
                failures.push(format!(
                    "{} noise {}: {name} {v:.3} worse than guider alone {:.3}",
                    r.case, r.noise_px, r.guider_only
                ));
            }
        }
        // The goals: C5-C8 at most 0.6 x the guider alone noise-free and
        // 0.8 x with 1 px, C8 0.6 x; issue 10, section 5 (half the gap to
        // a perfect feed-forward behind full pulses) C6 0.685 x and C7
        // 0.635 x with 1 px. C1-C4 with 1 px are held to 0.8 x as well:
        // without the earned pulse share they measure 0.87-0.93.
        let hard = ["C5", "C6", "C7", "C8"].contains(&r.case.as_str());
        let bar = match (r.case.as_str(), r.noise_px > 0.0) {
            (_, false) if hard => Some(0.6),
            (_, false) => None,
            ("C8", true) => Some(0.6),
            ("C7", true) => Some(0.635),
            ("C6", true) => Some(0.685),
            (_, true) => Some(0.8),
        };
        if let Some(b) = bar {
            if ratio > b {
                failures.push(format!(
                    "{} noise {}: fw_mkgp / guider_only = {ratio:.3} > {b}",
                    r.case, r.noise_px
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// A guider exposing longer than the configured cadence (2 s): the
/// frames are filled at its own cadence, and the firmware stays below the
/// guider alone on C5-C8 with 1 px. With fills at 2 s behind 8 s exposures
/// the model learned its own feed-forward as gear error: C8 measured 21.56
/// arcsec against the guider alone's 4.53. Bars at issue 10's goals: never
/// above the guider alone for exposures up to 8 s, at most 0.8 x it on
/// C5-C8 at 1 px for 1-4 s.
#[test]
fn a_guider_slower_than_configured() {
    let cases: Vec<Case> = ["C5", "C6", "C7", "C8"].into_iter().map(case).collect();
    for (exposure_s, bar) in [(8.0, 1.0), (4.0, 0.8)] {
        let guider = GuiderSettings {
            exposure_s,
            ..GuiderSettings::default()
        };
        let setup = Setup {
            guider,
            ..Setup::default()
        };
        for r in st4_sim::table_with(&cases, &[1.0], setup) {
            let ratio = r.fw_mkgp / r.guider_only;
            println!(
                "{exposure_s} s {}: guider only {:.3}, fw mkgp {:.3} ({ratio:.3})",
                r.case, r.guider_only, r.fw_mkgp
            );
            assert!(
                ratio <= bar,
                "{exposure_s} s exposures, {}: {ratio:.3} > {bar}",
                r.case
            );
        }
    }
}

/// A mount configured with another wheel than it has: the worm's period
/// and the RA steps per worm turn both 10 % or 20 % off, so that it still
/// tracks at the sidereal rate. A worm faster than the configured period
/// (x1.1) is followed; a slower one (x0.8) is taken for no stage of the
/// train, the model keeps the configured period (`configured_worm`) and
/// loses most of the worm's gain, but the firmware stays below the guider
/// alone (C5 at 1 px, seeds 1-3).
#[test]
fn a_mount_configured_with_another_wheel_stays_below_the_guider_alone() {
    let c = case("C5");
    for factor in [1.1, 0.8] {
        let right = st4_sim::mount_config(&c);
        let config = MountConfig {
            worm_period_s: (right.worm_period_s as f64 * factor) as f32,
            ra_steps_per_worm_turn: (right.ra_steps_per_worm_turn as f64 * factor).round() as u32,
            ..right
        };
        let rms = |firmware| {
            (1..=3)
                .map(|seed| st4_sim::run_on(&c, firmware, 1.0, seed, Setup::default(), config).rms)
                .sum::<f64>()
                / 3.0
        };
        let (alone, mkgp) = (rms(Firmware::GuiderOnly), rms(Firmware::Mkgp));
        println!("wheel x{factor}: guider only {alone:.3}, fw mkgp {mkgp:.3}");
        assert!(mkgp < alone, "x{factor}: {mkgp:.3} vs {alone:.3}");
    }
}

/// A mount whose gears add no error, behind 1 px of seeing: the model must
/// find no stage in the noise alone (`noise_floor`), and the firmware
/// stays below the guider alone at its default share; without the floor
/// the stages it finds there cost more than the guider alone.
#[test]
fn a_flat_gear_finds_no_stage_in_the_noise() {
    let mut c = case("C1");
    for s in &mut c.sinusoids {
        s.amplitude_px = 0.0;
    }
    c.drift_px_per_s = 0.0;
    let rms = |firmware, setup: Setup| {
        (1..=3)
            .map(|seed| st4_sim::run_with(&c, firmware, 1.0, seed, setup).rms)
            .sum::<f64>()
            / 3.0
    };
    let mut without = Setup::default();
    without.additions.set("noise_floor", false).unwrap();
    let alone = rms(Firmware::GuiderOnly, Setup::default());
    let (on, off) = (
        rms(Firmware::Mkgp, Setup::default()),
        rms(Firmware::Mkgp, without),
    );
    println!(
        "flat gear at 1 px: guider only {alone:.3}, fw mkgp {on:.3}, without noise_floor {off:.3}"
    );
    assert!(on < alone, "{on:.3} vs {alone:.3}");
    assert!(off > alone, "without noise_floor: {off:.3} vs {alone:.3}");
}

/// A PPEC rig on C1, guided for `secs` first.
fn rig(secs: u64) -> Rig {
    let mut r = Rig::new(&case("C1"), Firmware::Ppec, 0.0, 1);
    r.run_until(secs * S);
    r
}

#[test]
fn contact_bounce() {
    let mut r = rig(100);
    let t = r.now_us + 500_000;
    // Five bounces of 100-300 us, then the contact closes for 200 ms.
    for k in 0..5 {
        r.edge(Line::DecPlus, true, t + k * 400);
        r.edge(Line::DecPlus, false, t + k * 400 + 100 + 40 * k);
    }
    r.pulse(Line::DecPlus, t + 2_100, 200_000);
    // Bounce on release too.
    r.edge(Line::DecPlus, true, t + 202_100 + 300);
    r.edge(Line::DecPlus, false, t + 202_100 + 500);
    r.run_until(t + S);
    let st4 = r.st4_counters();
    assert!(st4.glitches >= 6, "{st4:?}");
    assert_eq!(r.guiding_counters().dec_pulses, 1);
    // Dec moved 200 ms at the guide rate, within a step.
    let want = 0.2 * r.mount.guide_dec_steps_per_s() as f64;
    assert!(
        (r.dec_steps() as f64 - want).abs() <= 1.0,
        "{} vs {want}",
        r.dec_steps()
    );
    r.run_until(200 * S);
    assert_rates_sane(&r);
}

#[test]
fn both_lines_of_an_axis() {
    let mut r = rig(100);
    r.guider_on = false;
    let t = r.now_us + 500_000;
    r.edge(Line::DecMinus, true, t);
    r.edge(Line::DecPlus, true, t + 100_000);
    r.edge(Line::DecPlus, false, t + 300_000);
    r.edge(Line::DecMinus, false, t + 400_000);
    r.run_until(t + 50_000);
    assert!(r.rates().dec_steps_per_s < 0.0);
    r.run_until(t + 200_000);
    // Both asserted: the pulse stopped.
    assert_eq!(r.rates().dec_steps_per_s, 0.0);
    let moved = -(r.dec_steps() as f64);
    let want = 0.1 * r.mount.guide_dec_steps_per_s() as f64;
    assert!((moved - want).abs() <= 1.0, "{moved} vs {want}");
    r.run_until(t + S);
    assert_eq!(r.st4_counters().both_lines, 1);
    assert_eq!(r.rates().dec_steps_per_s, 0.0);
    assert_rates_sane(&r);
}

#[test]
fn a_line_stuck_low() {
    let mut r = rig(100);
    r.guider_on = false;
    let t = r.now_us + 500_000;
    r.edge(Line::RaMinus, true, t);
    r.run_until(t + 30 * S);
    let st4 = r.st4_counters();
    assert_eq!((st4.capped, st4.stuck), (1, 1), "{st4:?}");
    // The cut pulse lasted the cap: a dither to the firmware, not learned.
    let g = r.guiding_counters();
    assert!(g.dithers >= 1, "{g:?}");
    assert!(r.learner_counters().not_learned >= 10);
    // The RA rate is sidereal again after the cut.
    let sid = r.mount.sidereal_ra_steps_per_s();
    assert!((r.rates().ra_steps_per_s - sid).abs() < 0.01 * sid);
    assert_rates_sane(&r);
    // The guider's RA+ pulses meet a line that counts as asserted: both
    // lines, no pulse; released, guiding goes on.
    r.guider_on = true;
    r.run_until(r.now_us + 10 * S);
    assert!(r.st4_counters().both_lines >= 1);
    r.edge(Line::RaMinus, false, r.now_us + 1000);
    r.run_until(r.now_us + 100 * S);
    assert_rates_sane(&r);
}

#[test]
fn pulses_during_a_dither() {
    let mut r = rig(1200);
    let before = r.learner_counters();
    r.dither(40.0);
    let t = (r.now_us / (2 * S) + 1) * 2 * S;
    // Dec pulses and RA bounces while the 5.3 s dither pulse runs.
    for k in 0..4 {
        r.pulse(Line::DecPlus, t + S + k * S, 300_000);
        r.edge(Line::RaMinus, true, t + S + k * S + 10_000);
        r.edge(Line::RaMinus, false, t + S + k * S + 10_200);
    }
    r.run_until(t + 60 * S);
    let g = r.guiding_counters();
    assert_eq!(g.dithers, 1, "{g:?}");
    assert_eq!(g.dec_pulses, 4);
    let l = r.learner_counters();
    assert_eq!(l.dithers, 1);
    assert!(
        l.not_learned - before.not_learned >= 10,
        "{before:?} -> {l:?}"
    );
    let dither_frames = r
        .frames
        .iter()
        .filter(|f| matches!(f.kind, FrameKind::Dither { .. }))
        .count();
    assert_eq!(dither_frames, 1);
    r.run_until(t + 300 * S);
    assert_rates_sane(&r);
}

#[test]
fn guider_silence() {
    // Long enough for the model to be blended in (2 worm periods); with
    // 1 px noise the guider pulses nearly every frame until it stops.
    let mut r = Rig::new(&case("C1"), Firmware::Ppec, 1.0, 1);
    r.run_until(2000 * S);
    assert!(r.guiding().feed_forward_now() != 0.0);
    let silences_before = r.guiding_counters().silences;
    r.guider_on = false;
    let quiet_from = r.now_us;
    let worm = (r.mount.config().worm_period_s as f64 * 1e6) as u64;
    r.run_until(quiet_from + worm - 5 * S);
    let g = r.guiding_counters();
    assert_eq!(g.silences, silences_before + 1, "{g:?}");
    assert!(r.guiding().silent());
    // Feed-forward still extrapolated by the model (unmeasured frames).
    assert!(r.guiding().feed_forward_now() != 0.0);
    assert!(g.unmeasured_frames > 100);
    r.run_until(quiet_from + worm + 12 * S);
    assert_eq!(r.guiding().feed_forward_now(), 0.0);
    assert_eq!(r.guiding_counters().feed_forward_faded, 1);
    // The guider comes back: learning and feed-forward resume.
    r.guider_on = true;
    r.run_until(r.now_us + 100 * S);
    assert!(!r.guiding().silent());
    assert!(r.guiding().feed_forward_now() != 0.0);
    assert_rates_sane(&r);
}

#[test]
fn a_huge_pulse() {
    let mut r = rig(100);
    r.guider_on = false;
    let t = r.now_us + 500_000;
    r.pulse(Line::RaPlus, t, 3_600 * S);
    r.run_until(t + 20 * S);
    let st4 = r.st4_counters();
    assert_eq!(st4.capped, 1, "{st4:?}");
    // Cut at the cap: at most 10 s of guide rate.
    let dither = r
        .frames
        .iter()
        .find_map(|f| match f.kind {
            FrameKind::Dither { amount_arcsec } => Some(amount_arcsec),
            _ => None,
        })
        .expect("the cut pulse is a dither");
    let cap_s = r.mount.config().pulse_cap_us as f32 * 1e-6;
    assert!((dither - cap_s * r.mount.guide_rate_arcsec_per_s()).abs() < 0.01);
    r.run_until(t + 200 * S);
    assert_rates_sane(&r);
}

#[test]
fn a_zero_guide_rate_is_refused() {
    let c = MountConfig {
        guide_rate_sidereal: 0.0,
        ..MountConfig::default()
    };
    let e = c.validate().unwrap_err();
    assert_eq!(e.field, Field::GuideRateSidereal);
    assert!(e.to_string().contains("guide_rate_sidereal"), "{e}");
}

#[test]
fn cli_csv() {
    let dir = std::env::temp_dir().join(format!("guide-sim-st4-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let cases = dir.join("one_case.csv");
    std::fs::write(
        &cases,
        "case,component,period_s,amplitude_px,phase_rad,drift_px_per_s\nX,primary,432,9.0,0,\nX,drift,,,,0.0008\n",
    )
    .unwrap();
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_guide-sim"))
        .args([
            "st4",
            "--cases",
            cases.to_str().unwrap(),
            "--noise",
            "0",
            "--csv",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = String::from_utf8_lossy(&o.stdout).into_owned();
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines[0], "case,noise_px,guider_only,fw_ppec,fw_mkgp");
    assert_eq!(lines.len(), 2, "{out}");
    assert!(lines[1].starts_with("X,0,"), "{out}");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_guide-sim"))
        .args(["st4", "--cases", cases.to_str().unwrap(), "--case", "C9"])
        .output()
        .unwrap();
    assert!(!o.status.success());
}

/// A 1 px MKGP rig on `name` (seed 1) with the firmware's least pulse
/// share `least`, guided for `secs`.
fn shared_rig(name: &str, least: f32, secs: u64) -> Rig {
    let c = case(name);
    let config = MountConfig {
        least_pulse_share: least,
        ..st4_sim::mount_config(&c)
    };
    let mut r = Rig::with_mount(&c, Firmware::Mkgp, 1.0, 1, config);
    r.run_until(secs * S);
    r
}

/// Mean and RMS of the frames' observations minus the true gear error at
/// their stamp (the middle of their interval), over frames after 1800 s.
fn observation_error(r: &Rig) -> (f64, f64) {
    let errors: Vec<f64> = r
        .frames
        .iter()
        .filter(|f| f.gear_time_s > 1800.0 && f.kind == FrameKind::Measured)
        .map(|f| {
            let t = f.gear_time_s - 0.5 * f.interval_s as f64;
            f.gear_error_arcsec as f64 - r.case.gear_error(t)
        })
        .collect();
    let n = errors.len() as f64;
    let mean = errors.iter().sum::<f64>() / n;
    let rms = (errors.iter().map(|e| e * e).sum::<f64>() / n).sqrt();
    (mean, rms)
}

/// Behind a trusted model with 1 px of noise the firmware earns a share
/// below one and carries out the pulses in part; the observations it
/// rebuilds from them (the motion the steps made plus the pulse over the
/// aggressiveness) stay as right as with full pulses, and no swing lowers
/// the weight of a pulse learned. Switched off (`least_pulse_share` 1),
/// every pulse is carried out in full.
#[test]
fn the_pulse_share_is_earned_and_learning_stays_right() {
    let on = shared_rig("C1", 0.2, 3600);
    let off = shared_rig("C1", 1.0, 3600);
    assert!(on.pulse_share() < 0.5, "{}", on.pulse_share());
    assert_eq!(on.pulse_weight(), 1.0);
    assert_eq!(on.learner_counters().bumps, 0);
    let g = on.guiding_counters();
    assert!(g.ra_pulses_held_back > 500, "{g:?}");
    assert_eq!(off.pulse_share(), 1.0);
    assert_eq!(off.guiding_counters().ra_pulses_held_back, 0);
    let (mean_on, rms_on) = observation_error(&on);
    let (mean_off, rms_off) = observation_error(&off);
    println!("observation error: on {mean_on:.3} / {rms_on:.3}, off {mean_off:.3} / {rms_off:.3}");
    assert!(mean_on.abs() < 0.1 && mean_off.abs() < 0.1);
    assert!(
        (rms_on / rms_off - 1.0).abs() < 0.1,
        "{rms_on} vs {rms_off}"
    );
}

/// A PHD2 calibration (RA+ steps of 750 ms, RA- back, a 2.5 s step)
/// through the loop while the firmware shares its pulses: each pulse moves the mount
/// by exactly what it asks (the steps beyond sidereal and feed-forward,
/// within two steps), and a Dec pulse moves Dec by its whole length.
#[test]
fn a_calibration_through_the_shared_loop_moves_the_mount_as_asked() {
    let mut r = shared_rig("C1", 0.2, 3600);
    assert!(r.pulse_share() < 1.0);
    r.guider_on = false;
    // The guider's last pulse is over.
    r.run_until(r.now_us + 5 * S);
    let step = r.mount.arcsec_per_ra_step() as f64;
    let guide = r.mount.guide_rate_arcsec_per_s() as f64;
    let made_up_before = r.guiding_counters().ra_pulses_made_up;
    let mut pulses = vec![(Line::RaPlus, 750_000u64); 6];
    pulses.extend([(Line::RaMinus, 750_000); 6]);
    pulses.push((Line::RaPlus, 2_500_000));
    for (line, duration) in pulses {
        let start = r.now_us + S;
        r.pulse(line, start, duration);
        let before = r.applied_arcsec();
        let mut feed_forward = 0.0;
        let end = start + duration + S;
        while r.now_us < end {
            feed_forward += r.guiding().feed_forward_now() as f64 * 0.01;
            r.run_until(r.now_us + 10_000);
        }
        let moved = r.applied_arcsec() - before - feed_forward;
        let sign = if line == Line::RaPlus { 1.0 } else { -1.0 };
        let want = sign * guide * duration as f64 * 1e-6;
        assert!(
            (moved - want).abs() < 2.0 * step,
            "{line:?} {duration}: {moved} vs {want}"
        );
    }
    assert!(r.guiding_counters().ra_pulses_made_up > made_up_before);
    let dec_before = r.dec_steps();
    let t = r.now_us + S;
    r.pulse(Line::DecPlus, t, 750_000);
    r.run_until(t + 2 * S);
    let want = 0.75 * r.mount.guide_dec_steps_per_s() as f64;
    assert!(((r.dec_steps() - dec_before) as f64 - want).abs() <= 1.0);
    assert_rates_sane(&r);
}

/// What no model explains (a constant drift of 2 arcsec per minute either
/// way, a random walk of 1 arcsec per square root of a minute, a bump of
/// 3 arcsec every 15 minutes): the firmware stays below the guider alone,
/// by the margin `guide-sim st4 --drift/--walk/--bump` measures on every
/// case (at most 0.76 of it; docs/results.md).
#[test]
fn errors_no_model_explains_stay_below_the_guider_alone() {
    let cases: Vec<Case> = ["C1", "C5", "C6"].into_iter().map(case).collect();
    let skies = [
        Sky {
            drift_arcsec_per_min: 2.0,
            ..Sky::default()
        },
        Sky {
            drift_arcsec_per_min: -2.0,
            ..Sky::default()
        },
        Sky {
            walk_arcsec_per_sqrt_min: 1.0,
            ..Sky::default()
        },
        Sky {
            bump_arcsec: 3.0,
            ..Sky::default()
        },
    ];
    let mut failures = Vec::new();
    for sky in skies {
        let setup = Setup {
            sky,
            ..Setup::default()
        };
        for r in st4_sim::table_with(&cases, &[0.0, 1.0], setup) {
            let ratio = r.fw_mkgp / r.guider_only;
            println!("{sky:?} {} noise {}: {ratio:.3}", r.case, r.noise_px);
            if ratio > 0.8 || r.fw_ppec > r.guider_only {
                failures.push(format!("{sky:?} {} noise {}: {r:?}", r.case, r.noise_px));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// A bump of 30 arcsec every 15 minutes (the star steps out and back: a
/// cable snag, a gust): the firmware settles the model at each and takes
/// the step out of its observations, and stays below the guider alone
/// (C1, C5, C6, noise-free and 1 px: 0.92-0.99 measured; learned as gear
/// error, up to 1.04).
#[test]
fn a_bump_is_taken_out_of_the_observations() {
    let cases: Vec<Case> = ["C1", "C5", "C6"].into_iter().map(case).collect();
    let bump = |arcsec| Setup {
        sky: Sky {
            bump_arcsec: arcsec,
            ..Sky::default()
        },
        ..Setup::default()
    };
    let setup = bump(30.0);
    let run = st4_sim::run_with(&cases[1], Firmware::Mkgp, 1.0, 1, setup);
    // Eleven steps in 3 h, the first before the model is trusted.
    assert_eq!(run.learner.bumps, 11, "{:?}", run.learner);
    let mut failures = Vec::new();
    for r in st4_sim::table_with(&cases, &[0.0, 1.0], setup) {
        let ratio = r.fw_mkgp / r.guider_only;
        println!("bump 30 {} noise {}: {ratio:.3}", r.case, r.noise_px);
        if ratio > 1.0 {
            failures.push(format!("{r:?}"));
        }
    }
    // 100 arcsec, noise-free: the first step, before trust, learned as
    // gear error cost C5 1.010 x the guider alone (1.000 taken out; the
    // strongest line is the bumps', and the worm's period the mount's).
    let big = bump(100.0);
    let alone = st4_sim::run_with(&cases[1], Firmware::GuiderOnly, 0.0, 1, big);
    let fw = st4_sim::run_with(&cases[1], Firmware::Mkgp, 0.0, 1, big);
    let ratio = fw.rms / alone.rms;
    println!(
        "bump 100 C5 noise 0: {ratio:.3}, steps {}",
        fw.learner.bumps
    );
    if ratio > 1.0 {
        failures.push(format!("bump 100 C5 noise 0: {ratio:.4}"));
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// Issue 10, section 4: behind a guider more aggressive than the firmware
/// assumes (aggressiveness 1.0, 1 s exposures, a calibration of 0.75), fw
/// MKGP is at most 0.8 of the guider alone on C5-C8 with 1 px (0.60-0.72
/// measured with the earned pulse share; 0.71-0.94 without it). The
/// corner of all three at 4 s exposures swings from frame to frame, which
/// `paired_frames` keeps out of the cells (C5 0.73 on, 0.84 off).
#[test]
fn a_more_aggressive_guider_is_held_to_the_goal() {
    let cases: Vec<Case> = ["C5", "C6", "C7", "C8"].into_iter().map(case).collect();
    let default = GuiderSettings::default();
    let guiders = [
        GuiderSettings {
            aggressiveness: 1.0,
            ..default
        },
        GuiderSettings {
            exposure_s: 1.0,
            ..default
        },
        GuiderSettings {
            calibration: 0.75,
            ..default
        },
        GuiderSettings {
            aggressiveness: 1.0,
            exposure_s: 4.0,
            calibration: 0.75,
            ..default
        },
    ];
    let mut failures = Vec::new();
    for guider in guiders {
        let setup = Setup {
            guider,
            ..Setup::default()
        };
        for r in st4_sim::table_with(&cases, &[1.0], setup) {
            let ratio = r.fw_mkgp / r.guider_only;
            println!("{guider:?} {}: {ratio:.3}", r.case);
            if ratio > 0.8 {
                failures.push(format!("{guider:?} {}: {ratio:.3}", r.case));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// Issue 10, section 4: a guider unstable on its own (aggressiveness 1.0
/// with a calibration of 0.5: it corrects twice what it measures). At 2 s
/// exposures it loses the star alone and the earned share holds the loop
/// behind the trusted model. At 8 s the guider alone holds the star, and
/// the firmware's swing lowers its pulse weight. At 4 s the swing's
/// period (8 s) lies between one and two grid cells, and `paired_frames`
/// keeps it out of them (C5-C7 1.25, 1.43 and 1.08 of the guider alone
/// off, with min move 0.1). At 0.5 s exposures the
/// guider's pulses queue within seconds and it loses the star on its own;
/// the firmware then adds nothing (no feed-forward, full pulses, nothing
/// learned): exactly the guider alone. The bar is the goal for
/// every guider users run: never above the guider alone.
#[test]
fn an_unstable_guider_is_held_or_left_to_itself() {
    let cases: Vec<Case> = ["C5", "C6", "C7", "C8"].into_iter().map(case).collect();
    let unstable = GuiderSettings {
        aggressiveness: 1.0,
        calibration: 0.5,
        ..GuiderSettings::default()
    };
    let held = Setup {
        guider: unstable,
        ..Setup::default()
    };
    // The same guider at other exposures and min moves.
    let at = |exposure_s, min_move| Setup {
        guider: GuiderSettings {
            exposure_s,
            min_move,
            ..unstable
        },
        ..Setup::default()
    };
    let mut failures = Vec::new();
    for r in st4_sim::table_with(&cases, &[1.0], held) {
        println!("2 s {}: {r:?}", r.case);
        if r.fw_mkgp > r.guider_only {
            failures.push(format!("2 s: {r:?}"));
        }
    }
    let slow = at(8.0, 0.5);
    // The swing is recognised and lowers the weight for some 30 frames of
    // swing at least (1 % a frame); it stops falling once the loop is
    // stable, which the ratios below measure.
    let swung = st4_sim::run_with(&cases[2], Firmware::Mkgp, 1.0, 1, slow);
    assert!(swung.pulse_weight < 0.75, "{}", swung.pulse_weight);
    for r in st4_sim::table_with(&cases, &[1.0], slow) {
        let ratio = r.fw_mkgp / r.guider_only;
        println!("8 s {}: {r:?} {ratio:.3}", r.case);
        if ratio > 1.0 {
            failures.push(format!("8 s: {r:?}"));
        }
    }
    let paired = at(4.0, 0.1);
    for r in st4_sim::table_with(&cases, &[1.0], paired) {
        println!("4 s {}: {r:?} {:.3}", r.case, r.fw_mkgp / r.guider_only);
        if r.fw_mkgp > r.guider_only {
            failures.push(format!("4 s: {r:?}"));
        }
    }
    let queued = at(0.5, 0.1);
    for r in st4_sim::table_with(&cases, &[1.0], queued) {
        println!("0.5 s {}: {r:?}", r.case);
        if r.fw_mkgp != r.guider_only || r.fw_ppec != r.guider_only {
            failures.push(format!("0.5 s: {r:?}"));
        }
    }
    let run = st4_sim::run_with(&cases[0], Firmware::Mkgp, 1.0, 1, queued);
    assert!(run.guiding.backlogs >= 1, "{:?}", run.guiding);
    assert!(failures.is_empty(), "{failures:#?}");
}
