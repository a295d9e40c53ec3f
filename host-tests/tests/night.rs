//! A scripted night through the firmware's loop (`guide-sim night`, issue
//! 27): the default script holds every event a night holds; one night (C5
//! at 1 px, seed 1) runs through, its counters show each event for what it
//! was, and the goals that hold are asserted at the goal (the
//! section goal on C4, whose section after the meridian flip was the one
//! above the guider alone, and the first minutes after the flip on C8);
//! the guider's PHD2 log reads back with the
//! replay's parser, and the logs in `data/night-logs` are what the command
//! writes. The full sweep (C1-C8, 0 and 1 px, seeds 1-3) is the command's
//! (docs/results.md, "A night").

use host_tests::cases::{self, Case};
use host_tests::data::{self, cases_file};
use host_tests::night::goals;
use host_tests::night::ledger::Activity;
use host_tests::night::script::{self, Kind, Way, What, DEFAULT};
use host_tests::night::session::{learner_header, FIRST_S, TRUTH_HEADER};
use host_tests::night::{self, NightRun, MAX_RATE_SIDEREAL};
use host_tests::phd2_log;
use host_tests::st4_sim::Firmware;
use mkgp_mount::model::additions::Additions;
use mkgp_mount::mount::guiding::calibration;
use std::collections::BTreeSet;
use std::path::Path;
use std::sync::OnceLock;

fn case(name: &str) -> Case {
    let cases = cases::load(&cases_file()).unwrap_or_else(|e| panic!("{e}"));
    cases.into_iter().find(|c| c.name == name).unwrap()
}

fn starts() -> Vec<script::Section> {
    DEFAULT
        .iter()
        .filter_map(|e| match e.what {
            What::Start(s) => Some(s),
            _ => None,
        })
        .collect()
}

#[test]
fn the_default_script_holds_every_event_kind() {
    script::check(DEFAULT, MAX_RATE_SIDEREAL as f64).unwrap_or_else(|e| panic!("{e}"));
    assert!(script::length_s(DEFAULT) >= 6.0 * 3600.0);
    let kinds: BTreeSet<Kind> = DEFAULT.iter().map(|e| e.what.kind()).collect();
    assert_eq!(
        kinds,
        Kind::ALL.into_iter().collect(),
        "every kind of event"
    );
    let sections = starts();
    let targets: BTreeSet<&str> = sections.iter().map(|s| s.target).collect();
    assert!(targets.len() >= 5, "{targets:?}");
    // Re-pointed through the port both ways, and by hand.
    for way in [Way::West, Way::East] {
        assert!(DEFAULT
            .iter()
            .any(|e| matches!(e.what, What::Slew { way: w, .. } if w == way)));
    }
    assert!(DEFAULT
        .iter()
        .any(|e| matches!(e.what, What::Push { hours } if hours != 0.0)));
    // Refocus pauses of 2-10 minutes, a 20-minute cloud gap, a star lost
    // for a few frames.
    assert!(DEFAULT.iter().any(
        |e| matches!(e.what, What::Refocus { seconds } if (120.0..=600.0).contains(&seconds))
    ));
    assert!(DEFAULT
        .iter()
        .any(|e| matches!(e.what, What::Clouds { seconds } if seconds >= 1200.0)));
    assert!(DEFAULT
        .iter()
        .any(|e| matches!(e.what, What::LoseStar { frames } if (2..=10).contains(&frames))));
    // Exposures of 1 to 4 s changing between targets, frames further apart
    // than the exposure, dithers and downloads of 10-30 s.
    let exposures: BTreeSet<u64> = sections
        .iter()
        .map(|s| (s.exposure_s * 1000.0) as u64)
        .collect();
    assert_eq!(exposures.first(), Some(&1000));
    assert_eq!(exposures.last(), Some(&4000));
    assert!(exposures.len() >= 3, "{exposures:?}");
    assert!(sections.iter().any(|s| s.interval_s > s.exposure_s));
    assert!(sections.iter().all(|s| s.dither_px > 0.0));
    assert!(sections
        .iter()
        .all(|s| 10.0 <= s.download_s.0 && s.download_s.1 <= 30.0));
    // The guider restarts on the same target with nothing re-pointed.
    let restarted = DEFAULT.windows(2).any(|w| {
        matches!((w[0].what, w[1].what), (What::Stop, What::Start(_))) && {
            let i = DEFAULT
                .iter()
                .rposition(|e| matches!(e.what, What::Start(_)) && e.at_s < w[0].at_s);
            matches!((i.map(|i| DEFAULT[i].what), w[1].what),
                (Some(What::Start(a)), What::Start(b)) if a.target == b.target)
        }
    });
    assert!(restarted, "a restart without re-pointing");
}

