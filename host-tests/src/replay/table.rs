//! `guide-sim replay`'s output: one row per log, or with `--per-section`
//! one per section and then the log's, as text or CSV.

use super::report::{Figures, LogReport, WORST_SECTION_PCT};

/// The columns of a row, after those naming it.
const FIGURES: [&str; 5] = [
    "hysteresis_rms",
    "ppec_rms",
    "mkgp_rms",
    "ppec_gain_pct",
    "mkgp_gain_pct",
];
/// The columns naming a row of `--per-section`.
const SECTION: [&str; 6] = ["log", "section", "line", "start_s", "frames", "exposure_s"];
const ALONE: [&str; 2] = ["ppec_alone_gain_pct", "mkgp_alone_gain_pct"];

/// Prints logs' reports to stdout, under its header.
pub struct Table {
    csv: bool,
    per_section: bool,
}

impl Table {
    /// The table, its header printed (even if no log's rows follow).
    pub fn new(csv: bool, per_section: bool) -> Self {
        let table = Table { csv, per_section };
        table.header();
        table
    }

    fn print(&self, cells: &[String]) {
        if self.csv {
            println!("{}", cells.join(","));
        } else {
            // The log column fits PHD2's own names (PHD2_GuideLog_<date>_<time>).
            let widths: &[usize] = if self.per_section {
                &[31, 7, 6, 8, 6, 10, 11, 14, 9, 9, 13, 13, 19, 19]
            } else {
                &[31, 6, 14, 9, 9, 13, 13]
            };
            let row: Vec<String> = cells
                .iter()
                .zip(widths)
                .enumerate()
                .map(|(i, (c, &w))| match i {
                    0 => format!("{c:<w$}"),
                    _ => format!("{c:>w$}"),
                })
                .collect();
            println!("{}", row.join(" "));
        }
    }

    fn header(&self) {
        let names: Vec<&str> = if self.per_section {
            SECTION
                .iter()
                .chain(&["time_step_s"])
                .chain(&FIGURES)
                .chain(&ALONE)
                .copied()
                .collect()
        } else {
            ["log", "frames"].iter().chain(&FIGURES).copied().collect()
        };
        self.print(&names.iter().map(|s| s.to_string()).collect::<Vec<_>>());
    }

    /// The rows of log `name`.
    pub fn log(&self, name: &str, report: &LogReport) {
        if !self.per_section {
            let mut row = vec![name.to_string(), report.whole.frames.to_string()];
            row.extend(figures(&report.whole));
            self.print(&row);
            return;
        }
        for s in &report.sections {
            let mut row = vec![
                name.to_string(),
                (s.section + 1).to_string(),
                s.line.to_string(),
                format!("{:.0}", s.start_s),
                s.night.frames.to_string(),
                format!("{:.3}", s.exposure_s),
                format!("{:.3}", s.step_s),
            ];
            row.extend(figures(&s.night));
            row.push(format!("{:.2}", s.alone.ppec_gain_pct()));
            row.push(format!("{:.2}", s.alone.mkgp_gain_pct()));
            self.print(&row);
        }
        let n = report.sections.len() as f64;
        let mean = |gain: fn(&Figures) -> f64| {
            report.sections.iter().map(|s| gain(&s.alone)).sum::<f64>() / n
        };
        let mut row = vec![
            name.to_string(),
            "all".into(),
            String::new(),
            String::new(),
            report.whole.frames.to_string(),
            String::new(),
            String::new(),
        ];
        row.extend(figures(&report.whole));
        row.push(format!("{:.2}", mean(Figures::ppec_gain_pct)));
        row.push(format!("{:.2}", mean(Figures::mkgp_gain_pct)));
        self.print(&row);
        if let (false, Some(g)) = (self.csv, report.goals()) {
            println!(
                "  goals: MKGP gain {:.2} % >= 0 and >= {:.2} % (its sections alone, mean); \
                 worst section {:.2} % >= {WORST_SECTION_PCT} %: {}",
                g.whole_gain_pct,
                g.alone_mean_pct,
                g.worst_section_pct,
                if g.met() { "met" } else { "NOT met" }
            );
        }
    }
}

/// The figure columns of a row.
fn figures(f: &Figures) -> [String; 5] {
    [
        format!("{:.4}", f.hysteresis),
        format!("{:.4}", f.ppec),
        format!("{:.4}", f.mkgp),
        format!("{:.2}", f.ppec_gain_pct()),
        format!("{:.2}", f.mkgp_gain_pct()),
    ]
}
