//! `guide-sim bench`: what one guide frame of the library's guider costs.
//!
//! Host part: the paper's closed loop ([`closed_loop::run`]) on case C8 with
//! 1 px noise (seed 1), timing every `Guider::frame` call with
//! [`Instant`], for `f64` and `f32` and 1, 2 and 3 stages, all in one process.
//! The loop computes in `f64`; the `f32` guider gets its arguments converted
//! before the timed call.
//!
//! Cortex-M4 part: `target-tests/src/bin/bench.rs` runs the same loop on an
//! emulated Cortex-M4F in QEMU and counts the instructions of each `frame`
//! call; [`parse_target_line`] reads its result lines.
//!
//! Both report over the *active* frames, t >= [`ACTIVE_FROM_S`]: by then the
//! prediction is fully blended in (the data ramp ends at two worm periods,
//! about 600 s) and the spectrum, period tracking and stage discovery run
//! (from 600 s on); the GP fit itself runs from the 11th frame (t = 20 s).
//! Percentiles are nearest-rank: the median is the value of rank
//! ceil(n / 2) in ascending order, p90 that of rank ceil(0.9 n).

use crate::cases::Case;
use crate::closed_loop::{self, Noise};
use crate::guide_algorithm::GuideAlgorithm;
use mkgp_mount::model::guider::{Guider, GuiderConfig};
use mkgp_mount::model::numeric::scalar::Scalar;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

/// The case the bench runs.
pub const CASE: &str = "C8";
/// Measurement noise: N(0, 1 px), seed 1.
pub const NOISE: Noise = Noise::Gaussian {
    sigma_px: 1.0,
    seed: 1,
};
/// Frames with t >= this (s) are measured.
pub const ACTIVE_FROM_S: f64 = 1200.0;
/// Goal: median instructions per frame on the Cortex-M4 with 2 and with 3
/// stages.
pub const INSTRUCTIONS_GOAL: u64 = 1_000_000;
/// Goal: bytes of model state (`Guider<f32, 2>` and `Guider<f32, 3>`).
pub const STATE_GOAL_BYTES: usize = 64 * 1024;
/// The CSV header of `guide-sim bench --csv`.
pub const CSV_HEADER: &str = "platform,precision,stages,us_per_frame_median,us_per_frame_p90,instructions_per_frame_median,instructions_per_frame_max,state_bytes";

/// One row of the bench; `None` is a figure that does not apply (an empty
/// CSV cell).
#[derive(Debug, Clone, PartialEq)]
pub struct BenchRow {
    /// `host` or `cortex-m4`.
    pub platform: &'static str,
    /// `f32` or `f64`.
    pub precision: &'static str,
    pub stages: usize,
    /// Frames measured (the active frames).
    pub frames: usize,
    pub us_median: Option<f64>,
    pub us_p90: Option<f64>,
    pub instructions_median: Option<u64>,
    pub instructions_max: Option<u64>,
    pub state_bytes: usize,
}

impl BenchRow {
    /// The row's cells, columns of [`CSV_HEADER`]; empty where a figure
    /// does not apply.
    pub fn cells(&self) -> [String; 8] {
        fn cell<T: ToString>(x: Option<T>) -> String {
            x.map_or_else(String::new, |v| v.to_string())
        }
        [
            self.platform.to_string(),
            self.precision.to_string(),
            self.stages.to_string(),
            cell(self.us_median.map(|v| format!("{v:.2}"))),
            cell(self.us_p90.map(|v| format!("{v:.2}"))),
            cell(self.instructions_median),
            cell(self.instructions_max),
            self.state_bytes.to_string(),
        ]
    }

    /// The row as a CSV line (no trailing newline), columns of [`CSV_HEADER`].
    pub fn csv(&self) -> String {
        self.cells().join(",")
    }
}

/// Nearest-rank percentile `p` (0 < p <= 100) of ascending `sorted`.
pub fn percentile<T: Copy>(sorted: &[T], p: f64) -> T {
    assert!(!sorted.is_empty(), "percentile of nothing");
    let rank = ((p / 100.0) * sorted.len() as f64).ceil() as usize;
    sorted[rank.clamp(1, sorted.len()) - 1]
}

