//! The command port's motion through the real loop: port pulses against
//! ST4 pulses, manual motion, ownership, position, the port's queries, and
//! random command streams.

use super::port_mount::{PortMount, PortState, StoreRequest};
use super::st4_feed::{EdgeQueue, EdgeSource, RawEdge};
use super::*;
use crate::counters::Counters;
use crate::mount::config::MountConfig;
use crate::mount::frame::{FeedForward, FrameKind, PulseShare};
use crate::mount::guiding::GuidingCounters;
use crate::mount::st4::Line;
use crate::port::coords::{Dec, Equatorial, Ra};
use crate::port::interpreter::STORE_REPLY_TIMEOUT_US;
use crate::port::mount_port::{Identity, ModelOrigin, StepCounts};
use crate::port::{Interpreter, ReplySink};
use crate::safety::reset_cause::ResetCause;
use crate::testing::SplitMix64;
use std::string::String;
use std::vec::Vec;

struct Edges(Vec<RawEdge>);

impl EdgeSource for Edges {
    fn next_edge(&mut self) -> Option<RawEdge> {
        (!self.0.is_empty()).then(|| self.0.remove(0))
    }
    fn queue(&self) -> EdgeQueue {
        EdgeQueue::default()
    }
}

#[derive(Default)]
struct Text(String);

impl ReplySink for Text {
    fn send(&mut self, reply: &[u8]) -> bool {
        self.0.push_str(core::str::from_utf8(reply).unwrap());
        true
    }
}

const IDENTITY: Identity = Identity {
    product: "mkgp-mount",
    version: "0.1.0",
    date: "Nov 23 2026",
    time: "05:00:00",
};

/// The loop on a mount whose axes follow the rates exactly, with a port.
struct Rig {
    mount: Mount,
    lp: ControlLoop,
    state: PortState,
    port: Interpreter,
    t: u64,
    ra: f64,
    dec: f64,
    rates: Rates,
    frames: Vec<Frame>,
}

impl Rig {
    fn new() -> Self {
        let mount = MountConfig::default().validate().unwrap();
        let (lp, rates) = ControlLoop::start(&mount, 0, 0);
        let state = PortState::new(&mount, IDENTITY, ResetCause::Pin);
        Rig {
            mount,
            lp,
            state,
            port: Interpreter::new(),
            t: 0,
            ra: 0.0,
            dec: 0.0,
            rates,
            frames: Vec::new(),
        }
    }

    fn steps(&self) -> StepCounts {
        StepCounts {
            ra: self.ra as i64,
            dec: self.dec as i64,
        }
    }

    fn advance_to(&mut self, t: u64) {
        let dt = (t - self.t) as f64 * 1e-6;
        self.ra += f64::from(self.rates.ra_steps_per_s) * dt;
        self.dec += f64::from(self.rates.dec_steps_per_s) * dt;
        self.t = t;
    }

    fn wake(&mut self, edges: Vec<RawEdge>) -> Wake {
        let w = self
            .lp
            .wake(self.t, self.steps().ra, &mut Edges(edges), None);
        if let Some(r) = w.rates {
            self.rates = r;
        }
        while let Some(r) = self.lp.take_frame() {
            self.frames.push(r.frame);
        }
        w
    }

    /// Runs the loop until `end`, waking when it asks.
    fn run_until(&mut self, end: u64) {
        loop {
            let next = self.lp.next_wake_us().max(self.t);
            if next > end {
                break;
            }
            self.advance_to(next);
            self.wake(Vec::new());
        }
        self.advance_to(end);
    }

    fn edge(&mut self, line: Line, asserted: bool) {
        let t = self.t;
        self.wake(std::vec![RawEdge {
            line,
            asserted,
            at_us: t,
        }]);
    }

    /// Sends `cmd` on the port now; the reply.
    fn ask(&mut self, cmd: &str) -> String {
        let mut out = Text::default();
        let steps = self.steps();
        let mut mount = PortMount {
            control: &mut self.lp,
            state: &mut self.state,
            now_us: self.t,
            steps,
            port: 0,
        };
        self.port.feed(cmd.as_bytes(), self.t, &mut mount, &mut out);
        out.0
    }

