//! Nights of several guiding sections made from the real one-section logs
//! (`data/phd2-logs`): a log cut into pieces, each written as PHD2 writes a
//! section (its own `Guiding Begins at`, header and `Time` from its
//! begin), with pauses between them and the star locked afresh at each
//! start. A piece may be moved to another time of the night: the mount
//! then slewed there, and its header's hour angle says so (the gear's
//! true one, from the piece's place in the original log).

use host_tests::data;
use host_tests::phd2_log::date_time;
use host_tests::replay::pointing::SIDEREAL_PER_SOLAR;

/// One section of the night: rows `rows` (indices of the original's frame
/// rows, DROP rows included) from `at_s` on the night's clock (`None`:
/// where they were), with the exposure written as `exposure_ms` if given.
#[derive(Debug, Clone)]
pub struct Piece {
    pub rows: std::ops::Range<usize>,
    pub at_s: Option<f64>,
    pub exposure_ms: Option<u32>,
    /// Decimals of the hour angle and RA written (PHD2 writes 2).
    pub decimals: usize,
}

impl Piece {
    pub fn new(rows: std::ops::Range<usize>) -> Self {
        Piece {
            rows,
            at_s: None,
            exposure_ms: None,
            decimals: 2,
        }
    }
}

/// The lines of `performance_<name>.txt`.
pub fn original(name: &str) -> Vec<String> {
    let path = data::data_dir()
        .join("phd2-logs")
        .join(format!("performance_{name}.txt"));
    let text = data::read_text(&path).unwrap_or_else(|e| panic!("{e}"));
    text.lines().map(str::to_owned).collect()
}

/// Indices (in `lines`) of the frame rows.
pub fn rows(lines: &[String]) -> Vec<usize> {
    (0..lines.len())
        .filter(|&i| lines[i].starts_with(|c: char| c.is_ascii_digit()))
        .collect()
}

fn field(line: &str, k: usize) -> &str {
    line.split(',').nth(k).unwrap_or("")
}

fn set_field(line: &str, k: usize, value: &str) -> String {
    let mut fields: Vec<&str> = line.split(',').collect();
    fields[k] = value;
    fields.join(",")
}

/// The night made of `pieces` of the log `lines`, in the order given.
pub fn night(lines: &[String], pieces: &[Piece]) -> String {
    let rows = rows(lines);
    let frame_header = lines.iter().position(|l| l.starts_with("Frame,")).unwrap();
    let header = &lines[1..frame_header];
    let begins = date_time::seconds(lines[0].strip_prefix("Guiding Begins at ").unwrap()).unwrap();
    let mut out = Vec::new();
    for piece in pieces {
        let first = rows[piece.rows.start];
        let last = rows[piece.rows.end - 1];
        let t_first: f64 = field(&lines[first], 1).parse().unwrap();
        let t_last: f64 = field(&lines[last], 1).parse().unwrap();
        // Where the piece's clock starts: a whole second before its first
        // row, where it was (its gear time) and where the night puts it.
        let gear_zero = (t_first - 1.0).floor().max(0.0);
        let zero = piece.at_s.unwrap_or(gear_zero).floor();
        out.push(format!(
            "Guiding Begins at {}",
            date_time::format(begins + zero as i64)
        ));
        for l in header {
            out.push(header_line(l, gear_zero, zero, piece));
        }
        out.push(lines[frame_header].clone());
        // The star locked where it is at the start.
        let is_row = |l: &String| l.starts_with(|c: char| c.is_ascii_digit());
        let lock = match piece.rows.start {
            0 => 0.0,
            _ => lines[first..=last]
                .iter()
                .filter(|l| is_row(l))
                .find_map(|l| field(l, 5).parse().ok())
                .unwrap_or(0.0),
        };
        for l in &lines[first..=last] {
            if !is_row(l) {
                out.push(l.clone());
                continue;
            }
            let t: f64 = field(l, 1).parse().unwrap();
            let mut row = set_field(l, 1, &format!("{:.3}", t - gear_zero));
            if let Ok(m) = field(l, 5).parse::<f64>() {
                row = set_field(&row, 5, &format!("{:.3}", m - lock));
            }
            out.push(row);
        }
        let end = begins + zero as i64 + (t_last - gear_zero).ceil() as i64;
        out.push(format!("Guiding Ends at {}", date_time::format(end)));
        out.push(String::new());
    }
    out.join("\n") + "\n"
}

/// A header line of a piece whose gear clock starts at `gear_zero` s of the
/// original and whose night clock at `zero`: the hour angle of its gear,
/// the right ascension that puts the mount there at that time of night.
fn header_line(line: &str, gear_zero: f64, zero: f64, piece: &Piece) -> String {
    if line.starts_with("Exposure =") {
        if let Some(ms) = piece.exposure_ms {
            return format!("Exposure = {ms} ms");
        }
    }
    if !line.starts_with("Dec =") && !line.starts_with("RA =") {
        return line.to_string();
    }
    let to_hr = |s: f64| s / 3600.0 * SIDEREAL_PER_SOLAR;
    line.split(", ")
        .map(|part| match part.split_once(" = ") {
            Some(("Hour angle", v)) => {
                let ha: f64 = v.trim_end_matches(" hr").parse().unwrap();
                format!(
                    "Hour angle = {:.*} hr",
                    piece.decimals,
                    ha + to_hr(gear_zero)
                )
            }
            Some(("RA", v)) => {
                let ra: f64 = v.trim_end_matches(" hr").parse().unwrap();
                let ra = (ra + to_hr(zero - gear_zero)).rem_euclid(24.0);
                format!("RA = {ra:.*} hr", piece.decimals)
            }
            _ => part.to_string(),
        })
        .collect::<Vec<_>>()
        .join(", ")
}
