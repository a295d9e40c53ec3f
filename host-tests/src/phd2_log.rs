//! PHD2 guide logs (`PHD2_GuideLog_*.txt`, `performance_dataset0N.txt`).
//!
//! A log has header lines (`Exposure = 2000 ms`, ...), then per guiding
//! section a CSV header `Frame,Time,mount,dx,dy,RARawDistance,...` and one
//! row per frame. A frame counts when its first field is a frame number and
//! it has an RARawDistance (dropped frames, `"DROP"` rows, have none). The
//! columns used are found by name in the section's header: Time (col 1),
//! RARawDistance (col 5), RAGuideDistance (col 7), SNR (col 16) in the
//! logs at hand. `INFO: DITHER by X, Y, ...` lines are kept with the index of
//! the frame that follows them.
//!
//! Values a guide log cannot hold are errors (see [`limits`]): distances and
//! dithers beyond any camera frame, exposures beyond minutes, times beyond a
//! week or running back within a section, a correction far beyond the error
//! it corrects. A row whose star PHD2 could not have found, beyond its
//! search region from the last star found, is a frame the guider lost: it is
//! dropped as PHD2's own DROP rows are (see [`search_region`]). A section
//! runs from one `Frame,Time,...` header to the next.
//!
//! Errors name the file and line: `file:line: message`.

pub mod limits;
pub mod search_region;

use crate::data::{parse_f64, read_text, Error};
use limits::Clock;
use search_region::StarTrack;
use std::path::{Path, PathBuf};

/// One guide frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// 1-based line in the log.
    pub line: usize,
    pub frame: u64,
    pub time_s: f64,
    /// RARawDistance: the measured RA error (px).
    pub ra_raw: f64,
    /// RAGuideDistance: the RA correction PHD2 applied (px).
    pub ra_guide: f64,
    pub snr: f64,
}

/// An `INFO: DITHER by X, Y, ...` line.
#[derive(Debug, Clone, PartialEq)]
pub struct Dither {
    pub line: usize,
    /// Index in [`GuideLog::frames`] of the first frame after the dither.
    pub next_frame: usize,
    /// The first amount as printed (px); the replay's dither amount.
    pub x: f64,
    pub y: f64,
}

#[derive(Debug, Clone, PartialEq)]
pub struct GuideLog {
    pub path: PathBuf,
    /// `Exposure = N ms` of the first section, in seconds.
    pub exposure_s: f64,
    pub frames: Vec<Frame>,
    pub dithers: Vec<Dither>,
}

impl GuideLog {
    /// The file name without its extension, for tables.
    pub fn name(&self) -> String {
        self.path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| self.path.display().to_string())
    }
}

/// Load and parse a log.
pub fn load(path: &Path) -> Result<GuideLog, Error> {
    parse(&read_text(path)?, path)
}

/// Column indices of the fields we use, from a section's CSV header.
#[derive(Debug, Clone, Copy)]
struct Columns {
    time: usize,
    ra_raw: usize,
    ra_guide: usize,
    snr: usize,
}

const REQUIRED: [&str; 4] = ["Time", "RARawDistance", "RAGuideDistance", "SNR"];

impl Columns {
    fn from_header(fields: &[String]) -> Result<Columns, String> {
        let find = |name: &str| fields.iter().position(|f| f == name);
        let missing: Vec<&str> = REQUIRED
            .iter()
            .copied()
            .filter(|n| find(n).is_none())
            .collect();
        if !missing.is_empty() {
            return Err(format!(
                "guide-frame header lacks column(s) {}",
                missing.join(", ")
            ));
        }
        Ok(Columns {
            time: find("Time").unwrap(),
            ra_raw: find("RARawDistance").unwrap(),
            ra_guide: find("RAGuideDistance").unwrap(),
            snr: find("SNR").unwrap(),
        })
    }
}

/// Split a CSV line, honouring double quotes (PHD2 quotes the mount name and
/// error messages).
fn split_csv(line: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut field = String::new();
    let mut quoted = false;
    for ch in line.chars() {
        match ch {
            '"' => quoted = !quoted,
            ',' if !quoted => out.push(std::mem::take(&mut field)),
            _ => field.push(ch),
        }
    }
    out.push(field);
    out
}

/// Parse the `X, Y` of `INFO: DITHER by X, Y, new lock pos = ...`.
fn parse_dither(rest: &str) -> Result<(f64, f64), String> {
    let mut it = rest.split(',');
    let x = limits::distance(it.next().unwrap_or(""), "DITHER x")?;
    let y = limits::distance(it.next().unwrap_or(""), "DITHER y")?;
    Ok((x, y))
}