    /// The store's outcome for the port; the reply it sends.
    fn stored(&mut self, saved: bool) -> String {
        let mut out = Text::default();
        self.port.store_done(saved, &mut out);
        out.0
    }
}

const S: u64 = 1_000_000;

/// An RA pulse of 500 ms from the port and the same from the ST4 lines:
/// the same pulse counts and the same frame.
#[test]
fn a_port_pulse_makes_the_frame_an_st4_pulse_makes() {
    let mut st4 = Rig::new();
    let mut port = Rig::new();
    for rig in [&mut st4, &mut port] {
        rig.run_until(5 * S);
    }
    st4.edge(Line::RaPlus, true);
    assert_eq!(port.ask(":Mgw0500#"), "");
    for rig in [&mut st4, &mut port] {
        rig.run_until(5 * S + 500_000);
    }
    st4.edge(Line::RaPlus, false);
    for rig in [&mut st4, &mut port] {
        rig.run_until(6 * S);
    }
    let (a, b) = (st4.lp.guiding().counters(), port.lp.guiding().counters());
    assert_eq!((a.ra_pulses, b.ra_pulses), (1, 1));
    let measured = |r: &Rig| -> Vec<Frame> {
        r.frames
            .iter()
            .filter(|f| !f.filled)
            .copied()
            .collect::<Vec<_>>()
    };
    let (fa, fb) = (measured(&st4), measured(&port));
    assert_eq!((fa.len(), fb.len()), (1, 1), "{fa:?} {fb:?}");
    assert_eq!(fa[0].kind, FrameKind::Measured);
    assert_eq!(fa[0].kind, fb[0].kind);
    assert_eq!(fa[0].pulse_arcsec, fb[0].pulse_arcsec);
    assert!(fb[0].pulse_arcsec > 0.0);
    assert!((fa[0].gear_time_s - fb[0].gear_time_s).abs() < 1e-3);
    // The ST4 rig sets its rates a debounce late: its C differs by the
    // guide rate over that much.
    assert!((fa[0].gear_error_arcsec - fb[0].gear_error_arcsec).abs() < 0.05);
    assert_eq!(port.lp.port_counters().port_pulses, 1);
}

/// `:Mn#` at the guide rate is a pulse until `:Qn#`, and `:RG#`-`:Mw#`
/// likewise on RA; both set the guide rate and end with their stop.
#[test]
fn move_at_the_guide_rate_is_a_pulse_until_its_stop() {
    let mut r = Rig::new();
    r.run_until(S);
    r.ask(":RG#:Mn#:Mw#");
    r.run_until(S + 1);
    assert!((r.rates.dec_steps_per_s - r.mount.guide_dec_steps_per_s()).abs() < 1e-3);
    let guided = r.mount.sidereal_ra_steps_per_s() + r.mount.guide_ra_steps_per_s();
    assert!((r.rates.ra_steps_per_s - guided).abs() < 1e-3);
    assert_eq!(r.ask(":GU#"), "NpG^#");
    r.run_until(3 * S);
    r.ask(":Qn#:Qw#");
    r.run_until(3 * S + 1);
    assert_eq!(r.rates.dec_steps_per_s, 0.0);
    assert!((r.rates.ra_steps_per_s - r.mount.sidereal_ra_steps_per_s()).abs() < 1e-3);
    let c = r.lp.guiding().counters();
    assert_eq!((c.ra_pulses, c.dec_pulses), (1, 1));
    assert_eq!(r.ask(":GU#"), "Np^#");
}

