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

/// The PHD2 guide logs of the data directory, sorted by name.
pub fn phd2_logs() -> Result<Vec<PathBuf>, Error> {
    let dir = data_dir().join("phd2-logs");
    let entries = std::fs::read_dir(&dir).map_err(|e| Error::io(&dir, &e))?;
    let mut logs: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "txt"))
        .collect();
    logs.sort();
    if logs.is_empty() {
        return Err(Error::new(&dir, None, "no *.txt guide logs here"));
    }
    Ok(logs)
}

/// The INDIGO reference trace `indigo_ppec_<name>.csv`.
pub fn reference_trace(name: &str) -> PathBuf {
    data_dir()
        .join("reference-traces")
        .join(format!("indigo_ppec_{name}.csv"))
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