/// What one guiding section's rows are read with and checked against.
struct Section {
    /// The line of its `Frame,Time,...` header.
    header_line: usize,
    columns: Columns,
    clock: Clock,
    star: StarTrack,
}

impl Section {
    fn new(header_line: usize, columns: Columns) -> Self {
        Section {
            header_line,
            columns,
            clock: Clock::default(),
            star: StarTrack::default(),
        }
    }

    /// The frame of row `fields` (number `frame`, at `line`), or `None` for
    /// a frame the guider dropped (no RARawDistance) or would have lost.
    /// `dithered`: the dither amounts since the last frame, px.
    fn frame(
        &mut self,
        fields: &[String],
        line: usize,
        frame: u64,
        dithered: f64,
    ) -> Result<Option<Frame>, String> {
        let c = self.columns;
        let num = |idx: usize, name: &str, read: fn(&str, &str) -> Result<f64, String>| {
            let field = fields
                .get(idx)
                .ok_or_else(|| format!("row has {} fields, no {name} column", fields.len()))?;
            read(field, name)
        };
        let time_s = num(c.time, "Time", limits::time)?;
        self.clock.tick(time_s, line)?;
        if fields.get(c.ra_raw).is_none_or(|f| f.trim().is_empty()) {
            return Ok(None);
        }
        let f = Frame {
            line,
            frame,
            time_s,
            ra_raw: num(c.ra_raw, "RARawDistance", limits::distance)?,
            ra_guide: num(c.ra_guide, "RAGuideDistance", limits::distance)?,
            snr: num(c.snr, "SNR", parse_f64)?,
        };
        if !self.star.found(f.ra_raw) {
            return Ok(None);
        }
        limits::correction(f.ra_raw, f.ra_guide + dithered)?;
        Ok(Some(f))
    }
}