/// C5 at 1 px, seed 1: the guider alone (with its PHD2 log) and fw MKGP.
struct TestNight {
    alone: NightRun,
    mkgp: NightRun,
}

fn test_night() -> &'static TestNight {
    static NIGHT: OnceLock<TestNight> = OnceLock::new();
    NIGHT.get_or_init(|| {
        let c = case("C5");
        let run = |fw, log| night::run(&c, fw, 1.0, 1, DEFAULT, Additions::ALL, log).unwrap();
        let (alone, mkgp) = rayon::join(
            || run(Firmware::GuiderOnly, true),
            || run(Firmware::Mkgp, true),
        );
        TestNight { alone, mkgp }
    })
}

#[test]
fn the_night_runs_through_and_the_counters_say_what_happened() {
    let n = test_night();
    for run in [&n.alone, &n.mkgp] {
        assert_eq!(run.sections.len(), starts().len());
        for s in &run.sections {
            assert!(s.all.n > 0 && s.first.n > 0 && s.settled.n > 0, "{s:?}");
            // The later windows are whole FIRST_S of guiding within the
            // settled part, one after another.
            assert!(!s.later.is_empty(), "{s:?}");
            assert!(s.later.iter().all(|w| w.seconds() <= FIRST_S), "{s:?}");
            assert!(
                s.later.iter().map(|w| w.n).sum::<u64>() <= s.settled.n,
                "{s:?}"
            );
        }
        let e = run.extremes;
        assert_eq!(e.non_finite, 0);
        assert!(e.ra_min >= 0.0);
    }
    let m = &n.mkgp;
    let c = m.counters;
    // The firmware takes a pulse longer than its dither threshold for a
    // dither, and nothing else: every dither of the night that long, and
    // each settled without learning for the model's settling frames.
    let threshold = night::dither_threshold_arcsec(&case("C5"));
    let long = m.dithers.iter().filter(|d| d.abs() > threshold).count() as u32;
    assert!(long > 0, "the script's wide dithers");
    assert_eq!(c.guiding.dithers, long, "{:?}", c.guiding);
    assert_eq!(c.learner.dithers, long, "{:?}", c.learner);
    assert!(c.learner.not_learned >= 10 * long, "{:?}", c.learner);
    // Every re-pointing through the port was carried out.
    let slews = DEFAULT
        .iter()
        .filter(|e| matches!(e.what, What::Slew { .. } | What::Flip))
        .count() as u32;
    assert_eq!(c.port.manual_moves, slews, "{:?}", c.port);
    // Nothing of a slew or the flip is learned: the port moved the axis.
    for activity in [Activity::Slew, Activity::Flip] {
        let t = m.tally(activity);
        assert!(t.frames > 0 && t.learned == 0, "{activity:?}: {t:?}");
    }
    // Each calibration is recognised once from its pulses, and from its
    // third equal pulse to the hold after its last nothing is learned: at
    // most its first pulses and the frames filled between them are.
    let calibration = m.tally(Activity::Calibration);
    assert_eq!(calibration.windows as usize, starts().len());
    assert_eq!(
        c.guiding.calibrations, calibration.windows,
        "{:?}",
        c.guiding
    );
    let before_recognised = u32::from(calibration::RUN) + 1;
    assert!(
        calibration.learned <= before_recognised * calibration.windows,
        "{calibration:?}"
    );
    // No fault counter raised by an ordinary night: the model's faults,
    // frames lost between the tasks, feed-forwards refused, time running
    // back, stray pulse ends, edges lost, the ST4 line faults, a port
    // command refused. (The ST4 `glitches` count the guider's pulses
    // shorter than the 1 ms debounce, which PHD2's hysteresis sends when
    // its previous correction nearly cancels the new one; `ra_clamped`
    // counts the port's manual motion, whose RA rate is clamped to [0,
    // max] by design: east at the highest rate stops the axis.)
    let faults = c.faults.expect("the model's faults");
    assert_eq!(faults, Default::default(), "{faults:?}");
    let g = c.guiding;
    assert_eq!(
        (
            g.frames_dropped,
            g.feed_forward_rejected,
            g.time_backwards,
            g.stray_ends,
            g.dec_clamped
        ),
        (0, 0, 0, 0, 0),
        "{g:?}"
    );
    assert_eq!(c.lost_edges, 0);
    let s = c.st4;
    assert_eq!(
        (s.both_lines, s.capped, s.stuck, s.out_of_order, s.dropped),
        (0, 0, 0, 0, 0),
        "{s:?}"
    );
    assert_eq!((c.port.port_refused, c.port.st4_refused), (0, 0));
}

