//! guide-sim: the paper's synthetic table, PHD2-log replays, the cost of a
//! guide frame and the firmware's ST4 closed loop.
//!
//! ```text
//! guide-sim table [--cases FILE] [--csv] [--without NAME]...
//!                 [--trace FILE --case ID [--noise PX] [--seed N]]
//! guide-sim replay [LOG...] [--csv] [--per-section] [--trace FILE]
//! guide-sim bench [--csv] [--host-only]
//! guide-sim st4 [--case ID] [--cases FILE] [--noise PX] [--csv]
//!               [--aggressiveness A] [--exposure S] [--min-move PX] [--calibration K]
//!               [--drift A] [--walk W] [--bump B] [--least-pulse-share F]
//!               [--without NAME]...
//! guide-sim nights [--case ID] [--cases FILE] [--noise PX] [--park] [--calibrate] [--csv]
//!                  [--without NAME]...
//! guide-sim night [--case ID] [--cases FILE] [--noise PX] [--seed N] [--csv]
//!                 [--phd2-log FILE] [--truth FILE] [--trace FILE] [--without NAME]...
//! guide-sim mount [--pty PATH] [--tcp PORT] [--case ID] [--cases FILE] [--noise PX]
//!                 [--speed X] [--no-st4-guider]
//! guide-sim view (--port DEVICE | --pty PATH | --tcp HOST:PORT) [--listen ADDR:PORT]
//! guide-sim population [--seed S] [--count N | --mount K...] [--csv]
//!                     [--without NAME]...
//! guide-sim ablate [--seed S] [--count N] [--only NAME]...
//! ```
//! `guide-sim <subcommand> --help` describes each; the arguments are
//! parsed by clap (usage errors exit with 2).

use clap::{Args, Parser, Subcommand};
use host_tests::bench::{self, BenchRow, TargetRun};
use host_tests::cases;
use host_tests::data::{self, Error};
use host_tests::phd2_log::{self, GuideLog};
use host_tests::replay::{self, report};
use host_tests::{ablation, mount_sim, night, nights, population, st4_sim};
use host_tests::{svg, table};
use rayon::prelude::*;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};

/// The paper's synthetic table, PHD2-log replays, the cost of a guide frame
/// and the firmware's ST4 closed loop.
#[derive(Parser)]
#[command(
    name = "guide-sim",
    // As before clap: a repeated option takes its last value.
    args_override_self = true,
    after_help = "The data (cases, PHD2 logs) is read from host-tests/data in the repository."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Residual RMS of the synthetic cases: open loop, reactive, ppec, mkgp, mkgp3
    ///
    /// Residual RMS (px, t >= 3600 s) of the synthetic cases for the open loop,
    /// reactive (hysteresis 0.6), ppec (GP, 1 stage), mkgp (GP, 2 stages) and
    /// mkgp3 (GP, 3 stages), noise-free and with 1 px noise (mean of seeds 1-3). Without --csv also
    /// writes the bar chart guide-sim-table.svg in the current directory.
    #[command(verbatim_doc_comment)]
    Table(TableArgs),
    /// PHD2's causal replay of guide logs: hysteresis vs ppec and mkgp
    ///
    /// PHD2's causal replay of guide logs (default: all logs in
    /// host-tests/data/phd2-logs and host-tests/data/phd2-nights):
    /// hysteresis 0.7 baseline vs ppec and mkgp (control gain 0.7, prediction
    /// gain 0.5), section by section with the model carried across (a time
    /// step of the exposure, or of the frames' cadence where they come
    /// 1.5 exposures apart or more; frames without a star and pauses told).
    /// A value no guide log can hold fails that log (file:line); a star PHD2
    /// would have lost (beyond its search region) is a dropped frame.
    /// --per-section: a row per section (within the night, and replayed
    /// alone), then the whole log's, and without --csv the goals.
    #[command(verbatim_doc_comment)]
    Replay(ReplayArgs),
    /// Cost of one guide frame of the GP guider: host time, Cortex-M4 instructions
    ///
    /// Cost of one guide frame of the GP guider in the closed loop on case C8
    /// with 1 px noise (seed 1), over the frames t >= 1200 s: host time per
    /// frame (median, p90) in f64 and f32 for 1, 2 and 3 stages, and for f32 the
    /// instructions per frame on an emulated Cortex-M4 (median, max; QEMU runs
    /// target-tests' bench binary, about a minute) and the bytes of model
    /// state. Takes no files but the cases file.
    #[command(verbatim_doc_comment)]
    Bench(BenchArgs),
    /// The firmware's closed loop: ST4 pulses through St4, Guiding and Learner
    ///
    /// The firmware's closed loop: a virtual mount whose RA error is a synthetic
    /// case, a camera exposing every 2 s, a PHD2-like hysteresis guider (0.7, 0.1,
    /// min move 0.2) sending ST4 pulses at 0.5x sidereal through the firmware's
    /// St4 and Guiding; guider only, guider + firmware PPEC (Learner<1>) and
    /// guider + firmware MKGP (Learner<FIRMWARE_STAGES>, three stages). Pointing RMS (arcsec = px) over
    /// t >= 3600 s of 3 h runs; noise 0 and 1 px (seeds 1-3, mean) unless
    /// --noise PX picks one level; --case ID runs one case. The guider's
    /// aggressiveness, exposure, minimum move and calibration (its believed
    /// guide rate over the true one) can differ from what the firmware
    /// assumes (0.7, 2 s): how much a wrong guess costs.
    #[command(verbatim_doc_comment)]
    St4(St4Args),
    /// The learned model across a power cycle: night 1, then night 2 cold or restored
    ///
    /// The firmware's closed loop as in `st4` (MKGP firmware): night 1 guides
    /// 3 h from a cold model; its model is saved to bytes and restored into a
    /// fresh learner (the step counter starts again); night 2 starts with the
    /// gear at a phase drawn from the seed, cold, restored without an index
    /// (phase unknown) and restored with the index or from park (phase
    /// known). Pointing RMS (arcsec = px): settled = night 1's hours 1-3, the
    /// others night 2's first 30 minutes. Noise 0 and 1 px (seeds 1-3, mean)
    /// unless --noise PX picks one level; --case ID runs one case. Night 2
    /// starts with the gear moved (the index gives the worm's phase) or,
    /// with --park, where night 1 parked it (every phase carries over);
    /// with --calibrate it starts with the guider's calibration (PHD2's),
    /// and its 30 minutes are scored from the calibration's end.
    #[command(verbatim_doc_comment)]
    Nights(NightsArgs),
    /// A scripted night of many sections through the firmware's loop
    ///
    /// The firmware's closed loop as in `st4` (mount raised to 90x sidereal at
    /// most, for the flip) through a scripted night of 6 h 40 min
    /// (host-tests/src/night/script.rs, DEFAULT): five targets, seven guiding
    /// sections, each with a calibration at its start and a guider that
    /// remembers nothing of the one before, re-pointing through the command port
    /// (both ways) and by hand with the clutch released, a meridian flip,
    /// exposures of 1-4 s and frame intervals longer than them, dithers and
    /// settling, downloads (10-30 s), refocus pauses, a star lost, 20 minutes of
    /// clouds. Pointing RMS (arcsec = px) while the main camera images, per
    /// section, for the whole night, and for each section's first 5 minutes,
    /// for the guider alone, fw PPEC and fw MKGP; then the goals, and per
    /// section how many first and later 5 minutes are above the first
    /// minutes' bar (the spread that bar meets anywhere). Default: C1-C8,
    /// noise 0 and 1 px, seeds 1-3 (48 nights, progress on stderr); --case,
    /// --noise and --seed pick one. One night prints its sections and what the
    /// firmware counted. --phd2-log FILE (one night) writes the guider alone's
    /// side as a PHD2 guide log, --truth FILE the true gear error per guide row,
    /// --trace FILE what fw MKGP's learner holds after each guide row.
    #[command(verbatim_doc_comment)]
    Night(NightArgs),
    /// A virtual mount for LX200 clients: the firmware's loop on a pty, in real time
    ///
    /// The firmware's loop (ControlLoop, Learner<FIRMWARE_STAGES>, the step generators, as in
    /// `st4`) on a virtual mount whose RA error is a synthetic case (default
    /// C1), in real time (or --speed X times it), with the command port (LX200
    /// and our `:~` commands, docs/port.md) served on a pseudo-terminal linked
    /// at PATH and/or a TCP port on 127.0.0.1. The rig's own simulated camera
    /// and PHD2-like guider pulse its ST4 input, so that it learns with no
    /// client guiding; --no-st4-guider leaves the guiding to the port's client.
    /// Prints one line when ready; runs until SIGINT or SIGTERM, then removes
    /// the link.
    #[command(verbatim_doc_comment)]
    Mount(MountArgs),
    /// A live web page of what the mount learns, from its telemetry
    ///
    /// Connects to the command port of a board (--port, a serial device set to
    /// 9600 8N1) or of the virtual mount (--pty, --tcp), checks that it is
    /// mkgp-mount (:GVP#, :~V#), switches its telemetry on (:~T1#), asks for the
    /// counters every 3 s and serves a page at --listen that updates live: the
    /// pointing error over time, the gear error over the worm's phase with each
    /// stage's share, its spectrum with the stages marked, learning and counters;
    /// the session saves as CSV and the charts as SVG or PNG. Everything is served
    /// from this binary. Prints one line with the URL; runs until SIGINT or SIGTERM.
    #[command(verbatim_doc_comment)]
    View(ViewArgs),
    /// Mounts drawn from physical ranges, through the model's loop and the firmware's
    ///
    /// Draws --count mounts from the ranges of host-tests/src/population/ranges.rs
    /// (docs/results.md, "A population of mounts"): a worm of 90-360 teeth with
    /// harmonics (sometimes amplitude-modulated), 0-3 further gears or belts with
    /// harmonics (one sometimes fading), a polar drift, a random walk, a seeing
    /// and an exposure of 1-4 s. Runs each, noise-free and at its seeing (mean of
    /// three seeds), through the model's closed loop as `table` (reactive, ppec,
    /// mkgp) and the firmware's as `st4` (guider only, fw ppec, fw mkgp); prints
    /// a row per mount and noise level with its drawn parameters, then the
    /// summary: median, 90th percentile and worst ratio to the reactive guider
    /// (model) and to the guider alone (firmware), and how many mounts are worse.
    /// --csv: the rows on stdout, the summary on stderr. Progress on stderr.
    /// Seed 28 is the development seed (the tests, docs/results.md); others are
    /// for evaluation. About 12 s of CPU per mount (22 minutes for 200 on 2 cores).
    #[command(verbatim_doc_comment)]
    Population(PopulationArgs),
    /// What each addition around the paper's model is worth
    ///
    /// Runs --count mounts of the population (noise-free and at each mount's
    /// seeing, its first run seed only), the paper's cases C1-C8 at 0 and 1 px and
    /// the PHD2 logs of host-tests/data with every addition on, then with each one
    /// switched off in turn (--only: just those). The learner's additions are run
    /// in the firmware's loop (fw mkgp over the guider alone), the restore's and
    /// the saved share across a power cycle (as `nights`, the gear moved while
    /// off: night 2's first 30 min restored, the mean of without and with the
    /// index, over cold; about 3 s of CPU per mount), the model's in the
    /// model's (mkgp over the reactive guider). Prints per addition and noise
    /// level the mounts' ratios with it off, the change in median and worst
    /// against all on (positive: the addition pays) with its spread (the bootstrap
    /// standard deviation over redrawn mounts), whether it pays, the mean ratio
    /// on the paper's cases and the logs' gains over hysteresis (docs/model.md,
    /// "Additions and their worth"). Progress on stderr. About 2 s of CPU per
    /// mount and addition.
    #[command(verbatim_doc_comment)]
    Ablate(AblateArgs),
}

