//! The goals for a night (issue 27, "Goals"), and the rows
//! `guide-sim night` prints:
//!
//! - the whole night's fw MKGP at most [`WHOLE_NIGHT`] of the guider
//!   alone on C5-C8 at 1 px;
//! - no section's fw MKGP above [`SECTION`] of the guider alone's, on any
//!   case;
//! - the first [`FIRST_S`](super::session::FIRST_S) of each section after
//!   the first within [`FIRST`] of that section's settled figure (fw
//!   MKGP's own, after those first minutes).

use super::session::SectionScore;
use super::{Night, NightRun};

pub const WHOLE_NIGHT: f64 = 0.8;
pub const SECTION: f64 = 1.0;
pub const FIRST: f64 = 1.2;
/// The cases the whole-night goal covers, at 1 px.
pub const HARD_CASES: [&str; 4] = ["C5", "C6", "C7", "C8"];

/// A night's figures against the goals (fw MKGP).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Figures {
    /// The whole night's RMS over the guider alone's.
    pub whole: f64,
    /// The highest section ratio to the guider alone, and its section
    /// (0-based).
    pub worst_section: (f64, usize),
    /// The highest first-minutes RMS over the settled RMS of a section
    /// after the first, and its section.
    pub worst_first: (f64, usize),
}

/// The largest of `values` with its index (NaN-free values only).
fn worst(values: impl Iterator<Item = (usize, f64)>) -> (f64, usize) {
    values
        .filter(|(_, v)| v.is_finite())
        .fold((f64::NAN, 0), |(m, i), (j, v)| {
            if m.is_nan() || v > m {
                (v, j)
            } else {
                (m, i)
            }
        })
}

/// Each section's RMS of `run` over the guider alone's.
pub fn section_ratios<'a>(
    run: &'a NightRun,
    alone: &'a NightRun,
) -> impl Iterator<Item = f64> + 'a {
    run.sections
        .iter()
        .zip(&alone.sections)
        .map(|(s, g)| s.all.rms() / g.all.rms())
}

/// Each section's first minutes over its settled figure (NaN for the
/// first section, which has nothing to carry over).
pub fn first_ratios(run: &NightRun) -> impl Iterator<Item = f64> + '_ {
    run.sections
        .iter()
        .enumerate()
        .map(|(i, s)| if i == 0 { f64::NAN } else { first_ratio(s) })
}

/// A section's first minutes over its settled figure.
fn first_ratio(s: &SectionScore) -> f64 {
    s.first.rms() / s.settled.rms()
}

/// Each later window of each section after the first (its index), over
/// the section's settled figure without it: the first minutes' ratio taken
/// anywhere else in the section, where nothing was carried over. A window
/// with less than half the first minutes' imaging (a refocus, clouds) is
/// left out.
pub fn later_ratios(sections: &[SectionScore]) -> impl Iterator<Item = (usize, f64)> + '_ {
    sections.iter().enumerate().skip(1).flat_map(|(i, s)| {
        s.later
            .iter()
            .filter(|w| 2 * w.n >= s.first.n)
            .map(move |&w| (i, w.rms() / (s.settled - w).rms()))
            .filter(|(_, r)| r.is_finite())
    })
}

/// The first-minutes bar ([`FIRST`]) on one section of the night (0-based
/// index), over a set of nights: how many first windows and how many later
/// windows ([`later_ratios`]) are above it.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct WindowTally {
    pub first_above: usize,
    pub firsts: usize,
    pub later_above: usize,
    pub laters: usize,
}

impl WindowTally {
    /// The share of later windows within the bar (1 with none).
    pub fn later_within(&self) -> f64 {
        if self.laters == 0 {
            1.0
        } else {
            1.0 - self.later_above as f64 / self.laters as f64
        }
    }
}

/// Per section, fw MKGP's windows against [`FIRST`] over `nights`.
pub fn window_tallies(nights: &[Night]) -> Vec<WindowTally> {
    let mut t = Vec::new();
    for n in nights {
        tally(&mut t, &n.fw_mkgp.sections);
    }
    t
}

/// Add one night's `sections` to the per-section tallies `t`.
fn tally(t: &mut Vec<WindowTally>, sections: &[SectionScore]) {
    t.resize(t.len().max(sections.len()), WindowTally::default());
    for (i, s) in sections.iter().enumerate().skip(1) {
        t[i].firsts += 1;
        t[i].first_above += usize::from(!meets(first_ratio(s), FIRST));
    }
    for (i, r) in later_ratios(sections) {
        t[i].laters += 1;
        t[i].later_above += usize::from(!meets(r, FIRST));
    }
}

/// On how many of `nights` the first-minutes goal would hold if each
/// section's first minutes were like any of its later windows: the sum over
/// the nights of the product over their sections after the first of the
/// share of that section's later windows within the bar (`tallies`, over
/// the same nights).
pub fn nights_if_like_later(nights: &[Night], tallies: &[WindowTally]) -> f64 {
    nights
        .iter()
        .map(|n| {
            (1..n.fw_mkgp.sections.len())
                .map(|i| tallies.get(i).map_or(1.0, WindowTally::later_within))
                .product::<f64>()
        })
        .sum()
}