/// The library's guider as a [`GuideAlgorithm`] that times each `frame` call
/// of the active frames.
struct Timed<S: Scalar, const N: usize> {
    guider: Box<Guider<S, N>>,
    /// Nanoseconds of each active frame.
    ns: Vec<u64>,
}

impl<S: Scalar, const N: usize> GuideAlgorithm for Timed<S, N> {
    fn step(&mut self, t: f64, measured: f64, snr: f64, dt: f64) -> f64 {
        let (input, snr, dt) =
            std::hint::black_box((S::from_f64(measured), S::from_f64(snr), S::from_f64(dt)));
        let start = Instant::now();
        let control = self.guider.frame(t, input, snr, dt);
        let elapsed = start.elapsed();
        if t >= ACTIVE_FROM_S {
            self.ns.push(elapsed.as_nanos() as u64);
        }
        std::hint::black_box(control).to_f64()
    }
}

/// Times `Guider<S, N>` in the closed loop on `case`.
pub fn host_row<S: Scalar, const N: usize>(case: &Case, precision: &'static str) -> BenchRow {
    let mut timed = Timed::<S, N> {
        guider: Box::new(Guider::new(GuiderConfig::default())),
        ns: Vec::with_capacity(closed_loop::FRAMES),
    };
    closed_loop::run(case, &mut timed, NOISE);
    let mut ns = timed.ns;
    ns.sort_unstable();
    BenchRow {
        platform: "host",
        precision,
        stages: N,
        frames: ns.len(),
        us_median: Some(percentile(&ns, 50.0) as f64 / 1000.0),
        us_p90: Some(percentile(&ns, 90.0) as f64 / 1000.0),
        instructions_median: None,
        instructions_max: None,
        state_bytes: core::mem::size_of::<Guider<S, N>>(),
    }
}

/// The six host rows: f64 and f32, 1, 2 and 3 stages, in one process.
pub fn host_rows(case: &Case) -> Vec<BenchRow> {
    vec![
        host_row::<f64, 1>(case, "f64"),
        host_row::<f64, 2>(case, "f64"),
        host_row::<f64, 3>(case, "f64"),
        host_row::<f32, 1>(case, "f32"),
        host_row::<f32, 2>(case, "f32"),
        host_row::<f32, 3>(case, "f32"),
    ]
}

/// Parses a result line of the QEMU bench binary,
/// `bench stages=N frames=F median=M max=X state_bytes=B ...` (extra
/// `key=value` fields are ignored), into a `cortex-m4` `f32` row. `None` if
/// the line is not a result line or lacks a field.
pub fn parse_target_line(line: &str) -> Option<BenchRow> {
    let rest = line.trim().strip_prefix("bench ")?;
    let field = |key: &str| -> Option<u64> {
        rest.split_whitespace()
            .find_map(|kv| kv.strip_prefix(key)?.strip_prefix('='))?
            .parse()
            .ok()
    };
    Some(BenchRow {
        platform: "cortex-m4",
        precision: "f32",
        stages: field("stages")? as usize,
        frames: field("frames")? as usize,
        us_median: None,
        us_p90: None,
        instructions_median: Some(field("median")?),
        instructions_max: Some(field("max")?),
        state_bytes: field("state_bytes")? as usize,
    })
}

/// The thumbv7em target the QEMU bench is built for.
pub const TARGET: &str = "thumbv7em-none-eabihf";

/// The target-tests crate of this repository.
pub fn target_tests_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../target-tests")
}

/// Outcome of the Cortex-M4 part.
#[derive(Debug)]
pub enum TargetRun {
    /// The `cortex-m4` rows, 1, 2 and 3 stages.
    Rows(Vec<BenchRow>),
    /// qemu-system-arm or the thumbv7em target is missing: why.
    Unavailable(String),
    /// The build or the QEMU run failed, or its output had no result: why.
    Failed(String),
}