/// Manual motion: bounded by the maximum, not learned (C stays 0), and
/// `:Q#` stops both axes while tracking goes on.
#[test]
fn manual_motion_is_bounded_and_not_learned() {
    let mut r = Rig::new();
    r.run_until(S);
    let max_ra = r.mount.max_ra_steps_per_s();
    let max_dec = r.mount.max_dec_steps_per_s();
    r.ask(":RS#:Mw#:RM#:Ms#");
    r.run_until(S + 1);
    assert_eq!(r.rates.ra_steps_per_s, max_ra, "sidereal + max clamped");
    assert!((r.rates.dec_steps_per_s + 0.5 * max_dec).abs() < 1e-3);
    r.run_until(4 * S);
    // East at the max rate would reverse the axis: it stops instead.
    r.ask(":RS#:Me#");
    r.run_until(4 * S + 1);
    assert_eq!(r.rates.ra_steps_per_s, 0.0);
    r.run_until(6 * S);
    r.ask(":Q#");
    r.run_until(8 * S);
    assert!((r.rates.ra_steps_per_s - r.mount.sidereal_ra_steps_per_s()).abs() < 1e-3);
    assert_eq!(r.rates.dec_steps_per_s, 0.0);
    // Thousands of steps moved, none of them a correction: C within the
    // one step the rig's whole step counts round off.
    let step = f64::from(r.mount.arcsec_per_ra_step());
    assert!(r.ra > 1000.0);
    assert!(
        r.lp.guiding().applied_arcsec().abs() < step,
        "{}",
        r.lp.guiding().applied_arcsec()
    );
    assert_eq!(r.lp.port_counters().manual_moves, 3);
    // The next guide frame sees only its own pulse.
    r.ask(":Mgw0500#");
    r.run_until(9 * S);
    let f = r.frames.last().copied().expect("the pulse's frame");
    let aggressiveness = f64::from(r.mount.config().guider_aggressiveness);
    let own = f64::from(f.pulse_arcsec) / aggressiveness;
    assert!(f.pulse_arcsec > 0.0);
    assert!((f64::from(f.gear_error_arcsec) - own).abs() < step, "{f:?}");
    // Tracking off stops RA, and is not learned either: C (which holds
    // the pulse's correction now) does not move.
    let c = r.lp.guiding().applied_arcsec();
    r.ask(":Td#");
    r.run_until(12 * S);
    assert_eq!(r.rates.ra_steps_per_s, 0.0);
    assert_eq!(r.ask(":GT#"), "00.0#");
    assert!((r.lp.guiding().applied_arcsec() - c).abs() < step);
}

/// While the port holds the RA axis (east at the highest rate: the axis
/// stands) nothing it does is gear correction, the feed-forward's share
/// included: C holds, and the frames meanwhile are not learned. The
/// feed-forward once counted as applied though the clamp took it away,
/// and the guider's silent frames were learned as "no error".
#[test]
fn what_the_port_holds_is_neither_applied_nor_learned() {
    let mut r = Rig::new();
    r.run_until(S);
    // A guide pulse: the guider is heard, frames are filled from now on.
    r.ask(":Mgw0200#");
    r.run_until(S / 2 * 3);
    let ff = FeedForward {
        rate_arcsec_per_s: 1.0,
        from_gear_s: 0.0,
        until_gear_s: 1e9,
        pulse_share: PulseShare::FULL,
    };
    r.advance_to(S / 2 * 3 + 1);
    let w =
        r.lp.wake(r.t, r.steps().ra, &mut Edges(Vec::new()), Some(ff));
    if let Some(rates) = w.rates {
        r.rates = rates;
    }
    r.run_until(2 * S);
    assert!(r.lp.guiding().feed_forward_now() > 0.9);
    let c = r.lp.guiding().applied_arcsec();
    let frames = r.frames.len();
    r.ask(":RS#:Me#");
    r.run_until(12 * S);
    assert_eq!(r.rates.ra_steps_per_s, 0.0);
    let step = f64::from(r.mount.arcsec_per_ra_step());
    let held = r.lp.guiding().applied_arcsec() - c;
    assert!(held.abs() < step, "C moved by {held} arcsec");
    let during = &r.frames[frames..];
    assert!(during.len() >= 4, "{}", during.len());
    assert!(
        during.iter().all(|f| f.kind == FrameKind::Moved),
        "{during:?}"
    );
}