/// The night goals that hold on every night of the sweep, at the
/// goal, on this night: the whole night at most 0.8 x the guider alone on
/// C5-C8 at 1 px, and no section above the guider alone (on C4 below too).
/// A section's first 5 minutes within 1.2 x its settled figure does not
/// hold on every night yet (docs/results.md, "A night"): the command
/// reports it.
#[test]
fn the_goals_that_hold() {
    let n = test_night();
    let whole = n.mkgp.night().rms() / n.alone.night().rms();
    assert!(whole <= goals::WHOLE_NIGHT, "whole night {whole:.3}");
    for (i, ratio) in goals::section_ratios(&n.mkgp, &n.alone).enumerate() {
        assert!(
            goals::meets(ratio, goals::SECTION),
            "section {} {ratio:.3}",
            i + 1
        );
    }
}

/// C4 at 1 px, where the meridian flip and the slews turn the gears
/// through tens of worm turns: the data learned before is placed across
/// them with the worm's period, so a section after one keeps what was
/// learned only while that period is right to a few hundredths of a
/// second. The firmware keeps the mount's own (`configured_worm`), or
/// tracks it that closely (`log_power_peak`). On seeds 1-3 no section is
/// above the guider alone; with neither, a section of seed 2 is.
#[test]
fn after_a_long_re_pointing_no_section_is_above_the_guider_alone() {
    let c = case("C4");
    let worst = |seed, additions| {
        let n = night::night(&c, 1.0, seed, DEFAULT, additions, false).unwrap();
        goals::figures(&n).worst_section
    };
    for seed in 1..=3 {
        let (ratio, section) = worst(seed, Additions::ALL);
        assert!(
            goals::meets(ratio, goals::SECTION),
            "seed {seed}: section {} {ratio:.3}",
            section + 1
        );
    }
    let mut tracked = Additions::ALL;
    tracked.set("configured_worm", false).unwrap();
    tracked.set("log_power_peak", false).unwrap();
    let (ratio, section) = worst(2, tracked);
    assert!(
        !goals::meets(ratio, goals::SECTION),
        "without configured_worm and log_power_peak, seed 2: section {} {ratio:.3}",
        section + 1
    );
}

