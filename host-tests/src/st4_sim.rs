//! The firmware's closed loop (`guide-sim st4`): a virtual mount, a virtual
//! guide camera and a PHD2-like guider around the real controller code
//! (`mkgp_mount::mount::st4::St4`, `mkgp_mount::mount::guiding::{Guiding, Learner}`).
//!
//! - **Mount.** The RA axis integrates the step rate the controller sets,
//!   exactly between controller calls (rates are piecewise constant); the
//!   step count given to the controller and used for the pointing is the
//!   integer part (step quantisation is modelled, 0.06-0.08 arcsec per step
//!   here; the phase accumulator's sub-tick timing is not). Gear time is
//!   steps / sidereal steps per second, and the RA pointing error is
//!   `p = g(gear time) - C`, with `g` the synthetic case's gear error (1 px =
//!   1 arcsec) and `C` the steps beyond sidereal tracking in arcsec: the lag
//!   of the axis behind the sky. The mount is the default EQ6-class one
//!   (`MountConfig::default()`) with the worm period set to the case's first
//!   sinusoid (432 s, 288 s for C8), so the firmware's prior is its worm.
//! - **Time.** A 10 ms tick, split at every ST4 edge, ST4 deadline and
//!   feed-forward installation, so that pulses are resolved to the
//!   microsecond. At every tick the controller is called (`rates`) and the
//!   pointing is sampled.
//! - **Camera.** Back-to-back exposures of 2 s ending at t = 2, 4, ... s;
//!   the measurement is the mean of the pointing over the exposure (the 10 ms
//!   samples), minus the lock position, plus N(0, noise) from the
//!   design's generator (one per run and seed).
//! - **Guider.** PHD2's hysteresis (aggressiveness 0.7, hysteresis 0.1, min
//!   move 0.2) turns the measurement into a correction; the pulse lasts
//!   correction / guide rate (0.5x sidereal, 7.52 arcsec/s), at most 2.5 s,
//!   on RA+ for a positive correction (the star lags: faster) and RA- for a
//!   negative one. It starts [`LATENCY_US`] after the exposure ends (after
//!   the previous pulse if that is still running) as raw line edges fed to
//!   `St4::edge`.
//! - **Firmware.** `St4::poll` -> `Guiding::on_event`; each frame from
//!   `Guiding::take_frame` goes to `Learner::learn`, whose feed-forward is
//!   installed [`INFERENCE_US`] later (the model's time on the target).
//!   Guider only: no learner, the firmware tracks and obeys the pulses.
//! - **Score.** RMS of the pointing error (10 ms samples) over the final two
//!   thirds, t >= 3600 s of the 10 800 s run.

use crate::cases::Case;
use crate::controller::{Controller, Hysteresis};
use crate::noise::Gaussian;
use mkgp_mount::mount::config::{Mount, MountConfig, SIDEREAL_ARCSEC_PER_S};
use mkgp_mount::mount::guiding::{
    FeedForward, Guiding, GuidingCounters, Learner, LearnerCounters, Rates,
};
use mkgp_mount::mount::st4::{Line, St4, St4Counters};
use std::collections::VecDeque;

/// Length of a run, s.
pub const RUN_S: f64 = 10_800.0;
/// The score covers t >= this, s (the final two thirds).
pub const SCORE_FROM_S: f64 = 3_600.0;
/// Exposure and guide cadence, s.
pub const EXPOSURE_S: f64 = 2.0;
/// Simulation tick, us.
pub const TICK_US: u64 = 10_000;
/// From the end of an exposure to the start of its pulse, us.
pub const LATENCY_US: u64 = 20_000;
/// From a frame to the installation of its feed-forward, us.
pub const INFERENCE_US: u64 = 50_000;
/// Longest guide pulse the guider sends (PHD2's max RA duration), us.
pub const MAX_PULSE_US: u64 = 2_500_000;
/// Pause between a pulse and the next one when they would overlap, us.
pub const PULSE_GAP_US: u64 = 5_000;
/// The seeds of the noisy runs.
pub const SEEDS: [u64; 3] = [1, 2, 3];

/// What runs in the firmware.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Firmware {
    /// Tracking and the guider's pulses, no learning.
    GuiderOnly,
    /// `Learner<1>`.
    Ppec,
    /// `Learner<2>`.
    Mkgp,
}

pub const FIRMWARES: [Firmware; 3] = [Firmware::GuiderOnly, Firmware::Ppec, Firmware::Mkgp];

enum AnyLearner {
    None,
    One(Box<Learner<1>>),
    Two(Box<Learner<2>>),
}

