//! One night through the `st4` rig: the script's events at their times,
//! and between them the PHD2-like guider and the imaging sequence.
//!
//! The rig's own guider is switched off (`guider_on`); this module takes
//! each exposure from the rig's camera and decides as PHD2 would: in a
//! calibration the next step's pulse, while guiding the rig's own
//! correction (`Rig::guide`: its hysteresis and its dithers), or a DROP
//! when the star is lost. The imaging sequence runs on top: a main
//! exposure, the download (no guide frames), a dither,
//! settling (PHD2's: within [`SETTLE_PX`] for [`SETTLE_S`], at most
//! [`SETTLE_TIMEOUT_S`]), the next exposure. The score covers imaging only
//! (the main camera exposing), per section and split at
//! [`FIRST_S`] after guiding began.

use super::calibration::{self, Calibration, Leg, Next};
use super::ledger::{self, Activity, Rms, Window};
use super::phd2_writer::{Calibrated, Header, Phd2Writer, Pointing, Row};
use super::script::{self, Event, Section, Way, What};
use crate::gp::trace;
use crate::mount_sim::IDENTITY;
use crate::noise::{self, Gaussian};
use crate::st4_sim::{Exposure, GuiderSettings, Rig};
use mkgp_mount::control_loop::port_mount::PortState;
use mkgp_mount::mount::config::SIDEREAL_ARCSEC_PER_S;
use mkgp_mount::mount::learner::FIRMWARE_STAGES;
use mkgp_mount::mount::st4::Line;
use mkgp_mount::port::mount_port::ManualRate;
use mkgp_mount::port::{Interpreter, ReplySink};
use mkgp_mount::safety::reset_cause::ResetCause;
use mkgp_mount::testing::SplitMix64;
use std::fmt::Write;

/// A section's first minutes, scored apart, s.
pub const FIRST_S: f64 = 300.0;
/// PHD2's settling: the star within this distance (px, both axes) ...
pub const SETTLE_PX: f64 = 2.5;
/// ... for this long (s), or the sequence goes on after the timeout.
pub const SETTLE_S: f64 = 10.0;
pub const SETTLE_TIMEOUT_S: f64 = 60.0;
/// The hour angle where the night's first target starts, h.
pub const FIRST_HOUR_ANGLE: f64 = -3.0;
/// The camera's angle on the sky before the flip (PHD2's xAngle), deg.
pub const CAMERA_ANGLE_DEG: f64 = 12.0;
/// Arcsec of the RA axis per hour of hour angle.
const ARCSEC_PER_HOUR: f64 = 54_000.0;

const US: f64 = 1e6;

fn us(s: f64) -> u64 {
    (s * US) as u64
}

fn secs(us: u64) -> f64 {
    us as f64 / US
}

/// The section's score: imaging over the whole section, over its first
/// [`FIRST_S`] of guiding and after, and over each later [`FIRST_S`] of
/// guiding that the section holds whole (the spread a window that long
/// has anywhere in the section).
#[derive(Debug, Clone, PartialEq)]
pub struct SectionScore {
    pub section: Section,
    pub all: Rms,
    pub first: Rms,
    pub settled: Rms,
    pub later: Vec<Rms>,
}

/// What a PHD2-like guider on its own would log, with the truth beside it.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct GuideLogs {
    /// The PHD2 guide log.
    pub phd2: String,
    /// Per guide row: `section,frame,time_s,gear_time_s,gear_error_px,
    /// pointing_px,ra_raw_px` (the mean gear error and the mean pointing
    /// minus the lock over the exposure, without the camera's noise).
    pub truth: String,
    /// Per guide row, with the MKGP firmware: what its learner holds after
    /// the row ([`learner_header`]); the header alone with the other
    /// firmwares.
    pub learner: String,
}

/// The header of [`GuideLogs::truth`].
pub const TRUTH_HEADER: &str =
    "section,frame,time_s,gear_time_s,gear_error_px,pointing_px,ra_raw_px";