/// The meridian flip turns the gears through 43,082 s of gear time: C8's
/// 110 s stage comes back off its phase by what its tracked period's error
/// gathers over that, unless the new data finds the phase again
/// (`slew_refine`). The section after the flip (the fourth), C8
/// noise-free, seeds 1-3: its first 5 minutes within the goal on every
/// seed with the addition, above it on one at least without.
#[test]
fn after_the_meridian_flip_the_first_minutes_keep_to_the_goal() {
    let c = case("C8");
    let after_flip = |seed, additions| {
        let run = night::run(&c, Firmware::Mkgp, 0.0, seed, DEFAULT, additions, false).unwrap();
        let section_4 = goals::first_ratios(&run).nth(3).unwrap();
        section_4
    };
    let mut without = Additions::ALL;
    without.set("slew_refine", false).unwrap();
    let mut missed = 0;
    for seed in [1, 2, 3] {
        let (on, off) = (after_flip(seed, Additions::ALL), after_flip(seed, without));
        println!("seed {seed}: {on:.3} on, {off:.3} without slew_refine");
        assert!(goals::meets(on, goals::FIRST), "seed {seed}: {on:.3}");
        missed += usize::from(!goals::meets(off, goals::FIRST));
    }
    assert!(missed > 0, "without slew_refine every seed meets the goal");
}

/// The rows of a log's CSV below its header, as numbers.
fn csv_rows(text: &str) -> Vec<Vec<f64>> {
    text.lines()
        .skip(1)
        .map(|l| l.split(',').map(|f| f.parse().unwrap()).collect())
        .collect()
}

#[test]
fn the_phd2_log_reads_back() {
    let n = test_night();
    let logs = n.alone.logs.as_ref().expect("the guider's log");
    let log = phd2_log::parse(&logs.phd2, Path::new("night.txt")).unwrap_or_else(|e| panic!("{e}"));
    let truth = csv_rows(&logs.truth);
    assert_eq!(logs.truth.lines().next(), Some(TRUTH_HEADER));
    // Every guide row, in order, with its section's time; one section per
    // start, each with its own exposure.
    assert_eq!(log.sections.len(), starts().len());
    let frames: Vec<&phd2_log::GuideRow> = log.sections.iter().flat_map(|s| &s.frames).collect();
    assert_eq!(frames.len(), truth.len());
    for (f, t) in frames.iter().zip(&truth) {
        assert_eq!(f.frame, t[1] as u64);
        assert!((f.time_s - t[2]).abs() < 1e-9, "{f:?} {t:?}");
        // The log's 3 decimals against the truth's 4.
        assert!((f.ra_raw - t[6]).abs() < 6e-4, "{f:?} {t:?}");
    }
    let exposures: Vec<f64> = log.sections.iter().map(|s| s.exposure_s).collect();
    let want: Vec<f64> = starts().iter().map(|s| s.exposure_s).collect();
    assert_eq!(exposures, want);
    // Every dither, its amount as the move of the lock (PHD2's sign), at
    // its row of the night.
    let mut first = 0;
    let mut dithers = Vec::new();
    for s in &log.sections {
        dithers.extend(s.dithers().map(|(next, x, _)| (first + next, x)));
        first += s.frames.len();
    }
    assert_eq!(dithers.len(), n.alone.dithers.len());
    for ((_, x), amount) in dithers.iter().zip(&n.alone.dithers) {
        assert!((x + amount).abs() < 5e-4, "{x} {amount}");
    }
    // The guider measured the truth plus the camera's 1 px noise.
    let dither_rows: BTreeSet<usize> = dithers.iter().map(|&(row, _)| row).collect();
    let noise: Vec<f64> = frames
        .iter()
        .zip(&truth)
        .enumerate()
        .filter(|(i, _)| !dither_rows.contains(i))
        .map(|(_, (f, t))| f.ra_raw - t[5])
        .collect();
    let rms = (noise.iter().map(|x| x * x).sum::<f64>() / noise.len() as f64).sqrt();
    assert!((0.95..1.05).contains(&rms), "noise {rms:.3} px");
    // Sections, calibrations and DROP rows as PHD2 writes them.
    let text = &logs.phd2;
    assert_eq!(
        text.matches("\nCalibration Begins at ").count(),
        starts().len()
    );
    assert_eq!(
        text.matches("\nCalibration complete, mount = ").count(),
        starts().len()
    );
    assert_eq!(text.matches("\nGuiding Ends at ").count(), starts().len());
    assert!(text.contains(",\"DROP\",,,,,,,,,,,,,0,0.00,3,\"Star lost - low mass\"\n"));
    assert!(text.contains("\nINFO: SETTLING STATE CHANGE, Settling complete\n"));
    assert!(text.contains("Pier side = East"), "after the flip");
}