#[derive(Args)]
struct AblateArgs {
    /// The population's seed (28: the development seed; seeds below 2^32
    /// share no mount)
    #[arg(long, value_name = "S", default_value_t = population::DEVELOPMENT_SEED,
          value_parser = clap::value_parser!(u64).range(..1 << 32))]
    seed: u64,
    /// How many mounts (the issue's bar: at least 100)
    #[arg(long, value_name = "N", default_value_t = 100,
          value_parser = clap::value_parser!(u64).range(2..=100_000))]
    count: u64,
    /// Only this addition (repeatable); all of them by default
    #[arg(long, value_name = "NAME", value_parser = addition_name)]
    only: Vec<String>,
}

#[derive(Args)]
struct PopulationArgs {
    /// The population's seed (28: the development seed; seeds below 2^32
    /// share no mount)
    #[arg(long, value_name = "S", default_value_t = population::DEVELOPMENT_SEED,
          value_parser = clap::value_parser!(u64).range(..1 << 32))]
    seed: u64,
    /// How many mounts
    #[arg(long, value_name = "N", default_value_t = 200,
          value_parser = clap::value_parser!(u64).range(1..=100_000))]
    count: u64,
    /// Only mount K of the seed (repeatable), as a run of any --count
    /// draws it: a row of a long run, again
    #[arg(long = "mount", value_name = "K", conflicts_with = "count",
          value_parser = clap::value_parser!(u64).range(1..=100_000))]
    mounts: Vec<u64>,
    /// Print the rows as CSV (the summary goes to stderr)
    #[arg(long)]
    csv: bool,
    /// Switch off this addition around the paper's model, in every column
    /// of both loops (repeatable; `ablate --help`)
    #[arg(long, value_name = "NAME", value_parser = addition_name)]
    without: Vec<String>,
}

#[derive(Args)]
#[command(group(clap::ArgGroup::new("target").required(true).args(["port", "pty", "tcp"])))]
struct ViewArgs {
    /// A board's serial port (USB serial or UART), e.g. /dev/ttyACM0
    #[arg(long, value_name = "DEVICE")]
    port: Option<PathBuf>,
    /// The virtual mount's pty link (guide-sim mount --pty PATH)
    #[arg(long, value_name = "PATH")]
    pty: Option<PathBuf>,
    /// The virtual mount's TCP port (guide-sim mount --tcp PORT)
    #[arg(long, value_name = "HOST:PORT")]
    tcp: Option<String>,
    /// Where the page is served (port 0: any free port)
    #[arg(long, value_name = "ADDR:PORT", default_value = "127.0.0.1:8080")]
    listen: String,
}