impl AnyLearner {
    fn learn(&mut self, f: mkgp_mount::mount::guiding::Frame) -> Option<FeedForward> {
        match self {
            AnyLearner::None => None,
            AnyLearner::One(l) => Some(l.learn(f)),
            AnyLearner::Two(l) => Some(l.learn(f)),
        }
    }
    fn counters(&self) -> LearnerCounters {
        match self {
            AnyLearner::None => LearnerCounters::default(),
            AnyLearner::One(l) => l.counters(),
            AnyLearner::Two(l) => l.counters(),
        }
    }
}

/// The mount used for a case: the default mount with the case's worm.
pub fn mount_config(case: &Case) -> MountConfig {
    let mut c = MountConfig::default();
    if let Some(s) = case.sinusoids.first() {
        c.worm_period_s = s.period_s as f32;
    }
    c
}

/// Extremes of what the controller asked for, and the counters.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Extremes {
    pub ra_min: f32,
    pub ra_max: f32,
    pub dec_abs_max: f32,
    pub non_finite: u32,
}

/// The virtual rig: mount, camera, guider and the firmware.
pub struct Rig {
    pub mount: Mount,
    pub case: Case,
    pub st4: St4,
    pub guiding: Guiding,
    learner: AnyLearner,
    pub now_us: u64,
    ra_pos: f64,
    dec_pos: f64,
    rates: Rates,
    /// Raw edges still to come, sorted by time.
    edges: VecDeque<(u64, Line, bool)>,
    pending_ff: VecDeque<(u64, FeedForward)>,
    /// The guider: its hysteresis, noise, whether it answers at all.
    hysteresis: Hysteresis,
    noise: Option<(f64, Gaussian)>,
    pub guider_on: bool,
    /// The guider's lock position (arcsec of pointing error it aims at).
    pub lock_arcsec: f64,
    /// A dither the guider sends with its next pulse: amount, arcsec.
    dither_next: Option<f64>,
    exposure_sum: f64,
    exposure_n: u32,
    next_exposure_end_us: u64,
    last_pulse_end_us: u64,
    score_sq: f64,
    score_n: u64,
    pub extremes: Extremes,
    /// Every frame the firmware made (for tests).
    pub frames: Vec<mkgp_mount::mount::guiding::Frame>,
    /// Every feed-forward installed (for tests): (time us, rate).
    pub feed_forwards: Vec<(u64, f32)>,
}

impl Rig {
    pub fn new(case: &Case, firmware: Firmware, noise_px: f64, seed: u64) -> Self {
        Self::with_mount(case, firmware, noise_px, seed, mount_config(case))
    }

    pub fn with_mount(
        case: &Case,
        firmware: Firmware,
        noise_px: f64,
        seed: u64,
        config: MountConfig,
    ) -> Self {
        let mount = config.validate().unwrap_or_else(|e| panic!("{e}"));
        let learner = match firmware {
            Firmware::GuiderOnly => AnyLearner::None,
            Firmware::Ppec => AnyLearner::One(Box::new(Learner::new(&mount))),
            Firmware::Mkgp => AnyLearner::Two(Box::new(Learner::new(&mount))),
        };
        let c = mount.config();
        Rig {
            st4: St4::new(c.glitch_us, c.pulse_cap_us),
            guiding: Guiding::new(&mount),
            mount,
            case: case.clone(),
            learner,
            now_us: 0,
            ra_pos: 0.0,
            dec_pos: 0.0,
            rates: Rates::default(),
            edges: VecDeque::new(),
            pending_ff: VecDeque::new(),
            hysteresis: Hysteresis::phd2_baseline(),
            noise: (noise_px > 0.0).then(|| (noise_px, Gaussian::new(seed))),
            guider_on: true,
            lock_arcsec: 0.0,
            dither_next: None,
            exposure_sum: 0.0,
            exposure_n: 0,
            next_exposure_end_us: (EXPOSURE_S * 1e6) as u64,
            last_pulse_end_us: 0,
            score_sq: 0.0,
            score_n: 0,
            extremes: Extremes {
                ra_min: f32::INFINITY,
                ra_max: f32::NEG_INFINITY,
                ..Extremes::default()
            },
            frames: Vec::new(),
            feed_forwards: Vec::new(),
        }
    }

    pub fn learner_counters(&self) -> LearnerCounters {
        self.learner.counters()
    }

    pub fn guiding_counters(&self) -> GuidingCounters {
        self.guiding.counters()
    }

    pub fn st4_counters(&self) -> St4Counters {
        self.st4.counters()
    }

    pub fn rates(&self) -> Rates {
        self.rates
    }

    pub fn ra_steps(&self) -> i64 {
        self.ra_pos.floor() as i64
    }

    pub fn dec_steps(&self) -> i64 {
        self.dec_pos.floor() as i64
    }

