//! Where the test data lives, and the error type of the loaders.

use std::fmt;
use std::path::{Path, PathBuf};

/// The data directory, `host-tests/data` in this repository (found from this
/// crate's manifest directory at build time; see its README for where each
/// file came from). The path is not checked here; the loaders report a
/// missing file with its full path.
pub fn data_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data")
}

/// `synthetic_cases.csv` in the data directory.
pub fn cases_file() -> PathBuf {
    data_dir().join("synthetic_cases.csv")
}

/// The PHD2 guide logs of the data directory (`phd2-logs`: one guiding
/// section each), sorted by name.
pub fn phd2_logs() -> Result<Vec<PathBuf>, Error> {
    text_files(&data_dir().join("phd2-logs"))
}

/// The PHD2 guide logs of whole nights (`phd2-nights`: many sections),
/// sorted by name.
pub fn night_logs() -> Result<Vec<PathBuf>, Error> {
    text_files(&data_dir().join("phd2-nights"))
}

/// The PHD2 guide logs `guide-sim night` wrote (`night-logs`: the
/// scripted night, whose truth lies beside each), sorted by name.
pub fn simulated_night_logs() -> Result<Vec<PathBuf>, Error> {
    text_files(&data_dir().join("night-logs"))
}

/// The `*.txt` files of `dir`, sorted by name; none is an error.
fn text_files(dir: &Path) -> Result<Vec<PathBuf>, Error> {
    let entries = std::fs::read_dir(dir).map_err(|e| Error::io(dir, &e))?;
    let mut logs: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "txt"))
        .collect();
    logs.sort();
    if logs.is_empty() {
        return Err(Error::new(dir, None, "no *.txt guide logs here"));
    }
    Ok(logs)
}

/// The INDIGO reference trace `indigo_ppec_<name>.csv`.
pub fn reference_trace(name: &str) -> PathBuf {
    data_dir()
        .join("reference-traces")
        .join(format!("indigo_ppec_{name}.csv"))
}

/// The header line of an INDIGO reference trace.
pub const TRACE_HEADER: &str =
    "time_s,input_px,snr,output_correction_px,period_s,learning_progress";

/// One frame of an INDIGO reference trace: what INDIGO's single-kernel
/// guider was given (time, input, SNR) and what it answered.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TraceRow {
    pub time_s: f64,
    pub input_px: f64,
    pub snr: f64,
    /// The correction, i.e. minus the control.
    pub output_correction_px: f64,
    pub period_s: f64,
    pub learning_progress: f64,
}

/// Loads a reference trace (see [`reference_trace`] and the data README):
/// the [`TRACE_HEADER`] line, then one frame per line with six finite
/// numbers. Errors name the file and line.
pub fn load_trace(path: &Path) -> Result<Vec<TraceRow>, Error> {
    let text = read_text(path)?;
    let err = |line: usize, msg: String| Error::new(path, Some(line), msg);
    let mut lines = text.lines().enumerate().map(|(i, l)| (i + 1, l));
    match lines.next() {
        Some((_, header)) if header.trim() == TRACE_HEADER => {}
        Some((n, header)) => {
            return Err(err(
                n,
                format!("expected the header {TRACE_HEADER:?}, found {header:?}"),
            ))
        }
        None => return Err(Error::new(path, None, "empty file")),
    }
    let mut rows = Vec::new();
    for (n, line) in lines {
        if line.trim().is_empty() {
            continue;
        }
        let f: Vec<&str> = line.split(',').collect();
        if f.len() != 6 {
            return Err(err(n, format!("expected 6 columns, found {}", f.len())));
        }
        let num = |i: usize| {
            let column = TRACE_HEADER.split(',').nth(i).unwrap_or("?");
            parse_f64(f[i], column).map_err(|m| err(n, m))
        };
        rows.push(TraceRow {
            time_s: num(0)?,
            input_px: num(1)?,
            snr: num(2)?,
            output_correction_px: num(3)?,
            period_s: num(4)?,
            learning_progress: num(5)?,
        });
    }
    if rows.is_empty() {
        return Err(Error::new(path, None, "no frames"));
    }
    Ok(rows)
}

/// Read a whole text file; a missing file is reported with its path.
pub fn read_text(path: &Path) -> Result<String, Error> {
    std::fs::read_to_string(path).map_err(|e| Error::io(path, &e))
}

/// A problem with one input file, shown as `file:line: message` (or
/// `file: message` when it concerns the whole file).
#[derive(Debug, Clone, PartialEq)]
pub struct Error {
    pub path: PathBuf,
    /// 1-based line number.
    pub line: Option<usize>,
    pub message: String,
}

impl Error {
    pub fn new(path: &Path, line: Option<usize>, message: impl Into<String>) -> Self {
        Error {
            path: path.to_path_buf(),
            line,
            message: message.into(),
        }
    }

    /// A file that cannot be read.
    pub fn io(path: &Path, err: &std::io::Error) -> Self {
        Error::new(path, None, format!("cannot read: {err}"))
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.line {
            Some(line) => write!(f, "{}:{}: {}", self.path.display(), line, self.message),
            None => write!(f, "{}: {}", self.path.display(), self.message),
        }
    }
}

impl std::error::Error for Error {}

/// Parse one numeric CSV field, naming the column on failure.
pub(crate) fn parse_f64(field: &str, column: &str) -> Result<f64, String> {
    let field = field.trim();
    match field.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(format!("{column}: not a finite number: {field:?}")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Writes `text` to a file of its own in the temporary directory.
    fn temp_file(name: &str, text: &str) -> PathBuf {
        let path =
            std::env::temp_dir().join(format!("host-tests-data-{}-{name}.csv", std::process::id()));
        std::fs::write(&path, text).unwrap();
        path
    }

    #[test]
    fn trace_errors_name_file_and_line() {
        let cases = [
            ("header", "t,x\n0,1,10,0,300,0\n", 1, "expected the header"),
            (
                "columns",
                &format!("{TRACE_HEADER}\n0,1,10,0,300,0\n2,1,10,0,300\n"),
                3,
                "expected 6 columns",
            ),
            (
                "number",
                &format!("{TRACE_HEADER}\n0,1,10,0,300,0\n2,x,10,0,300,0\n"),
                3,
                "input_px: not a finite number",
            ),
        ];
        for (name, text, line, message) in cases {
            let path = temp_file(name, text);
            let e = load_trace(&path).unwrap_err();
            std::fs::remove_file(&path).unwrap();
            assert_eq!(e.line, Some(line), "{name}: {e}");
            assert!(e.message.contains(message), "{name}: {e}");
            assert!(e
                .to_string()
                .starts_with(&format!("{}:{line}: ", path.display())));
        }
        let path = temp_file("empty", &format!("{TRACE_HEADER}\n"));
        let e = load_trace(&path).unwrap_err();
        std::fs::remove_file(&path).unwrap();
        assert_eq!((e.line, e.message.as_str()), (None, "no frames"));
    }
}
