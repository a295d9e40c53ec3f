//! The view's side of the command port: connects (and reconnects), checks
//! that the port is mkgp-mount's and which version, switches telemetry on,
//! and asks for the counters every few seconds. Everything it hears goes
//! to the [`Session`]; nothing the port sends can stop it.

use super::link::{Link, Target};
use super::session::{shown, LinkState, Session, Topic};
use super::stream::{Expect, Item, Stream};
use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// The products whose telemetry the view reads: a board, the simulator.
pub const PRODUCTS: [&str; 2] = ["mkgp-mount", "mkgp-mount-sim"];
/// The firmware version the view was written with (the workspace's).
pub const VERSION: &str = env!("CARGO_PKG_VERSION");
/// How often the counters are asked for.
const COUNTERS_EVERY: Duration = Duration::from_secs(3);
/// A reply later than this is lost.
const REPLY_TIMEOUT: Duration = Duration::from_secs(3);
/// Telemetry silent this long gets a notice (a frame is every few s).
const QUIET: Duration = Duration::from_secs(15);
/// Between attempts to open the port.
const RETRY: Duration = Duration::from_secs(1);
/// The counter groups shown: faults first.
const GROUPS: [char; 5] = ['f', 'l', 'g', 's', 'p'];

/// A query sent and what its reply means.
#[derive(Clone, Copy, Debug)]
enum Query {
    Product,
    Version,
    TelemetryOn,
    Learning,
    Counters(char, usize),
}

impl Query {
    fn command(self) -> (String, Expect) {
        match self {
            Query::Product => (":GVP#".into(), Expect::Hash),
            Query::Version => (":~V#".into(), Expect::Hash),
            Query::TelemetryOn => (":~T1#".into(), Expect::Byte),
            Query::Learning => (":~L#".into(), Expect::Hash),
            Query::Counters(g, 0) => (format!(":~C{g}#"), Expect::Hash),
            Query::Counters(g, k) => (format!(":~C{g}{k}#"), Expect::Hash),
        }
    }
}

/// `name=value` fields separated by spaces, or `None` if it is not that.
pub fn fields(reply: &str) -> Option<Vec<(String, String)>> {
    reply
        .split(' ')
        .map(|f| {
            let (k, v) = f.split_once('=')?;
            let ok = !k.is_empty()
                && k.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'_')
                && !v.is_empty()
                && v.bytes().all(|b| b.is_ascii_graphic());
            ok.then(|| (k.to_string(), v.to_string()))
        })
        .collect()
}

/// Major and minor of a version: what the telemetry's format follows.
fn major_minor(v: &str) -> Option<(&str, &str)> {
    let mut it = v.split('.');
    Some((it.next()?, it.next()?))
}

/// One connection's state.
struct Conn {
    link: Link,
    stream: Stream,
    sent: VecDeque<(Query, Instant)>,
    product_ok: bool,
    telemetry_on: bool,
    last_counters: Option<Instant>,
    last_line: Instant,
}

impl Conn {
    fn send(&mut self, q: Query) -> std::io::Result<()> {
        let (cmd, expect) = q.command();
        self.link.write_all(cmd.as_bytes())?;
        self.stream.expect(expect);
        self.sent.push_back((q, Instant::now()));
        Ok(())
    }

    /// A reply to the oldest query still waiting.
    fn reply(&mut self, s: &mut Session, text: &str) -> std::io::Result<()> {
        let Some((q, _)) = self.sent.pop_front() else {
            return Ok(());
        };
        match q {
            Query::Product => {
                s.product = Some(shown(text));
                self.product_ok = PRODUCTS.contains(&text);
                if self.product_ok {
                    s.clear(Topic::Identity);
                } else {
                    s.problem(
                        Topic::Identity,
                        format!(
                            "this port answers as {:?}, not mkgp-mount: the view reads only \
                             mkgp-mount's telemetry and does not switch it on",
                            shown(text)
                        ),
                    );
                }
            }
            Query::Version => {
                let f = fields(text).unwrap_or_default();
                let get = |k: &str| f.iter().find(|(n, _)| n == k).map(|(_, v)| v.clone());
                s.version = get("version");
                s.reset = get("reset");
                match &s.version {
                    Some(v) if major_minor(v) == major_minor(VERSION) => s.clear(Topic::Version),
                    other => s.problem(
                        Topic::Version,
                        format!(
                            "the firmware is version {}, the view was made for {VERSION}: \
                             lines it cannot read are counted and skipped",
                            other.as_deref().map_or("unknown".into(), shown)
                        ),
                    ),
                }
                // The identity is in: the telemetry, if this is our board.
                if self.product_ok && !self.telemetry_on {
                    self.send(Query::TelemetryOn)?;
                }
            }
            Query::TelemetryOn => {
                self.telemetry_on = text == "1";
                if self.telemetry_on {
                    s.note("telemetry on");
                    self.last_line = Instant::now();
                } else {
                    s.problem(
                        Topic::Replies,
                        format!("telemetry refused: {:?}", shown(text)),
                    );
                }
            }
            Query::Learning => match fields(text) {
                Some(f) => s.counters('L', 0, f),
                None => s.problem(
                    Topic::Replies,
                    format!("garbled reply to :~L#: {:?}", shown(text)),
                ),
            },
            Query::Counters(g, from) => match fields(text) {
                Some(mut f) => {
                    let more = f
                        .last()
                        .filter(|(k, _)| k == "more")
                        .and_then(|(_, v)| v.parse::<usize>().ok());
                    if more.is_some() {
                        f.pop();
                    }
                    s.counters(g, from, f);
                    // A continuation only forwards: a garbled `more` cannot loop.
                    if let Some(k) = more.filter(|&k| k > from && k < 100) {
                        self.send(Query::Counters(g, k))?;
                    }
                }
                None => s.problem(
                    Topic::Replies,
                    format!("garbled reply to {}: {:?}", q.command().0, shown(text)),
                ),
            },
        }
        Ok(())
    }