    /// The applied correction C (steps beyond sidereal, arcsec) now.
    pub fn applied_arcsec(&self) -> f64 {
        let a = SIDEREAL_ARCSEC_PER_S / self.mount.sidereal_ra_steps_per_s_f64();
        self.ra_steps() as f64 * a - SIDEREAL_ARCSEC_PER_S * self.now_us as f64 * 1e-6
    }

    /// The pointing error now: the axis' lag behind the sky, arcsec.
    pub fn pointing_arcsec(&self) -> f64 {
        let gear_s = self.ra_steps() as f64 / self.mount.sidereal_ra_steps_per_s_f64();
        self.case.gear_error(gear_s) - self.applied_arcsec()
    }

    /// Residual RMS over the scored samples so far.
    pub fn score(&self) -> f64 {
        (self.score_sq / self.score_n.max(1) as f64).sqrt()
    }

    /// A raw edge at `at_us` (not before now).
    pub fn edge(&mut self, line: Line, asserted: bool, at_us: u64) {
        let at = at_us.max(self.now_us);
        let i = self.edges.partition_point(|e| e.0 <= at);
        self.edges.insert(i, (at, line, asserted));
    }

    /// A pulse on `line` from `start_us` for `duration_us`.
    pub fn pulse(&mut self, line: Line, start_us: u64, duration_us: u64) {
        self.edge(line, true, start_us);
        self.edge(line, false, start_us + duration_us);
    }

    /// The guider dithers by `amount_arcsec` with its next pulse: one long
    /// RA pulse of amount / guide rate, and the lock position moves by the
    /// amount (positive amount: RA+, the mount moves ahead).
    pub fn dither(&mut self, amount_arcsec: f64) {
        self.dither_next = Some(amount_arcsec);
    }

    fn next_event_us(&self, end_us: u64) -> u64 {
        let tick = (self.now_us / TICK_US + 1) * TICK_US;
        let mut t = tick.min(end_us);
        if let Some(&(at, _, _)) = self.edges.front() {
            t = t.min(at);
        }
        if let Some(d) = self.st4.next_deadline_us() {
            if d > self.now_us {
                t = t.min(d);
            }
        }
        if let Some(&(at, _)) = self.pending_ff.front() {
            t = t.min(at);
        }
        t.max(self.now_us + 1)
    }

    /// Run the loop until `end_us`.
    pub fn run_until(&mut self, end_us: u64) {
        while self.now_us < end_us {
            let t = self.next_event_us(end_us);
            let dt = (t - self.now_us) as f64 * 1e-6;
            self.ra_pos += self.rates.ra_steps_per_s as f64 * dt;
            self.dec_pos += self.rates.dec_steps_per_s as f64 * dt;
            self.now_us = t;
            self.controller_step();
            if t % TICK_US == 0 {
                self.sample();
            }
        }
    }

    fn controller_step(&mut self) {
        let now = self.now_us;
        while let Some(&(at, line, asserted)) = self.edges.front() {
            if at > now {
                break;
            }
            self.edges.pop_front();
            self.st4.edge(line, asserted, at);
        }
        while let Some(ev) = self.st4.poll(now) {
            self.guiding.on_event(ev);
        }
        while let Some(f) = self.guiding.take_frame() {
            self.frames.push(f);
            if let Some(ff) = self.learner.learn(f) {
                self.pending_ff.push_back((now + INFERENCE_US, ff));
            }
        }
        while let Some(&(at, ff)) = self.pending_ff.front() {
            if at > now {
                break;
            }
            self.pending_ff.pop_front();
            self.guiding.set_feed_forward(ff);
            self.feed_forwards.push((now, ff.rate_arcsec_per_s));
        }
        let r = self.guiding.rates(now, self.ra_steps());
        let e = &mut self.extremes;
        if !(r.ra_steps_per_s.is_finite() && r.dec_steps_per_s.is_finite()) {
            e.non_finite += 1;
        }
        e.ra_min = e.ra_min.min(r.ra_steps_per_s);
        e.ra_max = e.ra_max.max(r.ra_steps_per_s);
        e.dec_abs_max = e.dec_abs_max.max(r.dec_steps_per_s.abs());
        self.rates = r;
    }

    /// The 10 ms sample: score, exposure, and the guider at the end of an
    /// exposure.
    fn sample(&mut self) {
        let p = self.pointing_arcsec();
        let t = self.now_us as f64 * 1e-6;
        if t >= SCORE_FROM_S {
            let r = p - self.lock_arcsec;
            self.score_sq += r * r;
            self.score_n += 1;
        }
        self.exposure_sum += p;
        self.exposure_n += 1;
        if self.now_us >= self.next_exposure_end_us {
            let mean = self.exposure_sum / self.exposure_n.max(1) as f64;
            self.exposure_sum = 0.0;
            self.exposure_n = 0;
            self.next_exposure_end_us += (EXPOSURE_S * 1e6) as u64;
            let noise = match self.noise.as_mut() {
                Some((sigma, g)) => *sigma * g.next(),
                None => 0.0,
            };
            if self.guider_on {
                self.guide(mean - self.lock_arcsec + noise);
            }
        }
    }