/// The header of [`GuideLogs::learner`]: the row as in the truth, the
/// pointing and the guider's RA correction (px), the share of the pulses
/// carried out, the part of a pulse learned, the feed-forward's weight, the
/// model's blend weight, the frames the learner took and learned and the
/// framer filled so far, the steps of the star taken off its observations
/// so far (px; a dither's move is one), and each stage's tracked period
/// (s) and gate (0: the stage is not in the model).
pub fn learner_header() -> String {
    String::from(
        "section,frame,time_s,gear_time_s,pointing_px,guide_px,pulse_share,pulse_weight,\
         feed_forward_weight,blend_weight,frames,learned,filled_frames,step_level_px",
    ) + &trace::stage_header(FIRMWARE_STAGES)
}

/// The logs of a night being written.
struct Logging {
    phd2: Phd2Writer,
    truth: String,
    learner: String,
}

/// What the imaging sequence is doing.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Imaging {
    /// Nothing to image: calibrating, or interrupted (refocus, clouds).
    Idle,
    Exposing {
        until_us: u64,
    },
    Downloading {
        from_us: u64,
        until_us: u64,
    },
    /// Waiting for the guider: in range since, and the timeout.
    Settling {
        in_range_since: Option<u64>,
        timeout_us: u64,
        /// The next row is the dither's own (not judged).
        dither_row: bool,
    },
}

/// The calibration under way: its plan and where the legs started.
#[derive(Debug, Clone, Copy)]
struct Calibrating {
    plan: Calibration,
    /// The west leg's start: measured RA and Dec, arcsec.
    origin: Option<(f64, f64)>,
    /// The current leg pair's start in camera px.
    leg_origin: (f64, f64),
    west: Option<(f64, f64)>,
    began_us: u64,
}

#[derive(Debug, Clone, Copy)]
enum Phase {
    Calibrating(Calibrating),
    Guiding,
}

/// The section that runs.
struct Active {
    index: usize,
    spec: Section,
    phase: Phase,
    /// Guiding: when it began, the calibration it uses, its last row.
    guide_start_us: u64,
    calibrated: Calibrated,
    frame: u32,
    /// The lock in camera px, and the Dec the guider locked on, arcsec.
    lock_cam: (f64, f64),
    dec_lock: f64,
    /// Where the star appears on the camera when the section starts.
    spot: (f64, f64),
    imaging: Imaging,
    subs: u32,
    lost_frames: u32,
    lost_since_us: u64,
    hidden_until_us: Option<u64>,
    paused_until_us: Option<u64>,
    /// The interruption that settling follows, and since when.
    interrupted: Option<(Activity, u64)>,
    score_from: (f64, u64),
    /// The rig's running sums at each [`FIRST_S`] of guiding.
    marks: Vec<(f64, u64)>,
    mass: f64,
    snr: f64,
}

impl Active {
    /// When the running sums are read next: every [`FIRST_S`] of guiding.
    fn next_mark_us(&self) -> u64 {
        self.guide_start_us + us(FIRST_S) * (self.marks.len() as u64 + 1)
    }
}

/// A reply sink that drops the port's replies (the night reads none).
struct Discard;

impl ReplySink for Discard {
    fn send(&mut self, _reply: &[u8]) -> bool {
        true
    }
}

/// What a night leaves behind.
pub struct Outcome {
    pub rig: Rig,
    pub sections: Vec<SectionScore>,
    pub windows: Vec<Window>,
    /// Every dither's amount, arcsec (positive: RA+).
    pub dithers: Vec<f64>,
    pub logs: Option<GuideLogs>,
}

/// The night being run.
pub struct Session {
    rig: Rig,
    seed: u64,
    port: Interpreter,
    port_state: PortState,
    dec_noise: Option<(f64, Gaussian)>,
    log: Option<Logging>,
    flips: u32,
    hand_hours: f64,
    section: Option<Active>,
    sections: Vec<SectionScore>,
    windows: Vec<Window>,
    dithers: Vec<f64>,
    /// A port motion to stop, when, and a flip's camera turning over then.
    slew_stop: Option<(u64, Way, bool)>,
    /// The guider stopped at.
    off_since_us: Option<u64>,
    /// The interval of the guider's frames, this section's or the last.
    cadence_us: u64,
}