/// The first source on an axis keeps it; the other is refused, counted,
/// and leaves nothing behind (no stray end, no frame of its own).
#[test]
fn an_st4_pulse_and_a_port_pulse_on_one_axis_the_first_keeps_it() {
    let mut r = Rig::new();
    r.run_until(S);
    // ST4 first: the port's pulse on RA is refused, its Dec pulse not.
    r.edge(Line::RaMinus, true);
    r.run_until(S + 10_000);
    r.ask(":Mgw1000#:Mgn0200#");
    assert_eq!(r.lp.port_counters().port_refused, 1);
    r.run_until(S + 20_000);
    let guided = r.mount.sidereal_ra_steps_per_s() - r.mount.guide_ra_steps_per_s();
    assert!((r.rates.ra_steps_per_s - guided).abs() < 1e-3);
    assert!(r.rates.dec_steps_per_s > 0.0);
    r.run_until(S + 300_000);
    r.edge(Line::RaMinus, false);
    r.run_until(2 * S);
    // Port first: the ST4 pulse on Dec is refused up to its release.
    r.ask(":Mgs1000#");
    r.run_until(2 * S + 100_000);
    r.edge(Line::DecPlus, true);
    r.run_until(2 * S + 200_000);
    assert!(r.rates.dec_steps_per_s < 0.0, "the port's south pulse runs");
    r.edge(Line::DecPlus, false);
    r.run_until(4 * S);
    assert_eq!(r.rates.dec_steps_per_s, 0.0);
    let p = r.lp.port_counters();
    assert_eq!((p.port_refused, p.st4_refused, p.port_pulses), (1, 1, 2));
    let c = r.lp.guiding().counters();
    assert_eq!((c.ra_pulses, c.dec_pulses, c.stray_ends), (1, 2, 0));
    assert_eq!(
        r.ask(&format!(":~Cg{}#", GuidingCounters::NAMES.len())),
        "port_pulses=2 manual_moves=0 port_refused=1 st4_refused=1#"
    );
}

/// After a sync RA holds under tracking and moves with the steps beyond
/// it; Dec follows the Dec steps.
#[test]
fn ra_and_dec_follow_the_step_counters_after_a_sync() {
    let mut r = Rig::new();
    r.run_until(S);
    assert_eq!(r.ask(":Sr06:00:00#:Sd+10*00:00#"), "11");
    assert_eq!(r.ask(":CM#"), "N/A#");
    r.run_until(100 * S);
    assert_eq!(r.ask(":GR#:GD#"), "06:00:00#+10*00:00#");
    // 20 s west at the guide rate: 20 x 7.52 arcsec = 10 s of RA less.
    r.ask(":Mgw20000#");
    r.run_until(130 * S);
    assert_eq!(r.ask(":GR#"), "05:59:50#");
    r.ask(":Mgn20000#");
    r.run_until(160 * S);
    let guide = r.mount.guide_rate_arcsec_per_s() as f64;
    let want = Dec::from_arcsec(36_000 + libm::round(20.0 * guide) as i32).unwrap();
    let mut text = crate::port::reply::Reply::new();
    want.write(crate::port::coords::Precision::High, &mut text);
    let want = core::str::from_utf8(text.as_bytes()).unwrap();
    assert_eq!(r.ask(":GD#"), std::format!("{want}#"));
    let at = r.state.position(r.steps(), r.t);
    assert_eq!(at.ra, Ra::from_seconds(6 * 3600 - 10).unwrap());
    let _ = Equatorial::default();
}