/// Builds and runs target-tests' `bench` binary in QEMU: `cargo run
/// --release --bin bench` in `dir`, whose runner (`.cargo/config.toml`
/// there) is `qemu-system-arm -machine mps2-an386 -icount shift=0` with
/// semihosting. Cargo's and QEMU's stderr pass through, and so, to stderr,
/// do its lines on the frames after a restore.
pub fn run_target(dir: &Path) -> TargetRun {
    match Command::new("qemu-system-arm")
        .arg("--version")
        .stdin(Stdio::null())
        .output()
    {
        Ok(o) if o.status.success() => {}
        _ => {
            return TargetRun::Unavailable(
                "qemu-system-arm not found (Debian/Ubuntu: apt-get install qemu-system-arm)".into(),
            )
        }
    }
    let sysroot = Command::new("rustc")
        .args(["--print", "sysroot"])
        .current_dir(dir)
        .stdin(Stdio::null())
        .output();
    let has_target = match sysroot {
        Ok(o) if o.status.success() => {
            let root = String::from_utf8_lossy(&o.stdout).trim().to_string();
            Path::new(&root).join("lib/rustlib").join(TARGET).is_dir()
        }
        _ => false,
    };
    if !has_target {
        return TargetRun::Unavailable(format!(
            "the Rust target {TARGET} is not installed (rustup target add {TARGET})"
        ));
    }
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let out = match Command::new(&cargo)
        .args(["run", "--release", "--quiet", "--bin", "bench"])
        .current_dir(dir)
        .stdin(Stdio::null())
        .stderr(Stdio::inherit())
        .output()
    {
        Ok(o) => o,
        Err(e) => return TargetRun::Failed(format!("cannot run cargo in {}: {e}", dir.display())),
    };
    let stdout = String::from_utf8_lossy(&out.stdout);
    if !out.status.success() {
        return TargetRun::Failed(format!(
            "`cargo run --release --bin bench` in {} failed ({}); its output:\n{stdout}",
            dir.display(),
            out.status
        ));
    }
    // The frames after a restore, as the binary prints them.
    for line in stdout.lines().filter(|l| l.starts_with("restore ")) {
        eprintln!("{line}");
    }
    let mut rows: Vec<BenchRow> = stdout.lines().filter_map(parse_target_line).collect();
    rows.sort_by_key(|r| r.stages);
    if rows.iter().map(|r| r.stages).collect::<Vec<_>>() != [1, 2, 3] {
        return TargetRun::Failed(format!(
            "the QEMU bench printed no result lines for stages 1, 2 and 3; its output:\n{stdout}"
        ));
    }
    TargetRun::Rows(rows)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_rank() {
        let v: Vec<u64> = (1..=10).collect();
        assert_eq!(percentile(&v, 50.0), 5);
        assert_eq!(percentile(&v, 90.0), 9);
        assert_eq!(percentile(&v, 100.0), 10);
        assert_eq!(percentile(&[7u64], 50.0), 7);
        assert_eq!(percentile(&[1u64, 2, 3], 50.0), 2);
    }

    #[test]
    fn parses_target_line() {
        let r = parse_target_line(
            "bench stages=2 frames=1800 median=412345 max=987654 state_bytes=71234 rms_px=0.9",
        )
        .unwrap();
        assert_eq!(
            (r.platform, r.precision, r.stages, r.frames),
            ("cortex-m4", "f32", 2, 1800)
        );
        assert_eq!(r.instructions_median, Some(412345));
        assert_eq!(r.instructions_max, Some(987654));
        assert_eq!(r.state_bytes, 71234);
        assert_eq!(r.csv(), "cortex-m4,f32,2,,,412345,987654,71234");
        assert!(parse_target_line("running bench").is_none());
        assert!(parse_target_line("bench stages=1 median=5").is_none());
    }

    #[test]
    fn host_csv_cells() {
        let r = BenchRow {
            platform: "host",
            precision: "f64",
            stages: 1,
            frames: 3,
            us_median: Some(12.346),
            us_p90: Some(20.0),
            instructions_median: None,
            instructions_max: None,
            state_bytes: 100,
        };
        assert_eq!(r.csv(), "host,f64,1,12.35,20.00,,,100");
        assert_eq!(CSV_HEADER.split(',').count(), r.csv().split(',').count());
    }
}