/// A value from the seed and a key, uniform in [0, 1): the same for every
/// firmware whatever the night did before it.
fn draw(seed: u64, key: u64) -> f64 {
    SplitMix64::new(seed ^ key.wrapping_mul(0x9E37_79B9_7F4A_7C15)).uniform()
}

/// (x, y) turned by `deg`.
fn rotate(v: (f64, f64), deg: f64) -> (f64, f64) {
    let (s, c) = deg.to_radians().sin_cos();
    (v.0 * c - v.1 * s, v.0 * s + v.1 * c)
}

fn add(a: (f64, f64), b: (f64, f64)) -> (f64, f64) {
    (a.0 + b.0, a.1 + b.1)
}

fn sub(a: (f64, f64), b: (f64, f64)) -> (f64, f64) {
    (a.0 - b.0, a.1 - b.1)
}

/// The rig's guider, at the section's exposure.
fn guider_for(spec: &Section) -> GuiderSettings {
    GuiderSettings {
        exposure_s: spec.exposure_s,
        ..GuiderSettings::default()
    }
}

fn normal_hours(h: f64) -> f64 {
    (h + 12.0).rem_euclid(24.0) - 12.0
}

fn normal_deg(d: f64) -> f64 {
    180.0 - (180.0 - d).rem_euclid(360.0)
}

impl Session {
    /// A night on `rig` (its own guider switched off), seeded `seed`;
    /// `log`: also write the guider's side as a PHD2 log.
    pub fn new(mut rig: Rig, noise_px: f64, seed: u64, log: bool) -> Self {
        rig.guider_on = false;
        rig.score_window_s = (f64::INFINITY, f64::INFINITY);
        let port_state = PortState::new(&rig.mount, IDENTITY, ResetCause::PowerOn);
        Session {
            rig,
            seed,
            port: Interpreter::default(),
            port_state,
            dec_noise: (noise_px > 0.0).then(|| (noise_px, noise::dec(seed))),
            log: log.then(|| Logging {
                phd2: Phd2Writer::new(),
                truth: format!("{TRUTH_HEADER}\n"),
                learner: format!("{}\n", learner_header()),
            }),
            flips: 0,
            hand_hours: 0.0,
            section: None,
            sections: Vec::new(),
            windows: Vec::new(),
            dithers: Vec::new(),
            slew_stop: None,
            off_since_us: Some(0),
            cadence_us: 0,
        }
    }

    /// Runs `script` (checked by `script::check`) to its end.
    pub fn run(mut self, script: &[Event]) -> Outcome {
        for e in script {
            self.advance_to(us(e.at_s));
            self.apply(e.what);
        }
        let end_s = secs(self.rig.now_us);
        Outcome {
            rig: self.rig,
            sections: self.sections,
            windows: self.windows,
            dithers: self.dithers,
            logs: self.log.map(|l| GuideLogs {
                phd2: l.phd2.close(end_s),
                truth: l.truth,
                learner: l.learner,
            }),
        }
    }

    fn writer(&mut self) -> Option<&mut Phd2Writer> {
        self.log.as_mut().map(|l| &mut l.phd2)
    }

    fn info(&mut self, message: &str) {
        if let Some(w) = self.writer() {
            w.info(message);
        }
    }

    /// A window of `activity`; the frames made before it may reach the
    /// learner up to a filled frame's grace after it opens.
    fn open_window(&mut self, activity: Activity, from_us: u64, until_us: u64) {
        self.windows.push(Window {
            activity,
            from_us,
            until_us,
            made_before_us: ledger::fill_grace_us(self.cadence_us),
        });
    }

    fn window(&mut self, activity: Activity, from_us: u64) {
        let until_us = self.rig.now_us;
        self.open_window(activity, from_us, until_us);
    }

    fn scoring(&mut self, on: bool) {
        self.rig.score_window_s = if on {
            (0.0, f64::INFINITY)
        } else {
            (f64::INFINITY, f64::INFINITY)
        };
    }

    /// The hour angle the mount points at now, h: the RA axis turns with
    /// it (the gear time, from the steps), a push by hand moves it without
    /// a step, a flip turns the axis 12 h past it.
    fn hour_angle(&self) -> f64 {
        let axis_hours = self.rig.gear_time_s() * SIDEREAL_ARCSEC_PER_S / ARCSEC_PER_HOUR;
        normal_hours(FIRST_HOUR_ANGLE + axis_hours + self.hand_hours - 12.0 * self.flips as f64)
    }