#[derive(Args)]
struct MountArgs {
    /// Serve the port on a pty linked at PATH
    #[arg(long, value_name = "PATH", required_unless_present = "tcp")]
    pty: Option<PathBuf>,
    /// Serve the port on 127.0.0.1:PORT (0: any free port)
    #[arg(long, value_name = "PORT")]
    tcp: Option<u16>,
    /// The case of the RA error
    #[arg(long, value_name = "ID", default_value = "C1")]
    case: String,
    /// The synthetic cases [default: host-tests/data/synthetic_cases.csv]
    #[arg(long, value_name = "FILE")]
    cases: Option<PathBuf>,
    /// Noise of the simulated guide camera, px
    #[arg(long, value_name = "PX", value_parser = noise_px, default_value = "0")]
    noise: f64,
    /// Simulated time runs X times real time
    #[arg(long, value_name = "X", value_parser = in_range(0.01, 1000.0), default_value = "1")]
    speed: f64,
    /// Switch off the rig's own camera and guider: only the port's client guides
    #[arg(long)]
    no_st4_guider: bool,
}

#[derive(Args)]
struct TableArgs {
    /// The synthetic cases [default: host-tests/data/synthetic_cases.csv]
    #[arg(long, value_name = "FILE")]
    cases: Option<PathBuf>,
    /// Print the table as CSV (and write no bar chart)
    #[arg(long)]
    csv: bool,
    /// Switch off this addition around the paper's model (repeatable; `ablate --help`)
    #[arg(long, value_name = "NAME", value_parser = addition_name)]
    without: Vec<String>,
    /// In place of the table, one run of MKGP3 (three stages, as the
    /// firmware) on --case: write what the model holds after each frame as
    /// CSV (the error it was given, its control and blend weight, each
    /// stage's period and gate) and print the run's residual RMS
    #[arg(long, value_name = "FILE", requires = "case")]
    trace: Option<PathBuf>,
    /// The case of --trace
    #[arg(long, value_name = "ID", requires = "trace")]
    case: Option<String>,
    /// The noise of --trace, px
    #[arg(long, value_name = "PX", value_parser = noise_px, default_value = "0", requires = "trace")]
    noise: f64,
    /// The noise's seed for --trace (the table's 1 px figure is the mean of seeds 1-3)
    #[arg(long, value_name = "N", default_value = "1", requires = "trace")]
    seed: u64,
}

#[derive(Args)]
struct ReplayArgs {
    /// PHD2 guide logs [default: all logs in host-tests/data/phd2-logs and
    /// host-tests/data/phd2-nights]
    #[arg(value_name = "LOG")]
    logs: Vec<PathBuf>,
    /// Print the results as CSV
    #[arg(long)]
    csv: bool,
    /// A row per guiding section, then the whole log's
    #[arg(long)]
    per_section: bool,
    /// Write what MKGP holds after each frame of the one LOG as CSV: the
    /// error it was given, its control and blend weight, each stage's
    /// period and gate (time on the log's clock, as --per-section's
    /// start_s)
    #[arg(long, value_name = "FILE")]
    trace: Option<PathBuf>,
}

#[derive(Args)]
struct BenchArgs {
    /// Print the rows as CSV
    #[arg(long)]
    csv: bool,
    /// Skip the Cortex-M4 bench in QEMU
    #[arg(long)]
    host_only: bool,
}

#[derive(Args)]
struct St4Args {
    #[command(flatten)]
    runs: RunsArgs,
    /// The guider's aggressiveness (the firmware assumes 0.7)
    #[arg(long, value_name = "A", value_parser = in_range(0.05, 1.0), default_value = "0.7")]
    aggressiveness: f64,
    /// The guider's exposure and cycle, s (the firmware assumes 2)
    #[arg(long, value_name = "S", value_parser = in_range(0.1, 60.0), default_value = "2")]
    exposure: f64,
    /// The guider's minimum move, px
    #[arg(long, value_name = "PX", value_parser = in_range(0.0, 10.0), default_value = "0.2")]
    min_move: f64,
    /// The guide rate the guider's calibration found over the true one
    #[arg(long, value_name = "K", value_parser = in_range(0.1, 10.0), default_value = "1")]
    calibration: f64,
    /// A constant RA drift of the star, arcsec per minute
    #[arg(long, value_name = "A", value_parser = in_range(-100.0, 100.0), default_value = "0")]
    drift: f64,
    /// A random walk of the star, arcsec per square root of a minute
    #[arg(long, value_name = "W", value_parser = in_range(0.0, 100.0), default_value = "0")]
    walk: f64,
    /// A bump: the star steps by this many arcsec at 900 s, back at 1800 s, and so on
    #[arg(long, value_name = "B", value_parser = in_range(-100.0, 100.0), default_value = "0")]
    bump: f64,
    /// The firmware's least share of a guide pulse (1: every pulse in full)
    #[arg(long, value_name = "F", value_parser = in_range(0.1, 1.0), default_value = "0.2")]
    least_pulse_share: f64,
    /// Switch off this addition around the paper's model (repeatable; `ablate --help`)
    #[arg(long, value_name = "NAME", value_parser = addition_name)]
    without: Vec<String>,
}

/// A parser of an addition's name (`mkgp_mount::model::additions`).
fn addition_name(s: &str) -> Result<String, String> {
    use mkgp_mount::model::additions::Additions;
    if Additions::acts(s).is_some() {
        Ok(s.to_string())
    } else {
        Err(format!(
            "no addition is called that (they are: {})",
            Additions::NAMES
                .iter()
                .map(|(n, _)| *n)
                .collect::<Vec<_>>()
                .join(", ")
        ))
    }
}

/// Every addition but `without`.
fn additions_without(without: &[String]) -> mkgp_mount::model::additions::Additions {
    let mut a = mkgp_mount::model::additions::Additions::ALL;
    for name in without {
        // The names were checked by `addition_name`.
        let _ = a.set(name, false);
    }
    a
}

/// A parser of numbers in [lo, hi].
fn in_range(lo: f64, hi: f64) -> impl Fn(&str) -> Result<f64, String> + Clone {
    move |s| match s.parse::<f64>() {
        Ok(x) if x >= lo && x <= hi => Ok(x),
        _ => Err(format!("needs a number from {lo} to {hi}")),
    }
}

/// The cases and noise levels of a closed-loop table.
#[derive(Args)]
struct RunsArgs {
    /// Run only the case ID
    #[arg(long, value_name = "ID")]
    case: Option<String>,
    /// The synthetic cases [default: host-tests/data/synthetic_cases.csv]
    #[arg(long, value_name = "FILE")]
    cases: Option<PathBuf>,
    /// One noise level, px [default: 0 and 1]
    #[arg(long, value_name = "PX", value_parser = noise_px, allow_negative_numbers = true)]
    noise: Option<f64>,
    /// Print the table as CSV
    #[arg(long)]
    csv: bool,
}

