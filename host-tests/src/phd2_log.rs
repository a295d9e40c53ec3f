//! PHD2 guide logs (`PHD2_GuideLog_*.txt`, `performance_dataset0N.txt`),
//! read as PHD2 writes them: a night of guiding sections.
//!
//! A section runs from `Guiding Begins at DATE TIME` to `Guiding Ends at`
//! (or to the next section, or the end of the file: PHD2 leaves a section
//! open when it stops abruptly). Its header lines give the exposure, the
//! pixel scale, the mount's guide rate and where it pointed ([`header`]);
//! then a CSV header `Frame,Time,mount,dx,dy,RARawDistance,...` names the
//! columns of its rows, one per frame ([`row`]), `Time` counting from the
//! section's begin. A frame counts when its first field is a frame number
//! and it has an RARawDistance; a `"DROP"` row (the star lost) is a frame
//! without a star, kept as an [`EventKind::Drop`]. `INFO: DITHER by X, Y`,
//! `INFO: SET LOCK POSITION` and `INFO: SETTLING STATE CHANGE` lines are
//! kept as events with the index of the frame that follows them.
//! Calibrations (`Calibration Begins at` to `Calibration complete`) are
//! skipped: their pulses are no guiding. A hand-made log may leave out the
//! `Guiding Begins` line: a `Frame,Time,...` header then starts a section,
//! with the header lines before it.
//!
//! Sections are placed on the night's clock by their `Guiding Begins at`
//! ([`Section::start_s`]), never earlier than the previous one ended.
//!
//! Values a guide log cannot hold are errors (see [`limits`]): distances and
//! dithers beyond any camera frame, exposures beyond minutes, times beyond a
//! week or running back within a section, a correction far beyond the error
//! it corrects, header values no mount gives. A row whose star PHD2 could
//! not have found, beyond its search region from the last star found, is a
//! frame the guider lost: it is dropped as PHD2's own DROP rows are (see
//! [`search_region`]).
//!
//! Errors name the file and line: `file:line: message`.

pub mod date_time;
pub mod header;
pub mod limits;
pub mod row;
pub mod search_region;

use crate::data::{read_text, Error};
use header::Header;
use limits::Clock;
use row::{Columns, Star};
use search_region::StarTrack;
use std::path::{Path, PathBuf};

/// One guide row of a log, with a star (the firmware's frame is
/// `mkgp_mount::mount::frame::Frame`).
#[derive(Debug, Clone, PartialEq)]
pub struct GuideRow {
    /// 1-based line in the log.
    pub line: usize,
    pub frame: u64,
    /// `Time`: seconds since the section began.
    pub time_s: f64,
    /// RARawDistance: the measured RA error (px).
    pub ra_raw: f64,
    /// RAGuideDistance: the RA correction the guide algorithm asked for
    /// (px).
    pub ra_guide: f64,
    /// The RA correction the mount carried out (px; [`row::applied`]).
    pub ra_applied: f64,
    pub snr: f64,
}

/// What happened between two frames.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum EventKind {
    /// `INFO: DITHER by X, Y, ...`: the lock moved by (X, Y) px; X is the
    /// replay's dither amount.
    Dither { x: f64, y: f64 },
    /// A frame without a star at `time_s` (a DROP row, or a star beyond
    /// PHD2's search region).
    Drop { time_s: f64 },
    /// `INFO: SET LOCK POSITION`.
    LockSet,
    /// `INFO: SETTLING STATE CHANGE, Settling started`.
    SettlingStarted,
    /// `... Settling complete` or `... Settling failed`.
    SettlingEnded,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Event {
    pub line: usize,
    /// Index in [`Section::frames`] of the first frame after the event.
    pub next_frame: usize,
    pub kind: EventKind,
}

/// One guiding section.
#[derive(Debug, Clone, PartialEq)]
pub struct Section {
    /// The line of its `Guiding Begins at` (of its `Frame,Time,...` header
    /// without one).
    pub line: usize,
    /// The line of its `Frame,Time,...` header.
    pub rows_line: usize,
    /// Where its `Time` 0 is on the night's clock: seconds since the first
    /// section began.
    pub start_s: f64,
    /// `Exposure = N ms` of the section (of the one before, if it gives
    /// none), in seconds.
    pub exposure_s: f64,
    pub header: Header,
    pub frames: Vec<GuideRow>,
    pub events: Vec<Event>,
}