    /// A section's header now, with the lock on the star at `star`.
    fn header(&self, spec: &Section, star: (f64, f64)) -> Header {
        Header {
            exposure_ms: (spec.exposure_s * 1e3).round() as u64,
            pointing: Pointing {
                dec_deg: spec.dec_deg,
                hour_angle_hr: self.hour_angle(),
                pier_west: self.flips.is_multiple_of(2),
            },
            lock: star,
            star,
        }
    }

    /// The camera's angle now: turned over by each flip.
    fn camera_deg(&self) -> f64 {
        normal_deg(CAMERA_ANGLE_DEG + 180.0 * self.flips as f64)
    }

    /// The Dec the guider measures now, arcsec.
    fn dec_measured(&mut self) -> f64 {
        let noise = match self.dec_noise.as_mut() {
            Some((sigma, g)) => *sigma * g.next(),
            None => 0.0,
        };
        self.rig.dec_arcsec() + noise
    }

    /// Runs the night up to `t_us`: exposures, the sequence's deadlines.
    fn advance_to(&mut self, t_us: u64) {
        while self.rig.now_us < t_us {
            let limit = self.next_deadline().map_or(t_us, |d| d.min(t_us));
            if let Some(e) = self.rig.run_to_exposure(limit) {
                self.on_exposure(e);
            }
            self.on_deadlines();
        }
    }

    fn next_deadline(&self) -> Option<u64> {
        let mut d: Vec<u64> = Vec::new();
        if let Some((t, _, _)) = self.slew_stop {
            d.push(t);
        }
        if let Some(a) = &self.section {
            match a.imaging {
                Imaging::Exposing { until_us } | Imaging::Downloading { until_us, .. } => {
                    d.push(until_us)
                }
                _ => {}
            }
            d.extend(a.hidden_until_us);
            d.extend(a.paused_until_us);
            if matches!(a.phase, Phase::Guiding) {
                d.push(a.next_mark_us());
            }
        }
        d.into_iter().min()
    }

    fn on_deadlines(&mut self) {
        let now = self.rig.now_us;
        if let Some((_, way, flip)) = self.slew_stop.filter(|s| s.0 <= now) {
            self.slew_stop = None;
            self.feed_port(match way {
                Way::West => b":Qw#",
                Way::East => b":Qe#",
            });
            if flip {
                self.flips += 1;
            }
        }
        let Some(a) = self.section.as_mut() else {
            return;
        };
        if matches!(a.phase, Phase::Guiding) && a.next_mark_us() <= now {
            a.marks.push(self.rig.score_sums());
        }
        let resumed = a.paused_until_us.is_some_and(|t| t <= now);
        if resumed {
            a.paused_until_us = None;
        }
        let cleared = a.hidden_until_us.is_some_and(|t| t <= now);
        if cleared {
            a.hidden_until_us = None;
        }
        let imaging = a.imaging;
        if resumed {
            self.info("Server received RESUME");
        }
        if resumed || cleared {
            self.settle_after_interruption();
            return;
        }
        match imaging {
            Imaging::Exposing { until_us } if until_us <= now => self.download(),
            Imaging::Downloading { from_us, until_us } if until_us <= now => {
                self.window(Activity::Download, from_us);
                self.after_download();
            }
            _ => {}
        }
    }

    /// The sub just taken downloads: no guide frame for its length, drawn
    /// from the seed.
    fn download(&mut self) {
        let now = self.rig.now_us;
        let Some(a) = self.section.as_mut() else {
            return;
        };
        let (lo, hi) = a.spec.download_s;
        let key = ((a.index as u64) << 32) | u64::from(a.subs);
        let until = now + us(lo + (hi - lo) * draw(self.seed, key));
        a.imaging = Imaging::Downloading {
            from_us: now,
            until_us: until,
        };
        self.scoring(false);
    }