#[derive(Args)]
struct NightsArgs {
    #[command(flatten)]
    runs: RunsArgs,
    /// Night 2 starts where night 1 parked the gear (default: moved to a
    /// phase drawn from the seed)
    #[arg(long)]
    park: bool,
    /// Night 2 starts with the guider's calibration (PHD2's), scored from
    /// its end
    #[arg(long)]
    calibrate: bool,
    /// Switch off this addition around the paper's model (repeatable; `ablate --help`)
    #[arg(long, value_name = "NAME", value_parser = addition_name)]
    without: Vec<String>,
}

#[derive(Args)]
struct NightArgs {
    #[command(flatten)]
    runs: RunsArgs,
    /// One seed [default: 1, 2 and 3]
    #[arg(long, value_name = "N")]
    seed: Option<u64>,
    /// Write the guider alone's side as a PHD2 guide log (one night only)
    #[arg(long, value_name = "FILE")]
    phd2_log: Option<PathBuf>,
    /// Write the true gear error per guide row of that log as CSV (one night only)
    #[arg(long, value_name = "FILE")]
    truth: Option<PathBuf>,
    /// Write what fw MKGP's learner holds after each guide row as CSV: its
    /// shares and weights, the frames it learned, each stage's period and
    /// gate (one night only)
    #[arg(long, value_name = "FILE")]
    trace: Option<PathBuf>,
    /// Switch off this addition around the paper's model (repeatable; `ablate --help`)
    #[arg(long, value_name = "NAME", value_parser = addition_name)]
    without: Vec<String>,
}

fn noise_px(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(x) if x.is_finite() && x >= 0.0 => Ok(x),
        _ => Err("needs a number of px >= 0".to_string()),
    }
}

fn main() -> ExitCode {
    match Cli::parse().command {
        Command::Table(args) => cmd_table(args),
        Command::Replay(args) => cmd_replay(args),
        Command::Bench(args) => cmd_bench(args),
        Command::St4(args) => cmd_st4(args),
        Command::Nights(args) => cmd_nights(args),
        Command::Night(args) => cmd_night(args),
        Command::Mount(args) => cmd_mount(args),
        Command::View(args) => cmd_view(args),
        Command::Population(args) => cmd_population(args),
        Command::Ablate(args) => cmd_ablate(args),
    }
}

/// Set by SIGINT and SIGTERM: `guide-sim mount` ends cleanly.
static STOP: AtomicBool = AtomicBool::new(false);

extern "C" fn on_signal(_: libc::c_int) {
    // Only an atomic store: async-signal-safe.
    STOP.store(true, Ordering::SeqCst);
}

/// SIGINT and SIGTERM set [`STOP`].
fn stop_on_signals() {
    let handler = on_signal as extern "C" fn(libc::c_int) as libc::sighandler_t;
    // SAFETY: the handler only stores to an atomic.
    unsafe {
        libc::signal(libc::SIGINT, handler);
        libc::signal(libc::SIGTERM, handler);
    }
}

/// Prints a ready line at once (a test or script waits for it).
fn print_ready(line: &str) {
    println!("{line}");
    let _ = std::io::stdout().flush();
}

fn cmd_view(args: ViewArgs) -> ExitCode {
    use host_tests::view::link::Target;
    let target = match (args.port, args.pty, args.tcp) {
        (Some(p), _, _) => Target::Serial(p),
        (_, Some(p), _) => Target::Pty(p),
        (_, _, Some(a)) => Target::Tcp(a),
        // clap's group requires one.
        (None, None, None) => unreachable!(),
    };
    stop_on_signals();
    match host_tests::view::run(target, &args.listen, &STOP, print_ready) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("guide-sim view: {}: {e}", args.listen);
            ExitCode::FAILURE
        }
    }
}

fn cmd_mount(args: MountArgs) -> ExitCode {
    let Some((path, cases)) = load_cases(args.cases) else {
        return ExitCode::FAILURE;
    };
    let Some(case) = cases.into_iter().find(|c| c.name == args.case) else {
        eprintln!("guide-sim: {}: no case {}", path.display(), args.case);
        return ExitCode::FAILURE;
    };
    stop_on_signals();
    let opts = mount_sim::Options {
        case,
        noise_px: args.noise,
        pty: args.pty,
        tcp: args.tcp,
        speed: args.speed,
        st4_guider: !args.no_st4_guider,
    };
    match mount_sim::serve(opts, &STOP, print_ready) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("guide-sim mount: {e}");
            ExitCode::FAILURE
        }
    }
}

/// The cases of `--cases FILE`, or of host-tests/data; an error is printed.
fn load_cases(path: Option<PathBuf>) -> Option<(PathBuf, Vec<cases::Case>)> {
    let path = path.unwrap_or_else(data::cases_file);
    match cases::load(&path) {
        Ok(c) => Some((path, c)),
        Err(e) => {
            eprintln!("guide-sim: {e}");
            None
        }
    }
}

fn cmd_table(
    TableArgs {
        cases,
        csv,
        without,
        trace,
        case,
        noise,
        seed,
    }: TableArgs,
) -> ExitCode {
    let Some((_, cases)) = load_cases(cases) else {
        return ExitCode::FAILURE;
    };
    if let (Some(path), Some(id)) = (trace, case) {
        let Some(case) = cases.iter().find(|c| c.name == id) else {
            eprintln!("guide-sim table: no case {id} in the cases file");
            return ExitCode::FAILURE;
        };
        let (rms, csv) = table::traced_run(case, noise, seed, additions_without(&without));
        if !written(&path, &csv) {
            return ExitCode::FAILURE;
        }
        println!(
            "{id} at {noise} px, seed {seed}: MKGP3 residual RMS {rms:.3} px over t >= 3600 s; trace written to {}",
            path.display()
        );
        return ExitCode::SUCCESS;
    }
    let rows = table::compute_with(&cases, additions_without(&without));
    if csv {
        println!("case,noise_px,open_loop,reactive,ppec,mkgp,mkgp3");
        for r in &rows {
            println!(
                "{},{},{:.3},{:.3},{:.3},{:.3},{:.3}",
                r.case, r.noise_px, r.open_loop, r.reactive, r.ppec, r.mkgp, r.mkgp3
            );
        }
        return ExitCode::SUCCESS;
    }
    println!("Residual RMS (px) over t >= 3600 s; noise 1 px: mean of seeds 1-3");
    println!(
        "{:<6} {:>8} {:>10} {:>9} {:>9} {:>9} {:>9}",
        "case", "noise_px", "open_loop", "reactive", "ppec", "mkgp", "mkgp3"
    );
    for r in &rows {
        println!(
            "{:<6} {:>8} {:>10.3} {:>9.3} {:>9.3} {:>9.3} {:>9.3}",
            r.case, r.noise_px, r.open_loop, r.reactive, r.ppec, r.mkgp, r.mkgp3
        );
    }
    let out = Path::new("guide-sim-table.svg");
    let chart = svg::table_chart(&rows, "settled residual RMS (px), frames t >= 3600 s");
    if !written(out, &chart) {
        return ExitCode::FAILURE;
    }
    let shown = std::fs::canonicalize(out).unwrap_or_else(|_| out.to_path_buf());
    println!("bar chart written to {}", shown.display());
    ExitCode::SUCCESS
}

