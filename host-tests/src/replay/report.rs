//! What `guide-sim replay` prints: a log replayed by hysteresis, PPEC and
//! MKGP, as a whole and per section, and the goals of issue 27 for a night
//! of several sections.

use super::{model_algorithm, run_with, section_alone, time_step_s, Options};
use crate::data::Error;
use crate::guide_algorithm::{GuideAlgorithm, Hysteresis};
use crate::models::Model;
use crate::phd2_log::GuideLog;
use rayon::prelude::*;

/// The worst a section's MKGP gain may be, % (issue 27).
pub const WORST_SECTION_PCT: f64 = -0.5;

/// The replay's columns.
#[derive(Clone, Copy)]
enum Kind {
    Hysteresis,
    Model(Model),
}

const KINDS: [Kind; 3] = [
    Kind::Hysteresis,
    Kind::Model(Model::Ppec),
    Kind::Model(Model::Mkgp),
];

fn algorithm(kind: Kind) -> Box<dyn GuideAlgorithm> {
    match kind {
        Kind::Hysteresis => Box::new(Hysteresis::phd2_baseline()),
        Kind::Model(m) => model_algorithm(m),
    }
}

/// The RMS (px) of the three, over `frames` states.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Figures {
    pub frames: usize,
    pub hysteresis: f64,
    pub ppec: f64,
    pub mkgp: f64,
}

impl Figures {
    pub fn ppec_gain_pct(&self) -> f64 {
        super::gain_pct(self.ppec, self.hysteresis)
    }

    pub fn mkgp_gain_pct(&self) -> f64 {
        super::gain_pct(self.mkgp, self.hysteresis)
    }
}

/// One section: its place, and its figures within the night and replayed
/// on its own (a guider that starts afresh).
#[derive(Debug, Clone, PartialEq)]
pub struct SectionRow {
    /// Index in [`GuideLog::sections`].
    pub section: usize,
    pub line: usize,
    pub start_s: f64,
    pub exposure_s: f64,
    /// The time step the algorithms were given.
    pub step_s: f64,
    pub night: Figures,
    pub alone: Figures,
}

#[derive(Debug, Clone, PartialEq)]
pub struct LogReport {
    pub whole: Figures,
    /// Empty unless asked for.
    pub sections: Vec<SectionRow>,
}

/// The goals of issue 27 for one log.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Goals {
    /// MKGP's gain over hysteresis on the whole night, %.
    pub whole_gain_pct: f64,
    /// The mean of its sections' MKGP gains, each replayed alone, %.
    pub alone_mean_pct: f64,
    /// The lowest MKGP gain of a section within the night, %.
    pub worst_section_pct: f64,
}

impl Goals {
    /// Whole-night gain >= 0 and >= the sections' alone (carrying the model
    /// across sections pays); no section below [`WORST_SECTION_PCT`].
    pub fn met(&self) -> bool {
        self.whole_gain_pct >= 0.0
            && self.whole_gain_pct >= self.alone_mean_pct
            && self.worst_section_pct >= WORST_SECTION_PCT
    }
}

impl LogReport {
    /// The goals, from a report with its sections.
    pub fn goals(&self) -> Option<Goals> {
        let n = self.sections.len();
        (n > 0).then(|| Goals {
            whole_gain_pct: self.whole.mkgp_gain_pct(),
            alone_mean_pct: self
                .sections
                .iter()
                .map(|s| s.alone.mkgp_gain_pct())
                .sum::<f64>()
                / n as f64,
            worst_section_pct: self
                .sections
                .iter()
                .map(|s| s.night.mkgp_gain_pct())
                .fold(f64::INFINITY, f64::min),
        })
    }
}

/// Replay `log` with the night's [`Options`]; with `per_section`, each
/// section alone too.
pub fn report(log: &GuideLog, per_section: bool) -> Result<LogReport, Error> {
    let options = Options::default();
    let night = |log: &GuideLog| -> Result<Vec<super::LogResult>, Error> {
        KINDS
            .par_iter()
            .map(|&k| run_with(log, &mut *algorithm(k), &options))
            .collect()
    };
    let runs = night(log)?;
    let figures = |runs: &[super::LogResult], pick: &dyn Fn(&super::LogResult) -> (usize, f64)| {
        let [h, p, m] = [0, 1, 2].map(|i| pick(&runs[i]));
        Figures {
            frames: h.0,
            hysteresis: h.1,
            ppec: p.1,
            mkgp: m.1,
        }
    };
    let whole = figures(&runs, &|r| (r.whole.frames, r.whole.rms));
    let mut sections = Vec::new();
    if per_section {
        let alone: Vec<Figures> = runs[0]
            .sections
            .par_iter()
            .map(|s| {
                let runs = night(&section_alone(log, s.section))?;
                Ok(figures(&runs, &|r| (r.whole.frames, r.whole.rms)))
            })
            .collect::<Result<_, Error>>()?;
        for (j, alone) in alone.into_iter().enumerate() {
            let k = runs[0].sections[j].section;
            let s = &log.sections[k];
            sections.push(SectionRow {
                section: k,
                line: s.line,
                start_s: s.start_s,
                exposure_s: s.exposure_s,
                step_s: time_step_s(s, &options),
                night: figures(&runs, &|r| (r.sections[j].frames, r.sections[j].rms)),
                alone,
            });
        }
    }
    Ok(LogReport { whole, sections })
}