    /// After a download: a dither and settling, or the next sub at once.
    fn after_download(&mut self) {
        let camera = self.camera_deg();
        let Some(a) = self.section.as_mut() else {
            return;
        };
        a.subs += 1;
        if a.spec.dither_px <= 0.0 {
            a.imaging = Imaging::Exposing {
                until_us: self.rig.now_us + us(a.spec.sub_s),
            };
            self.scoring(true);
            return;
        }
        let key = (1 << 62) | ((a.index as u64) << 32) | u64::from(a.subs);
        let u = draw(self.seed, key);
        let size = a.spec.dither_px * (0.5 + 0.5 * (2.0 * u - 1.0).abs());
        let amount = if u < 0.5 { -size } else { size };
        self.rig.dither(amount);
        self.dithers.push(amount);
        // PHD2 writes the lock's move in the mount's axes (RA only here):
        // the dither row after it measures and moves -X.
        let x = -amount;
        a.lock_cam = add(a.lock_cam, rotate((x, 0.0), camera));
        a.imaging = Imaging::Settling {
            in_range_since: None,
            timeout_us: self.rig.now_us + us(SETTLE_TIMEOUT_S),
            dither_row: true,
        };
        a.interrupted = Some((Activity::Settling, self.rig.now_us));
        let lock = a.lock_cam;
        self.info(&format!(
            "DITHER by {x:.3}, 0.000, new lock pos = {:.3}, {:.3}",
            lock.0, lock.1
        ));
        self.info("SETTLING STATE CHANGE, Settling started");
    }

    /// Imaging waits for the guider to settle (after a refocus, clouds, a
    /// new section).
    fn settle_after_interruption(&mut self) {
        let now = self.rig.now_us;
        let ended = self.section.as_mut().and_then(|a| a.interrupted.take());
        if let Some((activity, from)) = ended {
            self.window(activity, from);
        }
        let Some(a) = self.section.as_mut() else {
            return;
        };
        a.imaging = Imaging::Settling {
            in_range_since: None,
            timeout_us: now + us(SETTLE_TIMEOUT_S),
            dither_row: false,
        };
        a.interrupted = Some((Activity::Settling, now));
        self.info("SETTLING STATE CHANGE, Settling started");
    }

    fn feed_port(&mut self, bytes: &[u8]) {
        self.rig
            .feed_port(&mut self.port, &mut self.port_state, bytes, &mut Discard);
    }

    fn apply(&mut self, what: What) {
        let now = self.rig.now_us;
        match what {
            What::Start(spec) => self.start(spec),
            What::Stop => self.stop(),
            What::End => {
                self.stop();
                self.off_since_us = None;
            }
            What::Slew { way, rate, seconds } => self.slew(way, rate, seconds, false),
            What::Flip => {
                let max = self.rig.mount.config().max_rate_sidereal as f64;
                self.slew(Way::West, ManualRate::Max, script::flip_seconds(max), true);
            }
            What::Push { hours } => {
                self.hand_hours += hours;
                self.rig.hand_arcsec -= hours * ARCSEC_PER_HOUR;
                self.window(Activity::Push, now);
            }
            What::LoseStar { frames } => {
                if let Some(a) = self.section.as_mut() {
                    a.lost_frames = frames;
                    a.lost_since_us = now;
                }
            }
            What::Refocus { seconds } => {
                self.interrupt(Activity::Refocus);
                let until = now + us(seconds);
                if let Some(a) = self.section.as_mut() {
                    a.paused_until_us = Some(until);
                }
                self.info("Server received PAUSE");
            }
            What::Clouds { seconds } => {
                self.interrupt(Activity::Clouds);
                if let Some(a) = self.section.as_mut() {
                    a.hidden_until_us = Some(now + us(seconds));
                }
            }
        }
    }

    /// Imaging stops for `activity` (a refocus, clouds).
    fn interrupt(&mut self, activity: Activity) {
        let now = self.rig.now_us;
        self.scoring(false);
        let Some(a) = self.section.as_mut() else {
            return;
        };
        let download = match a.imaging {
            Imaging::Downloading { from_us, .. } => Some(from_us),
            _ => None,
        };
        let ended = a.interrupted.replace((activity, now));
        a.imaging = Imaging::Idle;
        if let Some((was, from)) = ended {
            self.window(was, from);
        }
        if let Some(from) = download {
            self.window(Activity::Download, from);
        }
    }