fn cmd_replay(
    ReplayArgs {
        logs,
        csv,
        per_section,
        trace,
    }: ReplayArgs,
) -> ExitCode {
    if let Some(path) = trace {
        let [log] = &logs[..] else {
            eprintln!("guide-sim replay: --trace needs one LOG");
            return ExitCode::from(2);
        };
        return replay_trace(log, &path);
    }
    let paths = if logs.is_empty() {
        match data::phd2_logs().and_then(|mut p| {
            p.extend(data::night_logs()?);
            Ok(p)
        }) {
            Ok(p) => p,
            Err(e) => {
                eprintln!("guide-sim: {e}");
                return ExitCode::FAILURE;
            }
        }
    } else {
        logs
    };
    // Parse every log first; a bad log is reported and the others still run.
    let mut failed = false;
    let logs: Vec<Option<GuideLog>> = paths
        .iter()
        .map(|p| match phd2_log::load(p) {
            Ok(log) => Some(log),
            Err(e) => {
                eprintln!("guide-sim: {e}");
                failed = true;
                None
            }
        })
        .collect();
    let reports: Vec<Option<Result<report::LogReport, Error>>> = logs
        .par_iter()
        .map(|log| log.as_ref().map(|l| report::report(l, per_section)))
        .collect();
    let out = replay::table::Table::new(csv, per_section);
    for (log, rep) in logs.iter().zip(reports) {
        let (Some(log), Some(rep)) = (log, rep) else {
            continue;
        };
        match rep {
            Ok(rep) => out.log(&log.name(), &rep),
            Err(e) => {
                eprintln!("guide-sim: {e}");
                failed = true;
            }
        }
    }
    if failed {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    }
}

/// `replay --trace`: MKGP on `log`, its trace written to `path`.
fn replay_trace(log: &Path, path: &Path) -> ExitCode {
    let traced = phd2_log::load(log).and_then(|l| replay::traced_mkgp(&l));
    let (result, csv) = match traced {
        Ok(t) => t,
        Err(e) => {
            eprintln!("guide-sim: {e}");
            return ExitCode::FAILURE;
        }
    };
    if !written(path, &csv) {
        return ExitCode::FAILURE;
    }
    println!(
        "{}: MKGP RMS {:.4} px over {} frames; trace written to {}",
        log.display(),
        result.rms,
        result.frames,
        path.display()
    );
    ExitCode::SUCCESS
}

/// Writes `text` to `path`; false (said on stderr) where it cannot.
fn written(path: &Path, text: &str) -> bool {
    match std::fs::write(path, text) {
        Ok(()) => true,
        Err(e) => {
            eprintln!("guide-sim: cannot write {}: {e}", path.display());
            false
        }
    }
}

fn cmd_bench(BenchArgs { csv, host_only }: BenchArgs) -> ExitCode {
    let path = data::cases_file();
    let case = match cases::load(&path) {
        Ok(c) => c.into_iter().find(|c| c.name == bench::CASE),
        Err(e) => {
            eprintln!("guide-sim: {e}");
            return ExitCode::FAILURE;
        }
    };
    let Some(case) = case else {
        eprintln!("guide-sim: {}: no case {}", path.display(), bench::CASE);
        return ExitCode::FAILURE;
    };
    let mut rows = bench::host_rows(&case);
    let mut status = ExitCode::SUCCESS;
    if !host_only {
        if !csv {
            eprintln!(
                "guide-sim: running the Cortex-M4 bench in QEMU (target-tests, about a minute)"
            );
        }
        match bench::run_target(&bench::target_tests_dir()) {
            TargetRun::Rows(r) => rows.extend(r),
            TargetRun::Unavailable(why) => {
                eprintln!("guide-sim: note: no cortex-m4 rows: {why}");
            }
            TargetRun::Failed(why) => {
                eprintln!("guide-sim: error: the Cortex-M4 bench failed: {why}");
                status = ExitCode::FAILURE;
            }
        }
    }
    if csv {
        println!("{}", bench::CSV_HEADER);
        for r in &rows {
            println!("{}", r.csv());
        }
    } else {
        print_bench(&rows);
    }
    status
}

fn print_bench(rows: &[BenchRow]) {
    let frames = |platform: &str| {
        rows.iter()
            .find(|r| r.platform == platform)
            .map(|r| r.frames)
    };
    println!(
        "Cost of one guide frame: closed loop on case {}, 1 px noise (seed 1), dt 2 s; frames t >= {} s",
        bench::CASE,
        bench::ACTIVE_FROM_S
    );
    if let Some(n) = frames("host") {
        println!("  host: {n} frames of t = 0..10798 s, std::time::Instant around each frame call");
    }
    if let Some(n) = frames("cortex-m4") {
        println!("  cortex-m4: {n} frames of t = 0..4798 s, instructions in QEMU mps2-an386 -icount shift=0");
    }
    println!(
        "{:<10} {:<9} {:>6} {:>10} {:>10} {:>12} {:>12} {:>11}",
        "platform",
        "precision",
        "stages",
        "us_median",
        "us_p90",
        "instr_median",
        "instr_max",
        "state_bytes"
    );
    for r in rows {
        let [platform, precision, stages, us_median, us_p90, instr_median, instr_max, state] =
            r.cells();
        println!(
            "{platform:<10} {precision:<9} {stages:>6} {us_median:>10} {us_p90:>10} \
             {instr_median:>12} {instr_max:>12} {state:>11}"
        );
    }
    let host = |precision: &str, stages: usize| {
        rows.iter()
            .find(|r| r.platform == "host" && r.precision == precision && r.stages == stages)
            .and_then(|r| r.us_median)
    };
    if let (Some(a), Some(b)) = (host("f64", 1), host("f64", 2)) {
        print!("host median ratios: f64 2/1 stages {:.2}", b / a);
        if let (Some(c), Some(d)) = (host("f32", 1), host("f32", 2)) {
            print!(
                ", f32 2/1 stages {:.2}, f32/f64 {:.2} (1 stage) {:.2} (2 stages)",
                d / c,
                c / a,
                d / b
            );
        }
        println!();
    }
    let met = |ok: bool| if ok { "met" } else { "NOT met" };
    for stages in [2, 3] {
        if let Some(r) = rows
            .iter()
            .find(|r| r.platform == "cortex-m4" && r.stages == stages)
        {
            let median = r.instructions_median.unwrap_or(u64::MAX);
            println!(
                "goal, {stages} stages on the Cortex-M4: median <= 1,000,000 instructions per frame: {median} ({})",
                met(median <= bench::INSTRUCTIONS_GOAL)
            );
        }
        if let Some(r) = rows
            .iter()
            .find(|r| r.precision == "f32" && r.stages == stages)
        {
            println!(
                "goal, {stages} stages in f32: state <= {} bytes (64 KiB): {} ({})",
                bench::STATE_GOAL_BYTES,
                r.state_bytes,
                met(r.state_bytes <= bench::STATE_GOAL_BYTES)
            );
        }
    }
}