impl Section {
    /// The `INFO: DITHER` events: (index of the next frame, X, Y).
    pub fn dithers(&self) -> impl Iterator<Item = (usize, f64, f64)> + '_ {
        self.events.iter().filter_map(|e| match e.kind {
            EventKind::Dither { x, y } => Some((e.next_frame, x, y)),
            _ => None,
        })
    }

    /// The frames without a star: (index of the next frame, their time).
    pub fn drops(&self) -> impl Iterator<Item = (usize, f64)> + '_ {
        self.events.iter().filter_map(|e| match e.kind {
            EventKind::Drop { time_s } => Some((e.next_frame, time_s)),
            _ => None,
        })
    }

    /// Where the section ends on the night's clock: its last frame (with a
    /// star or not).
    pub fn end_s(&self) -> f64 {
        let last_frame = self.frames.last().map_or(0.0, |f| f.time_s);
        let last_drop = self.drops().map(|(_, t)| t).fold(0.0, f64::max);
        self.start_s + last_frame.max(last_drop)
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct GuideLog {
    pub path: PathBuf,
    /// The guiding sections that have frames, in the order of the log.
    pub sections: Vec<Section>,
}

impl GuideLog {
    /// The file name without its extension, for tables.
    pub fn name(&self) -> String {
        self.path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| self.path.display().to_string())
    }

    /// Frames with a star, in all sections.
    pub fn frame_count(&self) -> usize {
        self.sections.iter().map(|s| s.frames.len()).sum()
    }
}

/// Load and parse a log.
pub fn load(path: &Path) -> Result<GuideLog, Error> {
    parse(&read_text(path)?, path)
}

/// Parse the `X, Y` of `INFO: DITHER by X, Y, new lock pos = ...`.
fn parse_dither(rest: &str) -> Result<(f64, f64), String> {
    let mut it = rest.split(',');
    let x = limits::distance(it.next().unwrap_or(""), "DITHER x")?;
    let y = limits::distance(it.next().unwrap_or(""), "DITHER y")?;
    Ok((x, y))
}

/// Whether `line` is a guide-frame row: its first field a frame number.
fn is_row(line: &str) -> bool {
    line.split(',')
        .next()
        .is_some_and(|f| !f.is_empty() && f.bytes().all(|b| b.is_ascii_digit()))
}

/// The rows of the section being read, and what they are checked against.
struct Rows {
    columns: Columns,
    clock: Clock,
    star: StarTrack,
    section: Section,
}

impl Rows {
    /// Row `fields` (frame `frame`, at `line`): a frame, or a frame without
    /// a star (no RARawDistance, or one PHD2 would have lost).
    fn row(&mut self, fields: &[String], line: usize, frame: u64) -> Result<(), String> {
        let row = self.columns.row(fields)?;
        self.clock.tick(row.time_s, line)?;
        let next_frame = self.section.frames.len();
        let found = row.star.filter(|s| self.star.found(s.ra_raw));
        let Some(star) = found else {
            self.push(line, EventKind::Drop { time_s: row.time_s });
            return Ok(());
        };
        // The dithers since the last frame: the correction may include them.
        let dithered: f64 = self
            .section
            .dithers()
            .filter(|&(at, _, _)| at == next_frame)
            .map(|(_, x, _)| x)
            .sum();
        limits::correction(star.ra_raw, star.ra_guide + dithered)?;
        self.section
            .frames
            .push(self.frame(line, frame, row.time_s, &star));
        Ok(())
    }

    fn frame(&self, line: usize, frame: u64, time_s: f64, star: &Star) -> GuideRow {
        GuideRow {
            line,
            frame,
            time_s,
            ra_raw: star.ra_raw,
            ra_guide: star.ra_guide,
            ra_applied: row::applied(star, self.section.header.x_rate),
            snr: star.snr,
        }
    }

    fn push(&mut self, line: usize, kind: EventKind) {
        self.section.events.push(Event {
            line,
            next_frame: self.section.frames.len(),
            kind,
        });
    }

    /// An `INFO:` line within the rows.
    fn info(&mut self, line: usize, text: &str) -> Result<(), String> {
        if let Some(rest) = text.strip_prefix("INFO: DITHER by") {
            let (x, y) = parse_dither(rest)?;
            self.star.dithered(x, y);
            self.push(line, EventKind::Dither { x, y });
        } else if text.starts_with("INFO: SET LOCK POSITION") {
            self.star.lock_set();
            self.push(line, EventKind::LockSet);
        } else if let Some(rest) = text.strip_prefix("INFO: SETTLING STATE CHANGE,") {
            let kind = if rest.contains("started") {
                EventKind::SettlingStarted
            } else {
                EventKind::SettlingEnded
            };
            self.push(line, kind);
        }
        Ok(())
    }
}

/// Where the reader is in the log.
enum State {
    /// Between sections (or before any).
    Idle,
    /// In a calibration: nothing of it is guiding.
    Calibrating,
    /// In a section's rows.
    Rows(Box<Rows>),
}

struct Parser {
    state: State,
    /// The header lines read for the section to come.
    header: Header,
    /// The header of the last guiding section (what a section that leaves
    /// lines out inherits).
    last_header: Header,
    /// The last `Guiding Begins at`: its line and time (s since 1970).
    begins: Option<(usize, i64)>,
    /// The night clock's origin: the first `Guiding Begins at`.
    origin: Option<i64>,
    sections: Vec<Section>,
    /// The line of the last `Frame,Time,...` header.
    last_rows_line: Option<usize>,
}