    fn slew(&mut self, way: Way, rate: ManualRate, seconds: f64, flip: bool) {
        // The port refuses the axis while an ST4 pulse holds it: the
        // guider's last pulse ends first.
        let free = self.rig.pulses_end_us() + 1000;
        self.advance_to(free);
        let mut cmd = String::from(match rate {
            ManualRate::Centering => ":RC#",
            ManualRate::Find => ":RM#",
            ManualRate::Max => ":RS#",
        });
        cmd.push_str(match way {
            Way::West => ":Mw#",
            Way::East => ":Me#",
        });
        self.feed_port(cmd.as_bytes());
        let now = self.rig.now_us;
        let until = now + us(seconds);
        self.slew_stop = Some((until, way, flip));
        let activity = if flip { Activity::Flip } else { Activity::Slew };
        self.open_window(activity, now, until);
    }

    fn start(&mut self, spec: Section) {
        let now = self.rig.now_us;
        // The pause closes with the cadence the guider had when it stopped.
        if let Some(from) = self.off_since_us.take() {
            self.window(Activity::GuiderOff, from);
        }
        self.cadence_us = us(spec.interval_s);
        let index = self.sections.len();
        self.rig.start_guider(guider_for(&spec), spec.interval_s);
        let key = (2 << 60) | index as u64;
        let spot = (
            200.0 + 880.0 * draw(self.seed, key),
            150.0 + 660.0 * draw(self.seed, key + 1),
        );
        let guide_px_per_s = self.rig.believed_guide_rate();
        self.section = Some(Active {
            index,
            spec,
            phase: Phase::Calibrating(Calibrating {
                plan: Calibration::new(guide_px_per_s),
                origin: None,
                leg_origin: spot,
                west: None,
                began_us: now,
            }),
            guide_start_us: now,
            calibrated: Calibrated {
                x_angle_deg: 0.0,
                x_rate: 0.0,
                y_angle_deg: 0.0,
                y_rate: 0.0,
            },
            frame: 0,
            lock_cam: spot,
            dec_lock: 0.0,
            spot,
            imaging: Imaging::Idle,
            subs: 0,
            lost_frames: 0,
            lost_since_us: now,
            hidden_until_us: None,
            paused_until_us: None,
            interrupted: None,
            score_from: (0.0, 0),
            marks: Vec::new(),
            mass: 12_000.0 + 1_000.0 * index as f64,
            snr: 25.0 + 3.0 * index as f64,
        });
        let header = self.header(&spec, spot);
        if let Some(w) = self.writer() {
            w.calibration_begins(
                secs(now),
                &header,
                calibration::STEP_MS,
                calibration::DISTANCE_PX,
            );
        }
    }

    fn stop(&mut self) {
        let now = self.rig.now_us;
        self.scoring(false);
        let Some(a) = self.section.take() else {
            return;
        };
        if let Some((activity, from)) = a.interrupted {
            self.window(activity, from);
        }
        if let Phase::Calibrating(c) = a.phase {
            self.window(Activity::Calibration, c.began_us);
        }
        let end = self.rig.score_sums();
        let first_end = a.marks.first().copied().unwrap_or(end);
        self.sections.push(SectionScore {
            section: a.spec,
            all: Rms::between(a.score_from, end),
            first: Rms::between(a.score_from, first_end),
            settled: Rms::between(first_end, end),
            later: a
                .marks
                .windows(2)
                .map(|w| Rms::between(w[0], w[1]))
                .collect(),
        });
        if let Some(w) = self.writer() {
            w.guiding_ends(secs(now));
        }
        self.off_since_us = Some(now);
    }

    fn on_exposure(&mut self, e: Exposure) {
        let Some(a) = self.section.as_ref() else {
            return;
        };
        // The guider sees no frame while paused or while the main camera
        // downloads (the camera goes on, so that every firmware's night
        // draws the same noise for the same exposure).
        if a.paused_until_us.is_some() || matches!(a.imaging, Imaging::Downloading { .. }) {
            return;
        }
        let phase = a.phase;
        match phase {
            Phase::Calibrating(c) => self.calibration_step(c, e),
            Phase::Guiding => self.guide_step(e),
        }
    }