    fn guide(&mut self, measured: f64) {
        let guide_rate = self.mount.guide_rate_arcsec_per_s() as f64;
        let start = (self.now_us + LATENCY_US).max(self.last_pulse_end_us + PULSE_GAP_US);
        if let Some(amount) = self.dither_next.take() {
            let dur = (amount.abs() / guide_rate * 1e6) as u64;
            let line = if amount > 0.0 {
                Line::RaPlus
            } else {
                Line::RaMinus
            };
            self.pulse(line, start, dur);
            self.last_pulse_end_us = start + dur;
            // The mount moves ahead by the amount: the lag drops by it.
            self.lock_arcsec -= amount;
            return;
        }
        let control = self.hysteresis.step(0.0, measured, 10.0, EXPOSURE_S);
        let dur = ((control.abs() / guide_rate * 1e6) as u64).min(MAX_PULSE_US);
        if dur == 0 {
            return;
        }
        let line = if control > 0.0 {
            Line::RaPlus
        } else {
            Line::RaMinus
        };
        self.pulse(line, start, dur);
        self.last_pulse_end_us = start + dur;
    }
}

/// One run's outcome.
#[derive(Debug, Clone, Copy)]
pub struct RunResult {
    pub rms: f64,
    pub extremes: Extremes,
    pub guiding: GuidingCounters,
    pub learner: LearnerCounters,
    pub st4: St4Counters,
}

/// One full run: `noise_px` 0 is noise-free (the seed is then unused).
pub fn run(case: &Case, firmware: Firmware, noise_px: f64, seed: u64) -> RunResult {
    let mut rig = Rig::new(case, firmware, noise_px, seed);
    rig.run_until((RUN_S * 1e6) as u64);
    RunResult {
        rms: rig.score(),
        extremes: rig.extremes,
        guiding: rig.guiding_counters(),
        learner: rig.learner_counters(),
        st4: rig.st4_counters(),
    }
}

/// One row of the table.
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    pub case: String,
    pub noise_px: f64,
    pub guider_only: f64,
    pub fw_ppec: f64,
    pub fw_mkgp: f64,
}

pub const CSV_HEADER: &str = "case,noise_px,guider_only,fw_ppec,fw_mkgp";

/// The table for `cases` and noise levels (0: one noise-free run; else the
/// mean over [`SEEDS`]), on `threads` threads.
pub fn table(cases: &[Case], noise_levels: &[f64], threads: usize) -> Vec<Row> {
    use std::sync::atomic::{AtomicUsize, Ordering};
    use std::sync::Mutex;
    // (row, firmware, seed index)
    let mut jobs = Vec::new();
    for fw in [Firmware::Mkgp, Firmware::Ppec, Firmware::GuiderOnly] {
        for ci in 0..cases.len() {
            for (li, &noise) in noise_levels.iter().enumerate() {
                let seeds: &[u64] = if noise > 0.0 { &SEEDS } else { &SEEDS[..1] };
                for &seed in seeds {
                    jobs.push((ci * noise_levels.len() + li, fw, noise, seed));
                }
            }
        }
    }
    let sums = Mutex::new(vec![[(0.0f64, 0u32); 3]; cases.len() * noise_levels.len()]);
    let next = AtomicUsize::new(0);
    std::thread::scope(|s| {
        for _ in 0..threads.max(1) {
            s.spawn(|| loop {
                let Some(&(row, fw, noise, seed)) = jobs.get(next.fetch_add(1, Ordering::Relaxed))
                else {
                    break;
                };
                let case = &cases[row / noise_levels.len()];
                let r = run(case, fw, noise, seed);
                let k = FIRMWARES.iter().position(|&f| f == fw).unwrap();
                let mut sums = sums.lock().unwrap();
                sums[row][k].0 += r.rms;
                sums[row][k].1 += 1;
            });
        }
    });
    let sums = sums.into_inner().unwrap();
    let mut rows = Vec::new();
    for (ci, case) in cases.iter().enumerate() {
        for (li, &noise) in noise_levels.iter().enumerate() {
            let s = sums[ci * noise_levels.len() + li];
            let m = |k: usize| s[k].0 / s[k].1.max(1) as f64;
            rows.push(Row {
                case: case.name.clone(),
                noise_px: noise,
                guider_only: m(0),
                fw_ppec: m(1),
                fw_mkgp: m(2),
            });
        }
    }
    rows
}