/// The learner's trace (`guide-sim night --trace`): a row per guide row of
/// the MKGP night, in order, each as its header names, counting what the
/// learner took up to the counters at the night's end.
#[test]
fn the_learner_trace_follows_the_guide_rows() {
    let n = test_night();
    let logs = n.mkgp.logs.as_ref().expect("the MKGP night's logs");
    let header = learner_header();
    assert_eq!(logs.learner.lines().next(), Some(header.as_str()));
    let columns = header.split(',').count();
    let rows = csv_rows(&logs.learner);
    let truth = csv_rows(&logs.truth);
    assert_eq!(rows.len(), truth.len());
    let col = |name: &str| header.split(',').position(|c| c == name).unwrap();
    let (frames, learned, gate) = (col("frames"), col("learned"), col("gate_1"));
    for (i, (r, t)) in rows.iter().zip(&truth).enumerate() {
        assert_eq!(r.len(), columns, "row {i}");
        // Section, frame, time and gear time as the truth's row.
        assert_eq!(r[..4], t[..4], "row {i}");
        assert!(r.iter().all(|x| x.is_finite()), "row {i}: {r:?}");
        assert!(r[learned] <= r[frames], "row {i}");
        if let Some(before) = i.checked_sub(1).map(|k| &rows[k]) {
            assert!(r[frames] >= before[frames] && r[learned] >= before[learned]);
        }
        // The worm's gate is 1, every gate within 0..=1.
        assert_eq!(r[gate], 1.0, "row {i}");
        for g in (gate..columns).step_by(2) {
            assert!((0.0..=1.0).contains(&r[g]), "row {i}: {r:?}");
        }
    }
    let last = rows.last().expect("guide rows");
    let c = n.mkgp.counters.learner;
    assert!(last[frames] <= c.frames as f64 && last[learned] <= c.learned as f64);
    assert!(last[learned] > 0.5 * c.learned as f64, "{last:?} {c:?}");
    // The guider alone has no learner: the header alone.
    let alone = &n.alone.logs.as_ref().expect("the guider's log").learner;
    assert_eq!(alone.trim_end(), header);
}

/// The night logs in `data/night-logs`: each is what `guide-sim night`
/// writes for its case, noise and seed (data/README.md), and reads back.
#[test]
fn the_night_logs_in_data_are_the_commands() {
    let dir = data::data_dir().join("night-logs");
    for (name, noise, seed) in [("C5", 1.0, 1), ("C8", 1.0, 2), ("C2", 0.0, 3)] {
        let stem = format!("night_{name}_{noise}px_seed{seed}");
        let read = |ext: &str| {
            let p = dir.join(format!("{stem}.{ext}"));
            std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
        };
        let (phd2, truth) = (read("txt"), read("truth.csv"));
        let logs = if (name, noise, seed) == ("C5", 1.0, 1) {
            test_night().alone.logs.clone().unwrap()
        } else {
            night::run(
                &case(name),
                Firmware::GuiderOnly,
                noise,
                seed,
                DEFAULT,
                Additions::ALL,
                true,
            )
            .unwrap()
            .logs
            .unwrap()
        };
        assert!(
            logs.phd2 == phd2,
            "{stem}.txt is not what the command writes"
        );
        assert!(
            logs.truth == truth,
            "{stem}.truth.csv is not what the command writes"
        );
        let log = phd2_log::parse(&phd2, Path::new(&stem)).unwrap_or_else(|e| panic!("{e}"));
        let frames: usize = log.sections.iter().map(|s| s.frames.len()).sum();
        assert_eq!(frames + 1, truth.lines().count(), "{stem}");
    }
}
