//! The guide-sim binary: CSV headers, errors and exit status.

mod common;

use common::bad_logs::{self, RA_RAW};
use std::path::PathBuf;
use std::process::{Command, Output};

fn guide_sim(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_guide-sim"))
        .args(args)
        .output()
        .expect("run guide-sim")
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("guide-sim-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn table_csv() {
    // One small case keeps this fast also with the model built in.
    let cases = scratch("one_case.csv");
    std::fs::write(
        &cases,
        "case,component,period_s,amplitude_px,phase_rad,drift_px_per_s\nC1,primary,432,9.0,0,\nC1,drift,,,,0.0008\n",
    )
    .unwrap();
    let o = guide_sim(&["table", "--cases", cases.to_str().unwrap(), "--csv"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines[0], "case,noise_px,open_loop,reactive,ppec,mkgp,mkgp3");
    assert_eq!(lines.len(), 3, "{out}");
    assert!(lines[1].starts_with("C1,0,8.634,0.332,"), "{out}");
    assert!(lines[2].starts_with("C1,1,8.634,0.705,"), "{out}");
}

#[test]
fn table_trace_writes_one_run() {
    let trace = scratch("c1_trace.csv");
    let o = guide_sim(&["table", "--trace", trace.to_str().unwrap(), "--case", "C1"]);
    assert!(o.status.success(), "{}", stderr(&o));
    // The table's MKGP3 cell of C1 noise-free (docs/results.md).
    assert!(
        stdout(&o).starts_with("C1 at 0 px, seed 1: MKGP3 residual RMS 0.177 px"),
        "{}",
        stdout(&o)
    );
    let text = std::fs::read_to_string(&trace).unwrap();
    assert_eq!(text.lines().count(), 1 + 5400);
    // Without --trace the case is refused (clap: 2), an unknown case named.
    let o = guide_sim(&["table", "--case", "C1"]);
    assert_eq!(o.status.code(), Some(2));
    let o = guide_sim(&["table", "--trace", trace.to_str().unwrap(), "--case", "C9"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("no case C9"), "{}", stderr(&o));
}

#[test]
fn replay_trace_writes_one_log() {
    let night = "data/phd2-nights/PHD2_GuideLog_2026-01-28_174028.txt";
    let trace = scratch("night_trace.csv");
    let o = guide_sim(&["replay", "--trace", trace.to_str().unwrap(), night]);
    assert!(o.status.success(), "{}", stderr(&o));
    // The replay's MKGP over its 1,897 frames (docs/results.md).
    assert!(
        stdout(&o).contains(": MKGP RMS 0.4563 px over 1897 frames; trace written to"),
        "{}",
        stdout(&o)
    );
    let text = std::fs::read_to_string(&trace).unwrap();
    assert!(text.starts_with("time_s,measured_px,control_px,blend_weight,period_1_s"));
    // One log only (clap's usage code), and a log that cannot be read named.
    let o = guide_sim(&["replay", "--trace", trace.to_str().unwrap(), night, night]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("--trace needs one LOG"),
        "{}",
        stderr(&o)
    );
    let o = guide_sim(&[
        "replay",
        "--trace",
        trace.to_str().unwrap(),
        "/nonexistent.txt",
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("/nonexistent.txt"), "{}", stderr(&o));
}

#[test]
fn table_bad_cases_file() {
    let cases = scratch("bad_cases.csv");
    std::fs::write(
        &cases,
        "case,component,period_s,amplitude_px,phase_rad,drift_px_per_s\nC1,primary,43x,9.0,0,\n",
    )
    .unwrap();
    let o = guide_sim(&["table", "--cases", cases.to_str().unwrap(), "--csv"]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains(&format!("{}:2: period_s", cases.display())),
        "{}",
        stderr(&o)
    );
    assert!(stdout(&o).is_empty());
}

#[test]
fn missing_cases_file_names_the_path() {
    let o = Command::new(env!("CARGO_BIN_EXE_guide-sim"))
        .args([
            "table",
            "--csv",
            "--cases",
            "/nonexistent/synthetic_cases.csv",
        ])
        .output()
        .unwrap();
    assert!(!o.status.success());
    let err = stderr(&o);
    assert!(
        err.contains("/nonexistent/synthetic_cases.csv: cannot read"),
        "{err}"
    );
    assert!(stdout(&o).is_empty());
}

#[test]
fn replay_bad_log_fails_but_others_run() {
    let good = host_tests::data::data_dir().join("phd2-logs/performance_dataset03.txt");
    let bad = scratch("bad.txt");
    std::fs::write(
        &bad,
        "Exposure = 2000 ms\nFrame,Time,mount,dx,dy,RARawDistance,DECRawDistance,RAGuideDistance,\
         DECGuideDistance,RADuration,RADirection,DECDuration,DECDirection,XStep,YStep,StarMass,SNR,ErrorCode\n\
         1,2.250,\"Mount\",0.856,-0.494,-0.899,-0.308,-0.540,0.000,227,E,0,,,,1762,23.05,0\n\
         2,4.1o9,\"Mount\",0.159,-0.340,-0.191,-0.300,-0.115,0.000,48,E,0,,,,1463,21.04,0\n",
    )
    .unwrap();
    let o = guide_sim(&[
        "replay",
        bad.to_str().unwrap(),
        good.to_str().unwrap(),
        "--csv",
    ]);
    assert!(!o.status.success(), "a failed log must fail the run");
    assert!(
        stderr(&o).contains(&format!("{}:4: Time", bad.display())),
        "{}",
        stderr(&o)
    );
    let out = stdout(&o);
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(
        lines[0],
        "log,frames,hysteresis_rms,ppec_rms,mkgp_rms,ppec_gain_pct,mkgp_gain_pct"
    );
    assert_eq!(lines.len(), 2, "{out}");
    assert!(
        lines[1].starts_with("performance_dataset03,664,0.1588,"),
        "{out}"
    );
}

/// Issue 27: `--per-section` prints a row per section of a night, then the
/// whole log's; a log of one section gets one row of each, alike.
#[test]
fn replay_per_section_prints_each_section_then_the_log() {
    let one = host_tests::data::data_dir().join("phd2-logs/performance_dataset03.txt");
    let night = host_tests::data::night_logs().unwrap().remove(0);
    let o = guide_sim(&[
        "replay",
        one.to_str().unwrap(),
        night.to_str().unwrap(),
        "--csv",
        "--per-section",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(
        lines[0],
        "log,section,line,start_s,frames,exposure_s,time_step_s,hysteresis_rms,ppec_rms,\
         mkgp_rms,ppec_gain_pct,mkgp_gain_pct,ppec_alone_gain_pct,mkgp_alone_gain_pct"
    );
    assert!(lines[1].starts_with("performance_dataset03,1,1,0,664,3.000,3.000,0.1588,"));
    let whole: Vec<&str> = lines[2].split(',').collect();
    assert_eq!(
        &whole[..5],
        &["performance_dataset03", "all", "", "", "664"]
    );
    // The section's figures are the log's.
    let section: Vec<&str> = lines[1].split(',').collect();
    assert_eq!(&section[7..], &whole[7..]);
    let night_rows = lines[3..].len();
    assert!(night_rows > 10, "{out}");
    assert!(lines.last().unwrap().contains(",all,"), "{out}");
    // Without --csv, the goals follow each log.
    let o = guide_sim(&["replay", one.to_str().unwrap(), "--per-section"]);
    assert!(
        stdout(&o).contains("goals: MKGP gain 12.32 %"),
        "{}",
        stdout(&o)
    );
}

/// Issue 26, item 5: each of these logs was replayed into absurd figures
/// with exit status 0. Each is now a bad log: status 1, `file:line: what`
/// on stderr, no row on stdout.
#[test]
fn replay_of_absurd_values_fails_naming_file_and_line() {
    for (name, bad) in [
        ("raw_1e300", bad_logs::value(RA_RAW, "1e300")),
        ("dither_1e300", bad_logs::dither("1e300")),
        ("raw_1e6_in_12_rows", bad_logs::raw_1e6_in_12_rows()),
        ("time_backwards", bad_logs::time_backwards()),
        ("exposure_1e300", bad_logs::exposure_1e300()),
    ] {
        let path = scratch(&format!("{name}.txt"));
        std::fs::write(&path, &bad.text).unwrap();
        let o = guide_sim(&["replay", path.to_str().unwrap(), "--csv"]);
        assert_eq!(o.status.code(), Some(1), "{name}: {}", stdout(&o));
        let at = format!("{}:{}: ", path.display(), bad.line);
        assert!(stderr(&o).contains(&at), "{name}: {}", stderr(&o));
        assert_eq!(stdout(&o).lines().count(), 1, "{name}: {}", stdout(&o));
    }
}

/// A usage error: exit status 2 (clap's), nothing on stdout, and stderr
/// names `what` and shows the usage line of `usage`.
fn assert_usage_error(o: &Output, what: &str, usage: &str) {
    assert_eq!(o.status.code(), Some(2), "{}", stderr(o));
    assert!(stdout(o).is_empty(), "{}", stdout(o));
    let err = stderr(o);
    assert!(err.contains(what), "{err}");
    assert!(err.contains(&format!("Usage: {usage}")), "{err}");
}

#[test]
fn unknown_subcommand_is_a_usage_error() {
    let o = guide_sim(&["frobnicate"]);
    assert_usage_error(&o, "'frobnicate'", "guide-sim <COMMAND>");
}

/// Subcommands the usage and the help must name.
const SUBCOMMANDS: [&str; 8] = [
    "table",
    "replay",
    "bench",
    "st4",
    "nights",
    "night",
    "population",
    "ablate",
];

#[test]
fn no_subcommand_is_a_usage_error() {
    let o = guide_sim(&[]);
    assert_eq!(o.status.code(), Some(2));
    for sub in SUBCOMMANDS {
        assert!(stderr(&o).contains(sub), "{}", stderr(&o));
    }
}

#[test]
fn bench_unknown_option_is_a_usage_error() {
    // Only the argument check: the bench itself is timing-dependent and
    // runs QEMU, so no test runs it (test.sh prints its figures).
    let o = guide_sim(&["bench", "--frobnicate"]);
    assert_usage_error(&o, "'--frobnicate'", "guide-sim bench");
}

#[test]
fn replay_unknown_option_is_a_usage_error() {
    let o = guide_sim(&["replay", "--frobnicate"]);
    assert_usage_error(&o, "'--frobnicate'", "guide-sim replay");
}

#[test]
fn option_without_its_value_is_a_usage_error() {
    let o = guide_sim(&["table", "--cases"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("'--cases <FILE>'"), "{}", stderr(&o));
}

#[test]
fn st4_noise_must_be_a_number_of_px() {
    for bad in ["-1", "x", "inf", "NaN"] {
        let o = guide_sim(&["st4", "--noise", bad]);
        assert_eq!(o.status.code(), Some(2), "--noise {bad}");
        let err = stderr(&o);
        assert!(
            err.contains(&format!("'{bad}' for '--noise <PX>'")) && err.contains(">= 0"),
            "{err}"
        );
    }
}

#[test]
fn st4_guider_settings_must_be_in_range() {
    for (flag, bad) in [
        ("--aggressiveness", "1.5"),
        ("--aggressiveness", "0"),
        ("--exposure", "0"),
        ("--min-move", "11"),
        ("--calibration", "NaN"),
    ] {
        let o = guide_sim(&["st4", flag, bad]);
        assert_eq!(o.status.code(), Some(2), "{flag} {bad}");
        let err = stderr(&o);
        assert!(
            err.contains(&format!("'{bad}' for '{flag}")) && err.contains("needs a number from"),
            "{err}"
        );
    }
}

#[test]
fn each_subcommand_help_lists_its_options() {
    for (sub, options) in [
        (
            "table",
            &["--cases <FILE>", "--csv", "--without <NAME>"][..],
        ),
        (
            "replay",
            &["[LOG]...", "--csv", "--per-section", "--trace <FILE>"],
        ),
        ("bench", &["--csv", "--host-only"]),
        (
            "st4",
            &[
                "--case <ID>",
                "--cases <FILE>",
                "--noise <PX>",
                "--csv",
                "--aggressiveness <A>",
                "--exposure <S>",
                "--min-move <PX>",
                "--calibration <K>",
                "--without <NAME>",
            ],
        ),
        (
            "nights",
            &[
                "--case <ID>",
                "--cases <FILE>",
                "--noise <PX>",
                "--park",
                "--csv",
                "--without <NAME>",
            ],
        ),
        (
            "night",
            &[
                "--case <ID>",
                "--cases <FILE>",
                "--noise <PX>",
                "--seed <N>",
                "--csv",
                "--phd2-log <FILE>",
                "--truth <FILE>",
                "--trace <FILE>",
                "--without <NAME>",
            ],
        ),
        (
            "population",
            &["--seed <S>", "--count <N>", "--csv", "--without <NAME>"],
        ),
        ("ablate", &["--seed <S>", "--count <N>", "--only <NAME>"]),
    ] {
        let o = guide_sim(&[sub, "--help"]);
        assert!(o.status.success(), "{sub}: {}", stderr(&o));
        let out = stdout(&o);
        assert!(out.contains(&format!("Usage: guide-sim {sub}")), "{out}");
        for option in options {
            assert!(out.contains(option), "{sub} --help lacks {option}:\n{out}");
        }
    }
}

#[test]
fn a_population_of_no_mount_is_a_usage_error() {
    let o = guide_sim(&["population", "--count", "0"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stdout(&o).is_empty());
}

#[test]
fn an_ablation_of_an_unknown_addition_is_a_usage_error() {
    let o = guide_sim(&["ablate", "--only", "frobnicate"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(
        err.contains("'frobnicate' for '--only <NAME>'") && err.contains("measured_subset"),
        "{err}"
    );
    assert!(stdout(&o).is_empty());
    let o = guide_sim(&["ablate", "--count", "1"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
}

#[test]
fn a_night_log_needs_one_night() {
    // Refused before any night runs: every seed of C1 would write one file.
    let o = guide_sim(&[
        "night",
        "--case",
        "C1",
        "--noise",
        "1",
        "--phd2-log",
        "/nonexistent/x.txt",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("need one night"), "{}", stderr(&o));
    assert!(stdout(&o).is_empty());
}

#[test]
fn help_lists_the_subcommands() {
    let o = guide_sim(&["--help"]);
    assert!(o.status.success());
    let out = stdout(&o);
    for sub in SUBCOMMANDS {
        assert!(out.contains(&format!("  {sub} ")), "{out}");
    }
}

#[test]
fn a_repeated_option_takes_its_last_value() {
    let o = guide_sim(&[
        "table",
        "--cases",
        "/nonexistent/first.csv",
        "--cases",
        "/nonexistent/second.csv",
        "--csv",
        "--csv",
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("/nonexistent/second.csv: cannot read"),
        "{}",
        stderr(&o)
    );
}
