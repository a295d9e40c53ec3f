//! A real PHD2 guide log (`performance_dataset03.txt`) with the absurd
//! values issue 26 found `guide-sim replay` accepting, one case each.

use host_tests::data;

/// A log with one kind of absurd value: its text, and the first line (1-based)
/// that holds one.
pub struct BadLog {
    pub text: String,
    pub line: usize,
}

/// The log's lines, and the indices of its frame rows.
struct Log {
    lines: Vec<String>,
    rows: Vec<usize>,
}

impl Log {
    fn dataset03() -> Log {
        let path = data::data_dir().join("phd2-logs/performance_dataset03.txt");
        let text = data::read_text(&path).unwrap_or_else(|e| panic!("{e}"));
        let lines: Vec<String> = text.lines().map(str::to_owned).collect();
        let rows = (0..lines.len())
            .filter(|&i| lines[i].starts_with(|c: char| c.is_ascii_digit()))
            .collect();
        Log { lines, rows }
    }

    /// Field `col` of frame row `k` (fields split at commas: the log quotes
    /// no comma in its rows).
    fn field(&self, k: usize, col: usize) -> &str {
        self.lines[self.rows[k]].split(',').nth(col).unwrap()
    }

    fn set(&mut self, k: usize, col: usize, value: &str) {
        let i = self.rows[k];
        let mut fields: Vec<&str> = self.lines[i].split(',').collect();
        fields[col] = value;
        self.lines[i] = fields.join(",");
    }

    fn text(&self) -> String {
        self.lines.join("\n") + "\n"
    }

    fn bad(&self, first: usize) -> BadLog {
        BadLog {
            text: self.text(),
            line: first + 1,
        }
    }
}

/// Columns of the log's frame rows.
pub const TIME: usize = 1;
pub const RA_RAW: usize = 5;
pub const RA_GUIDE: usize = 7;

/// The untouched log.
pub fn dataset03() -> String {
    Log::dataset03().text()
}

/// `value` in column `col` of the 100th frame row.
pub fn value(col: usize, value: &str) -> BadLog {
    let mut log = Log::dataset03();
    log.set(100, col, value);
    log.bad(log.rows[100])
}

/// `INFO: DITHER by X, 0.000` before the 100th frame row, whose line is
/// the one named.
pub fn dither(x: &str) -> BadLog {
    let mut log = Log::dataset03();
    let at = log.rows[100];
    log.lines.insert(
        at,
        format!("INFO: DITHER by {x}, 0.000, new lock pos = 444.003, 198.480"),
    );
    log.bad(at)
}

/// RARawDistance 1e6 in 12 rows spread over the log.
pub fn raw_1e6_in_12_rows() -> BadLog {
    let mut log = Log::dataset03();
    for k in 0..12 {
        log.set(10 + 50 * k, RA_RAW, "1e6");
    }
    log.bad(log.rows[10])
}

/// The frames' Time running backwards through the section (the same
/// intervals, in reverse).
pub fn time_backwards() -> BadLog {
    let mut log = Log::dataset03();
    let last = log.rows.len() - 1;
    let (first_t, last_t): (f64, f64) = (
        log.field(0, TIME).parse().unwrap(),
        log.field(last, TIME).parse().unwrap(),
    );
    for k in 0..=last {
        let t: f64 = log.field(k, TIME).parse().unwrap();
        log.set(k, TIME, &format!("{:.3}", first_t + last_t - t));
    }
    log.bad(log.rows[1])
}

/// `Exposure = 1e300 ms`.
pub fn exposure_1e300() -> BadLog {
    let mut log = Log::dataset03();
    let at = log
        .lines
        .iter()
        .position(|l| l.starts_with("Exposure ="))
        .unwrap();
    log.lines[at] = "Exposure = 1e300 ms".into();
    log.bad(at)
}

/// RARawDistance `px` in 12 rows spread over the log (a star the guider
/// would have lost: far beyond its search region), and the same log with
/// those rows written as PHD2 writes a frame it dropped.
pub fn jumps_and_drops(px: f64) -> (String, String) {
    let mut jumps = Log::dataset03();
    let mut drops = Log::dataset03();
    for k in (0..12).map(|k| 10 + 50 * k) {
        jumps.set(k, RA_RAW, &format!("{px:.3}"));
        let i = drops.rows[k];
        let (frame, time) = (drops.field(k, 0), drops.field(k, TIME));
        drops.lines[i] =
            format!("{frame},{time},\"DROP\",,,,,,,,,,,,,0,0.00,3,\"Star lost - low mass\"");
    }
    (jumps.text(), drops.text())
}
