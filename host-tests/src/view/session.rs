//! What the view has heard from the mount: the frames (bounded), the
//! board's identity, the counters, and the problems to show on the page.
//! Shared between the port's thread (which writes) and the HTTP server
//! (which reads) behind one mutex.

use super::telemetry::{self, Stage, Telemetry};
use std::collections::{BTreeMap, VecDeque};
use std::fmt::Write;
use std::time::Instant;

/// Frames kept: 20 000 frames of 2 s are 11 hours of guiding, a few MB.
pub const MAX_FRAMES: usize = 20_000;
/// Messages kept for the page's log.
pub const MAX_LOG: usize = 30;
/// Counters kept per group (a garbled `more=` cannot grow it without end).
pub const MAX_COUNTERS: usize = 64;

/// How the link stands.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum LinkState {
    Connecting,
    Connected,
    /// The port went away or cannot be opened: why.
    Down(String),
}

/// What the page warns about, by topic, while it holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Topic {
    Link,
    Identity,
    Version,
    Telemetry,
    Replies,
}

#[derive(Debug)]
pub struct Session {
    pub target: String,
    pub link: LinkState,
    pub product: Option<String>,
    pub version: Option<String>,
    pub reset: Option<String>,
    /// Problems that hold now, shown until cleared.
    pub problems: BTreeMap<Topic, String>,
    /// Recent events: (seconds since start, text).
    pub log: VecDeque<(f64, String)>,
    pub frames: VecDeque<Telemetry>,
    /// Frames dropped from the front to stay within [`MAX_FRAMES`].
    pub frames_dropped: u64,
    /// The stages of the newest frame.
    pub stages: Vec<Stage>,
    pub lines_ok: u64,
    pub lines_bad: u64,
    pub last_bad: Option<(String, String)>,
    pub garbage_bytes: u64,
    /// Counter groups (`f`, `g`, `l`, `s`, `p`, and `L` for `:~L#`).
    pub counters: BTreeMap<char, Vec<(String, String)>>,
    started: Instant,
}

/// Shortens what the port sent for showing: printable ASCII, at most 120.
pub fn shown(s: &str) -> String {
    s.chars()
        .take(120)
        .map(|c| {
            if c.is_ascii_graphic() || c == ' ' {
                c
            } else {
                '?'
            }
        })
        .collect()
}

impl Session {
    pub fn new(target: String) -> Self {
        Session {
            target,
            link: LinkState::Connecting,
            product: None,
            version: None,
            reset: None,
            problems: BTreeMap::new(),
            log: VecDeque::new(),
            frames: VecDeque::new(),
            frames_dropped: 0,
            stages: Vec::new(),
            lines_ok: 0,
            lines_bad: 0,
            last_bad: None,
            garbage_bytes: 0,
            counters: BTreeMap::new(),
            started: Instant::now(),
        }
    }

    pub fn note(&mut self, text: impl Into<String>) {
        if self.log.len() == MAX_LOG {
            self.log.pop_front();
        }
        self.log
            .push_back((self.started.elapsed().as_secs_f64(), text.into()));
    }

    /// A problem begins (noted once in the log, shown while it holds).
    pub fn problem(&mut self, topic: Topic, text: String) {
        if self.problems.get(&topic) != Some(&text) {
            self.note(text.clone());
            self.problems.insert(topic, text);
        }
    }

    pub fn clear(&mut self, topic: Topic) {
        self.problems.remove(&topic);
    }

    /// A telemetry line as the port sent it.
    pub fn line(&mut self, line: &str) {
        match telemetry::parse(line) {
            Ok(t) => self.frame(t),
            Err(e) => self.bad_line(line, &e.0),
        }
    }

    /// A line that could not be read (garbled, truncated).
    pub fn bad_line(&mut self, line: &str, why: &str) {
        self.lines_bad += 1;
        self.last_bad = Some((shown(line), why.to_string()));
        self.problem(
            Topic::Telemetry,
            "garbled or truncated telemetry lines: they are counted and skipped".into(),
        );
    }

    fn frame(&mut self, t: Telemetry) {
        self.lines_ok += 1;
        if self.frames.back().is_some_and(|b| t.t_ms < b.t_ms) {
            // The board's clock went back: it restarted. A new session.
            self.note(format!(
                "the board restarted (its time went back to {} s): a new session",
                t.t_ms / 1000
            ));
            self.frames.clear();
        }
        self.stages.clone_from(&t.stages);
        if self.frames.len() == MAX_FRAMES {
            self.frames.pop_front();
            self.frames_dropped += 1;
        }
        self.frames.push_back(t);
    }

    /// A counter group's reply `name=value ...`, from counter `from`
    /// (a reply ending ` more=K` is continued by the client).
    pub fn counters(&mut self, group: char, from: usize, fields: Vec<(String, String)>) {
        let list = self.counters.entry(group).or_default();
        list.truncate(from);
        for f in fields {
            if list.len() < MAX_COUNTERS {
                list.push(f);
            }
        }
    }

    /// The session as CSV: one row per frame, the stages as
    /// `period_ms:gate_pm` joined by `;`.
    pub fn csv(&self) -> String {
        let mut s = String::from(
            "t_ms,gear_ms,kind,obs_mas,pulse_mas,applied_mas,pred_mas,ff_mas_s,learn_pm,stages\n",
        );
        for f in &self.frames {
            let stages: Vec<String> = f
                .stages
                .iter()
                .map(|st| format!("{}:{}", st.period_ms, st.gate_pm))
                .collect();
            let _ = writeln!(
                s,
                "{},{},{},{},{},{},{},{},{},{}",
                f.t_ms,
                f.gear_ms,
                f.kind as char,
                f.obs_mas,
                f.pulse_mas,
                f.applied_mas,
                f.pred_mas,
                f.ff_mas_s,
                f.learn_pm,
                stages.join(";")
            );
        }
        s
    }
}