/// The cases and noise levels `st4` and `nights` run: all cases or `--case`,
/// noise 0 and 1 px or `--noise`.
fn closed_loop_runs(args: &RunsArgs) -> Option<(Vec<cases::Case>, Vec<f64>)> {
    let (path, mut cases) = load_cases(args.cases.clone())?;
    if let Some(id) = &args.case {
        cases.retain(|c| &c.name == id);
        if cases.is_empty() {
            eprintln!("guide-sim: {}: no case {id}", path.display());
            return None;
        }
    }
    let levels = match args.noise {
        Some(x) => vec![x],
        None => vec![0.0, 1.0],
    };
    Some((cases, levels))
}

fn cmd_nights(args: NightsArgs) -> ExitCode {
    let Some((cases, levels)) = closed_loop_runs(&args.runs) else {
        return ExitCode::FAILURE;
    };
    let start = if args.park {
        nights::Night2Start::Parked
    } else {
        nights::Night2Start::Moved
    };
    let rows = nights::table(
        &cases,
        &levels,
        (start, args.calibrate),
        additions_without(&args.without),
    );
    if args.runs.csv {
        println!("{}", nights::CSV_HEADER);
        for r in &rows {
            println!("{}", nights::csv_line(r));
        }
        return ExitCode::SUCCESS;
    }
    println!(
        "Nights: pointing RMS (arcsec = px); settled = night 1 hours 1-3, the others night 2's first 30 min; noisy rows: mean of seeds 1-3"
    );
    println!(
        "{:<6} {:>8} {:>8} {:>6} {:>9} {:>15} {:>14} {:>16}",
        "case",
        "noise_px",
        "settled",
        "cold",
        "restored",
        "restored_index",
        "restored/cold",
        "index/settled"
    );
    for r in &rows {
        println!(
            "{:<6} {:>8} {:>8.3} {:>6.3} {:>9.3} {:>15.3} {:>14.3} {:>16.3}",
            r.case,
            r.noise_px,
            r.settled,
            r.cold_first30,
            r.restored_first30,
            r.restored_index_first30,
            r.restored_first30 / r.cold_first30,
            r.restored_index_first30 / r.settled
        );
    }
    ExitCode::SUCCESS
}

fn cmd_st4(args: St4Args) -> ExitCode {
    let Some((cases, levels)) = closed_loop_runs(&args.runs) else {
        return ExitCode::FAILURE;
    };
    let csv = args.runs.csv;
    let setup = st4_sim::Setup {
        guider: st4_sim::GuiderSettings {
            aggressiveness: args.aggressiveness,
            exposure_s: args.exposure,
            min_move: args.min_move,
            calibration: args.calibration,
        },
        sky: st4_sim::Sky {
            drift_arcsec_per_min: args.drift,
            walk_arcsec_per_sqrt_min: args.walk,
            bump_arcsec: args.bump,
        },
        least_pulse_share: args.least_pulse_share as f32,
        additions: additions_without(&args.without),
    };
    let rows = st4_sim::table_with(&cases, &levels, setup);
    if csv {
        println!("{}", st4_sim::CSV_HEADER);
        for r in &rows {
            println!(
                "{},{},{:.3},{:.3},{:.3}",
                r.case, r.noise_px, r.guider_only, r.fw_ppec, r.fw_mkgp
            );
        }
        return ExitCode::SUCCESS;
    }
    println!(
        "Firmware closed loop: pointing RMS (arcsec = px) over t >= 3600 s of 3 h; noisy rows: mean of seeds 1-3"
    );
    println!(
        "{:<6} {:>8} {:>12} {:>9} {:>9} {:>10} {:>10}",
        "case", "noise_px", "guider_only", "fw_ppec", "fw_mkgp", "ppec/only", "mkgp/only"
    );
    for r in &rows {
        println!(
            "{:<6} {:>8} {:>12.3} {:>9.3} {:>9.3} {:>10.3} {:>10.3}",
            r.case,
            r.noise_px,
            r.guider_only,
            r.fw_ppec,
            r.fw_mkgp,
            r.fw_ppec / r.guider_only,
            r.fw_mkgp / r.guider_only
        );
    }
    ExitCode::SUCCESS
}

fn cmd_night(args: NightArgs) -> ExitCode {
    let Some((cases, levels)) = closed_loop_runs(&args.runs) else {
        return ExitCode::FAILURE;
    };
    let seeds = args.seed.map_or(st4_sim::SEEDS.to_vec(), |s| vec![s]);
    let script = night::script::DEFAULT;
    let one = cases.len() == 1 && levels.len() == 1 && seeds.len() == 1;
    let logs = args.phd2_log.is_some() || args.truth.is_some() || args.trace.is_some();
    if logs && !one {
        eprintln!("guide-sim night: --phd2-log, --truth and --trace need one night: give --case, --noise and --seed");
        return ExitCode::from(2);
    }
    let additions = additions_without(&args.without);
    let nights = if one {
        night::night(&cases[0], levels[0], seeds[0], script, additions, logs).map(|n| vec![n])
    } else {
        night::sweep(
            &cases,
            &levels,
            &seeds,
            script,
            additions,
            |done, total, n| {
                eprintln!(
                    "guide-sim night: {done}/{total} {} {} px seed {}",
                    n.case, n.noise_px, n.seed
                );
            },
        )
    };
    let nights = match nights {
        Ok(n) => n,
        Err(e) => {
            eprintln!("guide-sim night: {e}");
            return ExitCode::FAILURE;
        }
    };
    let night = &nights[0];
    if let (Some(alone), Some(mkgp)) = (&night.guider_only.logs, &night.fw_mkgp.logs) {
        for (path, text) in [
            (&args.phd2_log, &alone.phd2),
            (&args.truth, &alone.truth),
            (&args.trace, &mkgp.learner),
        ] {
            if path.as_ref().is_some_and(|p| !written(p, text)) {
                return ExitCode::FAILURE;
            }
        }
    }
    if args.runs.csv {
        println!("{}", night::goals::CSV_HEADER);
        for n in &nights {
            for row in night::goals::csv_rows(n) {
                println!("{row}");
            }
        }
        return ExitCode::SUCCESS;
    }
    if one {
        print_night_sections(&nights[0]);
    }
    print_night_goals(&nights);
    ExitCode::SUCCESS
}