pub fn figures(n: &Night) -> Figures {
    Figures {
        whole: n.fw_mkgp.night().rms() / n.guider_only.night().rms(),
        worst_section: worst(section_ratios(&n.fw_mkgp, &n.guider_only).enumerate()),
        worst_first: worst(first_ratios(&n.fw_mkgp).enumerate()),
    }
}

/// Whether the whole-night goal covers this night.
pub fn whole_applies(n: &Night) -> bool {
    n.noise_px == 1.0 && HARD_CASES.contains(&n.case.as_str())
}

/// A figure at or below its goal (NaN: not).
pub fn meets(figure: f64, goal: f64) -> bool {
    figure <= goal
}

/// The goals a night misses, in words (empty: all met).
pub fn misses(n: &Night) -> Vec<String> {
    let f = figures(n);
    let mut out = Vec::new();
    if whole_applies(n) && !meets(f.whole, WHOLE_NIGHT) {
        out.push(format!("whole night {:.3} > {WHOLE_NIGHT}", f.whole));
    }
    if !meets(f.worst_section.0, SECTION) {
        out.push(format!(
            "section {} {:.3} > {SECTION}",
            f.worst_section.1 + 1,
            f.worst_section.0
        ));
    }
    if !meets(f.worst_first.0, FIRST) {
        out.push(format!(
            "section {} first minutes {:.3} x settled > {FIRST}",
            f.worst_first.1 + 1,
            f.worst_first.0
        ));
    }
    out
}

pub const CSV_HEADER: &str = "case,noise_px,seed,section,target,exposure_s,interval_s,\
imaging_s,guider_only,fw_ppec,fw_mkgp,fw_mkgp_first5,fw_mkgp_settled,guider_only_first5,\
guider_only_settled";

/// A night as CSV rows: one per section, then `night` for the whole.
pub fn csv_rows(n: &Night) -> Vec<String> {
    let head = format!("{},{},{}", n.case, n.noise_px, n.seed);
    let mut rows: Vec<String> = n
        .fw_mkgp
        .sections
        .iter()
        .enumerate()
        .map(|(i, m)| {
            let s = &m.section;
            let g = &n.guider_only.sections[i];
            format!(
                "{head},{},{},{},{},{:.0},{:.3},{:.3},{:.3},{:.3},{:.3},{:.3},{:.3}",
                i + 1,
                s.target,
                s.exposure_s,
                s.interval_s,
                m.all.seconds(),
                g.all.rms(),
                n.fw_ppec.sections[i].all.rms(),
                m.all.rms(),
                m.first.rms(),
                m.settled.rms(),
                g.first.rms(),
                g.settled.rms()
            )
        })
        .collect();
    let night = n.fw_mkgp.night();
    rows.push(format!(
        "{head},night,,,,{:.0},{:.3},{:.3},{:.3},,,,",
        night.seconds(),
        n.guider_only.night().rms(),
        n.fw_ppec.night().rms(),
        night.rms()
    ));
    rows
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::night::ledger::Rms;
    use crate::night::script::{What, DEFAULT};

    /// `seconds` of samples at `rms` arcsec.
    fn rms(rms: f64, seconds: u64) -> Rms {
        let n = seconds * 1_000_000 / crate::st4_sim::SAMPLE_US;
        Rms {
            sum_sq: rms * rms * n as f64,
            n,
        }
    }

    fn section(first: Rms, later: Vec<Rms>) -> SectionScore {
        let What::Start(spec) = DEFAULT[0].what else {
            panic!("the default night starts with a section");
        };
        let settled = later.iter().fold(Rms::default(), |a, &w| a + w);
        SectionScore {
            section: spec,
            all: first + settled,
            first,
            settled,
            later,
        }
    }

    /// Each later window against the rest of its section without it; a
    /// window with less than half the first's imaging is left out; the
    /// first section counts for nothing.
    #[test]
    fn the_later_windows_are_tallied_against_the_rest_of_their_section() {
        let one = rms(1.0, 300);
        let sections = [
            section(rms(9.0, 300), vec![one, rms(9.0, 300)]),
            // The first 1.4 against the settled 1.10: above. Later, 1.3
            // against the rest (1.0): above; each 1.0 against the rest (1.0
            // and 1.3: 1.14) within; the thin window (100 s) left out.
            section(rms(1.4, 300), vec![one, one, rms(1.3, 300), rms(1.0, 100)]),
        ];
        let mut t = Vec::new();
        tally(&mut t, &sections);
        assert_eq!(t[0], WindowTally::default());
        assert_eq!(
            t[1],
            WindowTally {
                first_above: 1,
                firsts: 1,
                later_above: 1,
                laters: 3,
            }
        );
        assert!((t[1].later_within() - 2.0 / 3.0).abs() < 1e-12);
        assert_eq!(WindowTally::default().later_within(), 1.0);
    }
}