/// Parse a log; `path` names the file in errors.
pub fn parse(text: &str, path: &Path) -> Result<GuideLog, Error> {
    let err = |line: usize, msg: String| Error::new(path, Some(line), msg);
    let mut exposure_s = None;
    let mut section: Option<Section> = None;
    let mut frames = Vec::new();
    let mut dithers = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let n = i + 1;
        let line = raw.trim();
        if let Some(rest) = line.strip_prefix("Exposure =") {
            let e = limits::exposure_s(rest).map_err(|m| err(n, m))?;
            exposure_s.get_or_insert(e);
        } else if line.starts_with("Frame,") {
            let fields = split_csv(line);
            let columns = Columns::from_header(&fields).map_err(|m| err(n, m))?;
            section = Some(Section::new(n, columns));
        } else if let Some(rest) = line.strip_prefix("INFO: DITHER by") {
            let (x, y) = parse_dither(rest).map_err(|m| err(n, m))?;
            if let Some(s) = &mut section {
                s.star.dithered(x, y);
            }
            dithers.push(Dither {
                line: n,
                next_frame: frames.len(),
                x,
                y,
            });
        } else if line.starts_with("INFO: SET LOCK POSITION") {
            if let Some(s) = &mut section {
                s.star.lock_set();
            }
        } else if line
            .split(',')
            .next()
            .is_some_and(|f| !f.is_empty() && f.bytes().all(|b| b.is_ascii_digit()))
        {
            let fields = split_csv(line);
            let frame: u64 = fields[0]
                .parse()
                .map_err(|_| err(n, format!("frame number out of range: {:?}", fields[0])))?;
            let Some(s) = &mut section else {
                return Err(err(
                    n,
                    "guide-frame row before any `Frame,Time,...` header".into(),
                ));
            };
            let dithered = dithers
                .iter()
                .rev()
                .take_while(|d| d.next_frame == frames.len())
                .map(|d| d.x)
                .sum();
            if let Some(f) = s
                .frame(&fields, n, frame, dithered)
                .map_err(|m| err(n, m))?
            {
                frames.push(f);
            }
        }
    }
    if frames.is_empty() {
        return Err(match section {
            Some(s) => err(
                s.header_line,
                "no guide frames (rows with a frame number and RARawDistance)".into(),
            ),
            None => Error::new(path, None, "no `Frame,Time,...` guide-frame header"),
        });
    }
    let Some(exposure_s) = exposure_s else {
        return Err(Error::new(path, None, "no `Exposure = N ms` header line"));
    };
    dithers.retain(|d| d.next_frame < frames.len());
    Ok(GuideLog {
        path: path.to_path_buf(),
        exposure_s,
        frames,
        dithers,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const HEAD: &str = "Guiding Begins at 2017-03-10 20:22:52\nExposure = 2000 ms\n\
        Frame,Time,mount,dx,dy,RARawDistance,DECRawDistance,RAGuideDistance,DECGuideDistance,\
        RADuration,RADirection,DECDuration,DECDirection,XStep,YStep,StarMass,SNR,ErrorCode\n";
    const ROW1: &str =
        "1,2.250,\"Mount\",0.856,-0.494,-0.899,-0.308,-0.540,0.000,227,E,0,,,,1762,23.05,0\n";
    const ROW2: &str =
        "2,4.109,\"Mount\",0.159,-0.340,-0.191,-0.300,-0.115,0.000,48,E,0,,,,1463,21.04,0\n";
    const DROP: &str = "3,3.2,\"DROP\",,,,,,,,,,,,,1486,21.65,6,\"Star lost, mass changed\"\n";

    fn p(text: &str) -> Result<GuideLog, Error> {
        parse(text, Path::new("x.txt"))
    }

    #[test]
    fn parses_frames_dithers_and_exposure() {
        let text = format!("{HEAD}{ROW1}INFO: SETTLING STATE CHANGE\n{DROP}INFO: DITHER by -4.987, 0.636, new lock pos = 636.680, 509.874\n{ROW2}");
        let log = p(&text).unwrap();
        assert_eq!(log.exposure_s, 2.0);
        assert_eq!(log.frames.len(), 2);
        let f = &log.frames[0];
        assert_eq!(
            (f.line, f.frame, f.time_s, f.ra_raw, f.ra_guide, f.snr),
            (4, 1, 2.25, -0.899, -0.540, 23.05)
        );
        assert_eq!(log.frames[1].line, 8);
        assert_eq!(
            log.dithers,
            vec![Dither {
                line: 7,
                next_frame: 1,
                x: -4.987,
                y: 0.636
            }]
        );
        assert_eq!(log.name(), "x");
    }

    #[test]
    fn error_bad_number() {
        let text = format!("{HEAD}{ROW1}{}", ROW2.replace("-0.191", "-0.1x1"));
        assert_eq!(
            p(&text).unwrap_err().to_string(),
            "x.txt:5: RARawDistance: not a finite number: \"-0.1x1\""
        );
        let text = format!("{HEAD}{}", ROW1.replace("23.05", "nan"));
        assert_eq!(p(&text).unwrap_err().line, Some(4));
        let text = format!("{HEAD}{}", ROW1.replace("-0.540", ""));
        assert!(p(&text)
            .unwrap_err()
            .to_string()
            .starts_with("x.txt:4: RAGuideDistance"));
    }

    #[test]
    fn error_short_row() {
        let text = format!("{HEAD}1,2.250,\"Mount\",0.856,-0.494,-0.899,-0.308,-0.540\n");
        let e = p(&text).unwrap_err();
        assert_eq!(e.line, Some(4));
        assert!(e.message.contains("no SNR column"), "{e}");
    }

    #[test]
    fn error_missing_columns() {
        let text = "Exposure = 2000 ms\nFrame,Time,mount,dx,dy,RAGuideDistance\n";
        assert_eq!(
            p(text).unwrap_err().to_string(),
            "x.txt:2: guide-frame header lacks column(s) RARawDistance, SNR"
        );
    }

    #[test]
    fn error_no_rows() {
        let text = format!("{HEAD}{DROP}");
        assert_eq!(
            p(&text).unwrap_err().to_string(),
            "x.txt:3: no guide frames (rows with a frame number and RARawDistance)"
        );
        assert_eq!(
            p("hello\n").unwrap_err().to_string(),
            "x.txt: no `Frame,Time,...` guide-frame header"
        );
    }

    #[test]
    fn error_row_before_header() {
        let e = p(&format!("Exposure = 2000 ms\n{ROW1}")).unwrap_err();
        assert_eq!(e.line, Some(2));
    }

    #[test]
    fn error_exposure() {
        let e = p(&format!("{}{ROW1}", HEAD.replace("2000 ms", "2 s"))).unwrap_err();
        assert_eq!(e.line, Some(2));
        let e = p(&format!(
            "{}{ROW1}",
            HEAD.replace("Exposure = 2000 ms\n", "")
        ))
        .unwrap_err();
        assert_eq!(e.to_string(), "x.txt: no `Exposure = N ms` header line");
    }

    #[test]
    fn error_dither() {
        let e = p(&format!(
            "{HEAD}{ROW1}INFO: DITHER by abc, 1.0, new lock pos = 1, 2\n{ROW2}"
        ))
        .unwrap_err();
        assert_eq!(
            e.to_string(),
            "x.txt:5: DITHER x: not a finite number: \"abc\""
        );
    }
}