/// Identity, learning, stages and counters come from the loop and the
/// caller's learner summary; `:~R#` is a request the caller takes.
#[test]
fn the_port_reads_the_loop_and_the_learner_summary() {
    let mut r = Rig::new();
    r.run_until(S);
    assert_eq!(r.ask(":GVP#:GVN#"), "mkgp-mount#0.1.0#");
    assert_eq!(
        r.ask(":~L#"),
        "learn_pm=0 ff_mas_s=0 ff_on=1 stages=0 from=cold#"
    );
    r.state.learner.learned_permille = 420;
    let stage = crate::port::mount_port::Stage {
        period_ms: 478_689,
        amplitude_mas: 3_000,
        gate_permille: 900,
    };
    r.state.learner.stages.push(stage).unwrap();
    r.state.learner.counters.frames = 7;
    r.state.model_origin = ModelOrigin::Park;
    assert_eq!(
        r.ask(":~L#"),
        "learn_pm=420 ff_mas_s=0 ff_on=1 stages=1 from=park#"
    );
    assert_eq!(
        r.ask(":~S0#:~S1#"),
        "period_ms=478689 amp_mas=3000 gate_pm=900#none#"
    );
    assert_eq!(
        r.ask(":~Cl#"),
        "frames=7 learned=0 not_learned=0 dithers=0 bumps=0#"
    );
    r.state.learner.faults.inference_failures = 2;
    assert_eq!(
        r.ask(":~Cf#"),
        "lost_edges=0 model_bad_time=0 model_bad_input=0 model_inference_failures=2 \
         model_grid_restarts=0 model_bad_dithers=0 store_rewrites=0 store_unverified=0#"
    );
    assert_eq!(r.ask(":~F0#:GU#"), "1Np/#");
    assert!(!r.lp.feed_forward_on());
    assert!(!r.state.take_reset_request());
    assert_eq!(r.ask(":~R#"), "1");
    assert!(r.state.take_reset_request());
    assert!(!r.state.take_reset_request());
    assert_eq!(r.ask(":~V#"), "version=0.1.0 reset=reset_pin#");
    // The pending configuration starts as the running one; a save is
    // refused without a store. With one, each save's reply waits for the
    // store's outcome: `1` saved and read back, `0` not; one at a time per
    // port, and `0` if no outcome comes in time.
    assert_eq!(
        r.ask(":~Kguider_aggressiveness#"),
        "guider_aggressiveness=0.7#"
    );
    assert_eq!(r.ask(":~Kguider_aggressiveness=0.5#"), "1");
    assert_eq!(r.ask(":~KW#:~W#"), "00");
    assert_eq!(r.state.take_store_request(), None);
    r.state.store = true;
    assert_eq!(r.ask(":~KW#"), "");
    let Some(StoreRequest::Config { config, port: 0 }) = r.state.take_store_request() else {
        panic!("a configuration to save, for port 0");
    };
    assert_eq!(config.guider_aggressiveness, 0.5);
    assert_eq!(r.ask(":~W#"), "0");
    assert_eq!(r.state.take_store_request(), None);
    assert_eq!(r.stored(true), "1");
    assert_eq!(r.stored(true), "");
    assert_eq!(r.ask(":~W#"), "");
    assert_eq!(
        r.state.take_store_request(),
        Some(StoreRequest::Model { port: 0 })
    );
    assert_eq!(r.stored(false), "0");
    assert_eq!(r.ask(":~W#"), "");
    r.t += STORE_REPLY_TIMEOUT_US - 1;
    assert_eq!(r.ask(""), "");
    r.t += 1;
    assert_eq!(r.ask(""), "0");
    assert_eq!(r.stored(true), "");
    assert!(r.ask(":~Cp#").ends_with(" store_timeouts=1#"));
    // The loop runs on with what it started with.
    assert_eq!(r.mount.config().guider_aggressiveness, 0.7);
}