/// One night's sections, and what the firmware counted.
fn print_night_sections(n: &night::Night) {
    use night::goals;
    println!(
        "Night: {} at {} px, seed {}; pointing RMS (arcsec = px) while imaging; first5/settled: fw MKGP's first 5 min of guiding over the rest",
        n.case, n.noise_px, n.seed
    );
    println!(
        "{:<7} {:<6} {:>10} {:>9} {:>12} {:>9} {:>9} {:>10} {:>14} {:>20}",
        "section",
        "target",
        "exposure",
        "imaging_s",
        "guider_only",
        "fw_ppec",
        "fw_mkgp",
        "mkgp/only",
        "first5/settled",
        "alone first5/settled"
    );
    let ratios: Vec<f64> = goals::section_ratios(&n.fw_mkgp, &n.guider_only).collect();
    let firsts: Vec<f64> = goals::first_ratios(&n.fw_mkgp).collect();
    let alone: Vec<f64> = goals::first_ratios(&n.guider_only).collect();
    for (i, m) in n.fw_mkgp.sections.iter().enumerate() {
        let s = &m.section;
        println!(
            "{:<7} {:<6} {:>10} {:>9.0} {:>12.3} {:>9.3} {:>9.3} {:>10.3} {:>14.3} {:>20.3}",
            i + 1,
            s.target,
            format!("{}/{} s", s.exposure_s, s.interval_s),
            m.all.seconds(),
            n.guider_only.sections[i].all.rms(),
            n.fw_ppec.sections[i].all.rms(),
            m.all.rms(),
            ratios[i],
            firsts[i],
            alone[i]
        );
    }
    let whole = n.fw_mkgp.night();
    println!(
        "{:<7} {:<6} {:>10} {:>9.0} {:>12.3} {:>9.3} {:>9.3} {:>10.3}",
        "night",
        "",
        "",
        whole.seconds(),
        n.guider_only.night().rms(),
        n.fw_ppec.night().rms(),
        whole.rms(),
        whole.rms() / n.guider_only.night().rms()
    );
    let m = &n.fw_mkgp;
    println!(
        "fw MKGP: frames the learner took in each activity's windows, and learned as gear error:"
    );
    println!(
        "{:<12} {:>7} {:>9} {:>7} {:>8}",
        "activity", "windows", "seconds", "frames", "learned"
    );
    for (a, t) in &m.tallies {
        println!(
            "{:<12} {:>7} {:>9.0} {:>7} {:>8}",
            a.name(),
            t.windows,
            t.seconds,
            t.frames,
            t.learned
        );
    }
    let c = &m.counters;
    println!("fw MKGP learner: {:?}", c.learner);
    println!("fw MKGP guiding: {:?}", c.guiding);
    println!("fw MKGP model faults: {:?}", c.faults.unwrap_or_default());
    println!(
        "fw MKGP st4: {:?}; port: {:?}; lost edges {}",
        c.st4, c.port, c.lost_edges
    );
    let threshold = n.dither_threshold_arcsec;
    let big = m.dithers.iter().filter(|d| d.abs() > threshold).count();
    println!(
        "dithers: {} ({} longer than the firmware's dither threshold, {threshold:.1} arcsec)",
        m.dithers.len(),
        big
    );
}

/// Each night's figures against the goals, and which goals hold.
fn print_night_goals(nights: &[night::Night]) {
    use night::goals::{self, FIRST, SECTION, WHOLE_NIGHT};
    println!(
        "Goals (fw MKGP): whole night <= {WHOLE_NIGHT} x the guider alone on C5-C8 at 1 px; \
         no section above {SECTION} x; the first 5 min of each later section <= {FIRST} x its settled figure"
    );
    println!(
        "{:<5} {:>5} {:>4} {:>12} {:>8} {:>8} {:>10} {:>14} {:>14}  misses",
        "case",
        "noise",
        "seed",
        "guider_only",
        "fw_ppec",
        "fw_mkgp",
        "mkgp/only",
        "worst_section",
        "worst_first5"
    );
    let mut met = [(0usize, 0usize); 3];
    for n in nights {
        let f = goals::figures(n);
        let misses = goals::misses(n);
        println!(
            "{:<5} {:>5} {:>4} {:>12.3} {:>8.3} {:>8.3} {:>10.3} {:>9.3} ({}) {:>9.3} ({})  {}",
            n.case,
            n.noise_px,
            n.seed,
            n.guider_only.night().rms(),
            n.fw_ppec.night().rms(),
            n.fw_mkgp.night().rms(),
            f.whole,
            f.worst_section.0,
            f.worst_section.1 + 1,
            f.worst_first.0,
            f.worst_first.1 + 1,
            if misses.is_empty() {
                "-".to_string()
            } else {
                misses.join("; ")
            }
        );
        if goals::whole_applies(n) {
            met[0].1 += 1;
            met[0].0 += usize::from(goals::meets(f.whole, WHOLE_NIGHT));
        }
        met[1].1 += 1;
        met[1].0 += usize::from(goals::meets(f.worst_section.0, SECTION));
        met[2].1 += 1;
        met[2].0 += usize::from(goals::meets(f.worst_first.0, FIRST));
    }
    let names = [
        format!("whole night <= {WHOLE_NIGHT} x guider alone (C5-C8, 1 px)"),
        format!("every section <= {SECTION} x guider alone"),
        format!("first 5 min <= {FIRST} x settled"),
    ];
    for (name, (ok, of)) in names.iter().zip(met) {
        if of > 0 {
            let verdict = if ok == of { "met" } else { "NOT met" };
            println!("goal, {name}: {verdict} (holds on {ok} of {of} nights)");
        }
    }
    print_later_windows(nights);
}

/// The first-minutes bar on every later 5 min of each section: how far
/// the first minutes stand out from the section's own spread.
fn print_later_windows(nights: &[night::Night]) {
    use night::goals::{self, FIRST};
    let tallies = goals::window_tallies(nights);
    println!(
        "fw MKGP's 5 min windows above {FIRST} x the rest of their section's settled figure, \
         the first and each later one (a window with half the first's imaging or more):"
    );
    println!("{:<8} {:>12} {:>14}", "section", "first", "later");
    for (i, t) in tallies.iter().enumerate().skip(1) {
        println!(
            "{:<8} {:>12} {:>14}",
            i + 1,
            format!("{}/{}", t.first_above, t.firsts),
            format!("{}/{}", t.later_above, t.laters)
        );
    }
    println!(
        "first 5 min like any later 5 min of their section: the goal would hold on {:.1} of {} nights",
        goals::nights_if_like_later(nights, &tallies),
        nights.len()
    );
}