impl Parser {
    fn new() -> Self {
        Parser {
            state: State::Idle,
            header: Header::default(),
            last_header: Header::default(),
            begins: None,
            origin: None,
            sections: Vec::new(),
            last_rows_line: None,
        }
    }

    /// The section being read is complete; the next starts from its
    /// equipment.
    fn close(&mut self) {
        if let State::Rows(rows) = std::mem::replace(&mut self.state, State::Idle) {
            let mut section = rows.section;
            self.last_header = section.header.clone();
            self.header = self.last_header.inherit();
            let n = section.frames.len();
            section.events.retain(|e| e.next_frame < n);
            if n > 0 {
                self.sections.push(section);
            }
        }
    }

    fn line(&mut self, n: usize, line: &str) -> Result<(), String> {
        if let Some(rest) = line.strip_prefix("Guiding Begins at") {
            self.close();
            self.header = self.last_header.inherit();
            let at = date_time::seconds(rest).ok_or_else(|| {
                format!(
                    "Guiding Begins at: {:?} is not `YYYY-MM-DD HH:MM:SS`",
                    rest.trim()
                )
            })?;
            self.begins = Some((n, at));
            self.origin.get_or_insert(at);
        } else if line.starts_with("Guiding Ends at") {
            self.close();
            self.begins = None;
        } else if line.starts_with("Calibration Begins at") {
            self.close();
            self.begins = None;
            self.state = State::Calibrating;
        } else if line.starts_with("Calibration complete") {
            if let State::Calibrating = self.state {
                self.state = State::Idle;
            }
        } else if let State::Calibrating = self.state {
            // The calibration's own header, table and pulses.
        } else if line.starts_with("Frame,") {
            self.open(n, line)?;
        } else if is_row(line) {
            self.row(n, line)?;
        } else if line.starts_with("INFO:") {
            if let State::Rows(rows) = &mut self.state {
                rows.info(n, line)?;
            } else if let Some(rest) = line.strip_prefix("INFO: DITHER by") {
                // Outside a section it moves nothing we replay, but a log
                // that holds such a value is no guide log.
                parse_dither(rest)?;
            }
        } else if let State::Rows(rows) = &mut self.state {
            // Not where PHD2 writes them, but they describe this section.
            let section = &mut rows.section;
            section.header.read(line)?;
            section.exposure_s = section.header.exposure_s.unwrap_or(section.exposure_s);
        } else {
            self.header.read(line)?;
        }
        Ok(())
    }

    /// A `Frame,Time,...` header at line `n`: the rows of a new section.
    fn open(&mut self, n: usize, line: &str) -> Result<(), String> {
        self.close();
        let columns = Columns::from_header(&row::split_csv(line))?;
        self.last_rows_line = Some(n);
        let header = std::mem::take(&mut self.header);
        let Some(exposure_s) = header.exposure_s else {
            return Err("guiding section without an `Exposure = N ms` header line".into());
        };
        let previous_end = self.sections.last().map_or(0.0, Section::end_s);
        let (line, start_s) = match (self.begins.take(), self.origin) {
            (Some((at, begins)), Some(origin)) => {
                (at, ((begins - origin) as f64).max(previous_end))
            }
            _ => (n, previous_end),
        };
        self.state = State::Rows(Box::new(Rows {
            columns,
            clock: Clock::default(),
            star: StarTrack::default(),
            section: Section {
                line,
                rows_line: n,
                start_s,
                exposure_s,
                header,
                frames: Vec::new(),
                events: Vec::new(),
            },
        }));
        Ok(())
    }

    fn row(&mut self, n: usize, line: &str) -> Result<(), String> {
        let fields = row::split_csv(line);
        let frame: u64 = fields[0]
            .parse()
            .map_err(|_| format!("frame number out of range: {:?}", fields[0]))?;
        match &mut self.state {
            State::Rows(rows) => rows.row(&fields, n, frame),
            _ if self.last_rows_line.is_none() => {
                Err("guide-frame row before any `Frame,Time,...` header".into())
            }
            _ => Err("guide-frame row outside a guiding section".into()),
        }
    }
}

/// Parse a log; `path` names the file in errors.
pub fn parse(text: &str, path: &Path) -> Result<GuideLog, Error> {
    let mut parser = Parser::new();
    for (i, raw) in text.lines().enumerate() {
        parser
            .line(i + 1, raw.trim())
            .map_err(|m| Error::new(path, Some(i + 1), m))?;
    }
    parser.close();
    if parser.sections.is_empty() {
        return Err(match parser.last_rows_line {
            Some(line) => Error::new(
                path,
                Some(line),
                "no guide frames (rows with a frame number and RARawDistance)",
            ),
            None => Error::new(path, None, "no `Frame,Time,...` guide-frame header"),
        });
    }
    Ok(GuideLog {
        path: path.to_path_buf(),
        sections: parser.sections,
    })
}

#[cfg(test)]
mod tests;