/// Random command streams (guides, moves, stops, rates, tracking, syncs,
/// queries, garbage) with random ST4 edges, through the real loop: no rate
/// outside [0, max] (RA) or beyond ±max (Dec), no pulse held beyond 60 s,
/// no wake-up asked in the past except "now" after a command.
#[test]
fn random_command_streams_keep_the_rates_and_pulses_bounded() {
    const WORDS: [&str; 24] = [
        ":Mgn", ":Mgs", ":Mge", ":Mgw", ":Mn#", ":Ms#", ":Me#", ":Mw#", ":Qn#", ":Qs#", ":Qe#",
        ":Qw#", ":Q#", ":RG#", ":RC#", ":RM#", ":RS#", ":Te#", ":Td#", ":CM#", ":GU#", ":GR#",
        ":~F0#", ":~F1#",
    ];
    let mut r = Rig::new();
    let mut rng = SplitMix64::new(8);
    let max_ra = r.mount.max_ra_steps_per_s();
    let max_dec = r.mount.max_dec_steps_per_s();
    let mut ram_cmds = 0u32;
    for _ in 0..100_000 {
        let span = if rng.below(10) == 0 {
            5_000_000
        } else {
            50_000
        };
        let t = r.t + rng.below(span);
        // Wake when the loop asks, up to t.
        r.run_until(t);
        match rng.below(4) {
            0 => {
                let line = Line::ALL[rng.below(4) as usize];
                let asserted = rng.below(2) == 0;
                r.edge(line, asserted);
            }
            1 => {
                let mut cmd = String::new();
                for _ in 0..1 + rng.below(3) {
                    let w = WORDS[rng.below(WORDS.len() as u64) as usize];
                    cmd.push_str(w);
                    if w.len() == 4 {
                        // A timed guide: up to 99999 ms (beyond 60 s refused).
                        cmd.push_str(&std::format!("{}#", rng.below(100_000)));
                    }
                }
                if rng.below(20) == 0 {
                    cmd.push(char::from(rng.below(128) as u8));
                }
                r.ask(&cmd);
                ram_cmds += 1;
            }
            _ => {}
        }
        // Commands take effect at the next wake-up, which is now.
        if r.lp.next_wake_us() <= r.t {
            r.wake(Vec::new());
        }
        let rates = r.rates;
        assert!((0.0..=max_ra).contains(&rates.ra_steps_per_s), "{rates:?}");
        assert!(rates.dec_steps_per_s.abs() <= max_dec, "{rates:?}");
        for axis in [Axis::Ra, Axis::Dec] {
            if let Some(start) = r.lp.guiding().pulse_start_us(axis) {
                assert!(
                    r.t - start <= 60 * S,
                    "{axis:?} held since {start}, now {}",
                    r.t
                );
            }
        }
    }
    let p = r.lp.port_counters();
    assert!(ram_cmds > 10_000 && p.port_pulses > 1_000 && p.manual_moves > 1_000);
    assert!(p.port_refused > 0 && p.st4_refused > 0, "{p:?}");
}

/// `:hP#` parks where the mount points: port motion and tracking stop, the
/// counts go to the store; while parked the port moves nothing; `:hR#`
/// tracks again and tells the store.
#[test]
fn park_and_unpark() {
    let mut r = Rig::new();
    r.state.store = true;
    r.run_until(S);
    assert!(r.rates.ra_steps_per_s > 0.0);
    assert_eq!(r.ask(":GU#"), "Np^#");
    assert_eq!(r.ask(":Mgn5000#:hP#"), "");
    let parked_at = r.steps();
    r.run_until(2 * S);
    assert_eq!(r.rates.ra_steps_per_s, 0.0);
    assert_eq!(r.rates.dec_steps_per_s, 0.0);
    assert_eq!(r.steps(), parked_at);
    assert_eq!(
        r.state.take_store_request(),
        Some(StoreRequest::Park(parked_at))
    );
    assert_eq!(r.ask(":GU#"), "nNP^#");
    // Parked: no pulse, no tracking from the port, no second park.
    assert_eq!(r.ask(":Mgn1000#:Te#:hP#"), "1");
    r.run_until(3 * S);
    assert_eq!(r.steps(), parked_at);
    assert_eq!(r.state.take_store_request(), None);
    assert_eq!(r.ask(":hR#:GU#"), "Np^#");
    assert_eq!(r.state.take_store_request(), Some(StoreRequest::Unpark));
    r.run_until(4 * S);
    assert!(r.rates.ra_steps_per_s > 0.0);
}