fn cmd_population(
    PopulationArgs {
        seed,
        count,
        mounts,
        csv,
        without,
    }: PopulationArgs,
) -> ExitCode {
    use population::summary;
    let mounts = match mounts.iter().max() {
        None => population::draw(seed, count as usize),
        Some(&last) => population::draw(seed, last as usize)
            .into_iter()
            .filter(|m| mounts.contains(&(m.index as u64)))
            .collect(),
    };
    let count = mounts.len();
    let start = std::time::Instant::now();
    if csv {
        println!("{}", population::csv_header());
    } else {
        println!(
            "Population of seed {seed}: {count} mounts; RMS (px) over t >= 3600 s of 3 h, \
             noise-free and at the mount's seeing (mean of 3 seeds)"
        );
        println!(
            "{:>5} {:>6} {:>9} {:>8} {:>7} {:>7} {:>11} {:>7} {:>7} {:>10} {:>10}  drawn",
            "mount",
            "noise",
            "open_loop",
            "reactive",
            "ppec",
            "mkgp",
            "guider_only",
            "fw_ppec",
            "fw_mkgp",
            "mkgp/reac",
            "fw_mkgp/go"
        );
    }
    // Each mount's rows as soon as they are in order: a long run can be
    // read (or cut short) as it goes.
    let mut done = 0;
    let rows = population::run(&mounts, additions_without(&without), |m, rows| {
        for r in rows {
            if csv {
                println!("{}", population::csv_line(r, m));
            } else {
                let [open_loop, reactive, ppec, mkgp, guider_only, fw_ppec, fw_mkgp] = r.figures();
                println!(
                    "{:>5} {:>6.2} {open_loop:>9.3} {reactive:>8.3} {ppec:>7.3} {mkgp:>7.3} {guider_only:>11.3} {fw_ppec:>7.3} {fw_mkgp:>7.3} {:>10.3} {:>10.3}  {}",
                    r.mount,
                    r.noise_px,
                    mkgp / reactive,
                    fw_mkgp / guider_only,
                    population::describe(m)
                );
            }
        }
        let _ = std::io::stdout().flush();
        done += 1;
        eprintln!(
            "guide-sim population: {done}/{count} mounts ({:.0} s)",
            start.elapsed().as_secs_f64()
        );
    });
    let lines = summary::summarize(&rows);
    if csv {
        eprintln!("{}", summary::CSV_HEADER);
        for l in &lines {
            eprintln!("{}", l.csv());
        }
        return ExitCode::SUCCESS;
    }
    println!("Summary: each ratio over the mounts (worse: mounts with a ratio above 1, beyond a tie of a millionth)");
    println!(
        "{:<7} {:<20} {:>6} {:>7} {:>7} {:>7} {:>11} {:>6}",
        "noise", "ratio", "mounts", "median", "p90", "worst", "worst_mount", "worse"
    );
    for l in &lines {
        let s = &l.stats;
        println!(
            "{:<7} {:<20} {:>6} {:>7.3} {:>7.3} {:>7.3} {:>11} {:>6}",
            l.level.name(),
            l.ratio.name(),
            s.mounts,
            s.median,
            s.p90,
            s.worst,
            s.worst_mount,
            s.worse
        );
    }
    ExitCode::SUCCESS
}

fn cmd_ablate(AblateArgs { seed, count, only }: AblateArgs) -> ExitCode {
    use ablation::Bench;
    use mkgp_mount::model::additions::{Acts, Additions};
    let names: Vec<(&str, Acts)> = Additions::NAMES
        .iter()
        .copied()
        .filter(|(n, _)| only.is_empty() || only.iter().any(|o| o == n))
        .collect();
    let Some((_, cases)) = load_cases(None) else {
        return ExitCode::FAILURE;
    };
    let logs = match ablation::phd2_logs() {
        Ok(l) => l,
        Err(e) => {
            eprintln!("guide-sim ablate: {e}");
            return ExitCode::FAILURE;
        }
    };
    let mounts = population::draw(seed, count as usize);
    let started = std::time::Instant::now();
    let progress = |what: &str| {
        eprintln!(
            "guide-sim ablate: {what} ({:.0} s)",
            started.elapsed().as_secs_f64()
        )
    };
    println!(
        "Ablation of seed {seed}: {count} mounts (noise-free and at each mount's seeing, \
         its first run seed), the paper's {} cases at 0 and 1 px, {} PHD2 logs",
        cases.len(),
        logs.len()
    );
    println!(
        "ratio: the model with {} stages over the reactive guider (model loop), fw mkgp over \
         the guider alone (firmware loop) or night 2's first 30 min restored (the mean of \
         without and with the index) over cold (restore loop); change: with the addition off \
         less all on (positive: it pays); spread: bootstrap SD over redrawn mounts",
        ablation::MODEL.stages()
    );
    println!(
        "{:<22} {:<8} {:<6} {:>6} {:>6} {:>13} {:>5} {:>15} {:>15} {:>5} {:>6}  logs: gain %",
        "addition",
        "loop",
        "noise",
        "median",
        "p90",
        "worst (mount)",
        "worse",
        "median change",
        "worst change",
        "pays",
        "cases"
    );
    let mut verdicts = Vec::new();
    for lp in [Acts::Model, Acts::Firmware, Acts::Restore] {
        let these: Vec<&str> = names
            .iter()
            .filter(|&&(_, acts)| acts == lp)
            .map(|&(n, _)| n)
            .collect();
        if these.is_empty() {
            continue;
        }
        let bench = Bench::new(lp, &mounts, &cases, &logs);
        let on = match bench.figures(Additions::ALL) {
            Ok(f) => f,
            Err(e) => {
                eprintln!("guide-sim ablate: {e}");
                return ExitCode::FAILURE;
            }
        };
        progress(&format!("{} loop, all on", ablation::loop_name(lp)));
        let numbers = bench.mount_numbers();
        let all_on = ablation::worth(&numbers, &on, &on);
        print_worth("(all on)", lp, &all_on, None, &on);
        for (k, name) in these.iter().enumerate() {
            let mut additions = Additions::ALL;
            let _ = additions.set(name, false);
            let off = match bench.figures(additions) {
                Ok(f) => f,
                Err(e) => {
                    eprintln!("guide-sim ablate: {e}");
                    return ExitCode::FAILURE;
                }
            };
            let w = ablation::worth(&numbers, &on, &off);
            let verdict = ablation::Verdict::of(&w);
            print_worth(name, lp, &w, Some(verdict), &off);
            verdicts.push((*name, verdict));
            progress(&format!("{name} off ({}/{})", k + 1, these.len()));
        }
    }
    for v in [
        ablation::Verdict::Pays,
        ablation::Verdict::Mixed,
        ablation::Verdict::DoesNotPay,
    ] {
        let names: Vec<&str> = verdicts
            .iter()
            .filter(|(_, w)| *w == v)
            .map(|(n, _)| *n)
            .collect();
        println!("pays {}: {}", v.name(), names.join(", "));
    }
    ExitCode::SUCCESS
}

/// An ablation's two lines (noise-free, seeing); `verdict` `None` for all on.
fn print_worth(
    name: &str,
    lp: mkgp_mount::model::additions::Acts,
    worth: &[ablation::Worth; 2],
    verdict: Option<ablation::Verdict>,
    figures: &ablation::Figures,
) {
    for w in worth {
        let s = &w.off;
        let change = |c: f64, spread: f64| match verdict {
            Some(_) => format!("{c:+.3} ±{spread:.3}"),
            None => String::new(),
        };
        let logs: Vec<String> = figures
            .log_gains_pct
            .iter()
            .map(|g| format!("{g:.2}"))
            .collect();
        println!(
            "{:<22} {:<8} {:<6} {:>6.3} {:>6.3} {:>13} {:>5} {:>15} {:>15} {:>5} {:>6.3}  {}",
            name,
            ablation::loop_name(lp),
            w.level.name(),
            s.median,
            s.p90,
            format!("{:.3} ({})", s.worst, s.worst_mount),
            s.worse,
            change(w.median_change, w.median_spread),
            change(w.worst_change, w.worst_spread),
            verdict.map_or("", ablation::Verdict::name),
            figures.cases_mean(w.level),
            logs.join(" ")
        );
    }
}