    /// What is due now: a lost reply, the counters, a quiet notice.
    fn tick(&mut self, s: &mut Session) -> std::io::Result<()> {
        if let Some((q, at)) = self.sent.front() {
            if at.elapsed() > REPLY_TIMEOUT {
                s.problem(
                    Topic::Replies,
                    format!(
                        "no reply to {} within {} s",
                        q.command().0,
                        REPLY_TIMEOUT.as_secs()
                    ),
                );
                self.sent.clear();
                self.stream.forget_pending();
            }
        }
        if !self.sent.is_empty() {
            return Ok(());
        }
        let due = self
            .last_counters
            .is_none_or(|t| t.elapsed() >= COUNTERS_EVERY);
        if due {
            self.last_counters = Some(Instant::now());
            if !self.product_ok {
                // Ask again: a board may be reflashed or replugged.
                self.send(Query::Product)?;
                return self.send(Query::Version);
            }
            if !self.telemetry_on {
                self.send(Query::TelemetryOn)?;
            }
            self.send(Query::Learning)?;
            for g in GROUPS {
                self.send(Query::Counters(g, 0))?;
            }
        }
        if self.telemetry_on && self.last_line.elapsed() > QUIET {
            s.problem(
                Topic::Telemetry,
                format!(
                    "no telemetry for {} s: is the mount guiding?",
                    self.last_line.elapsed().as_secs()
                ),
            );
        }
        Ok(())
    }
}

/// Serves one connection until the port goes away (the error) or `stop`.
fn session(target: &Target, s: &Mutex<Session>, stop: &AtomicBool) -> std::io::Result<()> {
    let link = Link::open(target)?;
    let mut c = Conn {
        link,
        stream: Stream::default(),
        sent: VecDeque::new(),
        product_ok: false,
        telemetry_on: false,
        last_counters: Some(Instant::now()),
        last_line: Instant::now(),
    };
    {
        let mut s = s.lock().unwrap();
        s.link = LinkState::Connected;
        s.clear(Topic::Link);
        s.note(format!("connected to {target}"));
    }
    c.send(Query::Product)?;
    c.send(Query::Version)?;
    let mut buf = [0u8; 4096];
    while !stop.load(Ordering::SeqCst) {
        let n = c.link.read(&mut buf, Duration::from_millis(100))?;
        let mut items = Vec::new();
        c.stream.push(&buf[..n], &mut |i| items.push(i));
        let mut s = s.lock().unwrap();
        for item in items {
            match item {
                Item::Reply(r) => c.reply(&mut s, &r)?,
                Item::Telemetry(l) => {
                    c.last_line = Instant::now();
                    if s.problems
                        .get(&Topic::Telemetry)
                        .is_some_and(|p| p.starts_with("no telemetry"))
                    {
                        s.clear(Topic::Telemetry);
                    }
                    s.line(&l);
                }
                Item::Garbled(g) => s.bad_line(&g, "cut short or too long"),
                Item::Garbage(k) => s.garbage_bytes += k as u64,
            }
        }
        c.tick(&mut s)?;
    }
    Ok(())
}

/// Runs until `stop`: connects, serves, and when the port goes away says
/// so on the page (until it is back) and tries again every second.
pub fn run(target: &Target, s: &Mutex<Session>, stop: &AtomicBool) {
    // Once up, a port that cannot be opened again has gone away.
    let mut was_up = false;
    while !stop.load(Ordering::SeqCst) {
        if let Err(e) = session(target, s, stop) {
            let mut s = s.lock().unwrap();
            was_up |= s.link == LinkState::Connected;
            let why = format!("{target}: {e}");
            s.link = LinkState::Down(why.clone());
            s.problem(
                Topic::Link,
                if was_up {
                    format!("the port went away ({why}); trying again every second")
                } else {
                    format!("cannot open the port ({why}); trying again every second")
                },
            );
        }
        std::thread::sleep(RETRY);
    }
}