    fn calibration_step(&mut self, mut c: Calibrating, e: Exposure) {
        let camera = self.camera_deg();
        let hidden = self
            .section
            .as_ref()
            .is_some_and(|a| a.hidden_until_us.is_some());
        if hidden {
            if let Some(w) = self.writer() {
                w.star_lost_in_calibration();
            }
            return;
        }
        let dec = self.dec_measured();
        let here = (e.measured_arcsec, dec);
        let origin = *c.origin.get_or_insert(here);
        let spot = self.section.as_ref().map_or((0.0, 0.0), |a| a.spot);
        let star = add(spot, rotate(sub(here, origin), camera));
        let step_s = calibration::STEP_MS as f64 * 1e-3;
        match c.plan.after_exposure() {
            Next::Row {
                leg,
                step,
                pulse,
                leg_complete,
            } => {
                if leg == Leg::North && step == 0 {
                    c.leg_origin = star;
                }
                let d = sub(c.leg_origin, star);
                let steps = c.plan.steps;
                if let Some(w) = self.writer() {
                    w.calibration_row(leg.name(), step, d, star);
                }
                if leg_complete {
                    let angle = normal_deg(d.1.atan2(d.0).to_degrees());
                    let rate = d.0.hypot(d.1) / (steps as f64 * step_s);
                    if leg == Leg::West {
                        c.west = Some((angle, rate));
                    }
                    if let Some(w) = self.writer() {
                        w.leg_complete(leg.name(), angle, rate);
                    }
                    if leg == Leg::North {
                        let (x_angle_deg, x_rate) = c.west.unwrap_or((camera, rate));
                        if let Some(a) = self.section.as_mut() {
                            a.calibrated = Calibrated {
                                x_angle_deg,
                                x_rate,
                                y_angle_deg: angle,
                                y_rate: rate,
                            };
                        }
                    }
                }
                if let Some(p) = pulse {
                    let sent = self.rig.send_pulse(p.line(), c.plan.pulse_us());
                    self.rig.hold_camera(sent.start_us + sent.duration_us);
                }
                if let Some(a) = self.section.as_mut() {
                    a.phase = Phase::Calibrating(c);
                }
            }
            Next::Done => {
                if let Some(w) = self.writer() {
                    w.calibration_complete();
                }
                self.begin_guiding(c, e, star, dec);
            }
        }
    }

    fn begin_guiding(&mut self, c: Calibrating, e: Exposure, star: (f64, f64), dec: f64) {
        let now = self.rig.now_us;
        self.window(Activity::Calibration, c.began_us);
        // The guider locks where the star is.
        self.rig.lock_arcsec += e.measured_arcsec;
        let from = self.rig.score_sums();
        let Some(a) = self.section.as_mut() else {
            return;
        };
        a.phase = Phase::Guiding;
        a.guide_start_us = now;
        a.lock_cam = star;
        a.dec_lock = dec;
        a.score_from = from;
        let spec = a.spec;
        let calibrated = a.calibrated;
        self.rig.start_guider(guider_for(&spec), spec.interval_s);
        let header = self.header(&spec, star);
        if let Some(w) = self.writer() {
            w.guiding_begins(secs(now), &header, &calibrated);
        }
        self.settle_after_interruption();
    }

    fn guide_step(&mut self, e: Exposure) {
        let now = self.rig.now_us;
        let gear_time = self.rig.gear_time_s();
        let dec = self.dec_measured();
        let Some(a) = self.section.as_mut() else {
            return;
        };
        a.frame += 1;
        let frame = a.frame;
        let time_s = secs(now - a.guide_start_us);
        if a.hidden_until_us.is_some() || a.lost_frames > 0 {
            if a.lost_frames > 0 {
                a.lost_frames -= 1;
                if a.lost_frames == 0 {
                    let from = a.lost_since_us;
                    self.window(Activity::LostStar, from);
                }
            }
            if let Some(w) = self.writer() {
                w.drop_row(frame, time_s);
            }
            return;
        }
        let c = self.rig.guide(e.measured_arcsec);
        if let Some(p) = c.pulse.filter(|_| c.dither) {
            self.open_window(Activity::Dither, p.start_us, p.start_us + p.duration_us);
        }
        let Some(a) = self.section.as_mut() else {
            return;
        };
        // PHD2's dither row: the move itself, measured and corrected.
        let ra_raw = if c.dither {
            c.arcsec
        } else {
            e.measured_arcsec
        };
        let dec_off = dec - a.dec_lock;
        let cal = a.calibrated;
        let (dx, dy) = rotate((ra_raw, dec_off), cal.x_angle_deg);
        let (ys, yc) = cal.y_angle_deg.to_radians().sin_cos();
        let dec_raw = dx * yc + dy * ys;
        let row = Row {
            frame,
            time_s,
            dx,
            dy,
            ra_raw,
            dec_raw,
            ra_guide: c.arcsec,
            ra_ms: c.pulse.map_or(0, |p| p.duration_us / 1000),
            ra_west: c.pulse.is_some_and(|p| p.line == Line::RaPlus),
            mass: a.mass,
            snr: a.snr,
        };
        let index = a.index;
        self.settle(ra_raw.hypot(dec_off), c.dither);
        if self.log.is_none() {
            return;
        }
        let learner = self.learner_row(index + 1, frame, time_s, gear_time, e, c.arcsec);
        if let Some(l) = self.log.as_mut() {
            l.phd2.row(&row);
            let _ = writeln!(
                l.truth,
                "{},{frame},{time_s:.3},{gear_time:.3},{:.4},{:.4},{ra_raw:.4}",
                index + 1,
                e.gear_error_arcsec,
                e.pointing_arcsec
            );
            if let Some(r) = learner {
                let _ = writeln!(l.learner, "{r}");
            }
        }
    }

    /// A row of [`GuideLogs::learner`], with the MKGP firmware.
    fn learner_row(
        &mut self,
        section: usize,
        frame: u32,
        time_s: f64,
        gear_time: f64,
        e: Exposure,
        guide_px: f64,
    ) -> Option<String> {
        let share = self.rig.pulse_share();
        let weight = self.rig.pulse_weight();
        let filled = self.rig.guiding_counters().filled_frames;
        let counters = self.rig.learner_counters();
        let l = self.rig.mkgp_learner()?;
        let mut r = format!(
            "{section},{frame},{time_s:.3},{gear_time:.3},{:.4},{guide_px:.4},{share:.4},\
             {weight:.4},{:.4},{:.4},{},{},{filled},{:.4}",
            e.pointing_arcsec,
            l.feed_forward_weight(),
            l.guider().blend_weight(),
            counters.frames,
            counters.learned,
            l.step_level(),
        );
        r += &trace::stage_values(l.guider());
        Some(r)
    }

    /// PHD2's settling on a row `distance` px from the lock.
    fn settle(&mut self, distance: f64, dither: bool) {
        let now = self.rig.now_us;
        let Some(a) = self.section.as_mut() else {
            return;
        };
        let Imaging::Settling {
            in_range_since,
            timeout_us,
            dither_row,
        } = a.imaging
        else {
            return;
        };
        if dither_row {
            if dither {
                a.imaging = Imaging::Settling {
                    in_range_since: None,
                    timeout_us,
                    dither_row: false,
                };
            }
            return;
        }
        let since = if distance <= SETTLE_PX {
            Some(in_range_since.unwrap_or(now))
        } else {
            None
        };
        let settled = since.is_some_and(|s| now - s >= us(SETTLE_S));
        let failed = now >= timeout_us;
        if !(settled || failed) {
            a.imaging = Imaging::Settling {
                in_range_since: since,
                timeout_us,
                dither_row: false,
            };
            return;
        }
        a.imaging = Imaging::Exposing {
            until_us: now + us(a.spec.sub_s),
        };
        let ended = a.interrupted.take();
        if let Some((activity, from)) = ended {
            self.window(activity, from);
        }
        self.scoring(true);
        self.info(if settled {
            "SETTLING STATE CHANGE, Settling complete"
        } else {
            "SETTLING STATE CHANGE, Settling failed"
        });
    }
}
