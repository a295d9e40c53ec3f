//! `guide-sim nights`: the learned model across a power cycle (issue 9,
//! section 5), through the firmware's loop (`st4_sim::Rig`, MKGP firmware).
//!
//! - **Night 1.** 3 h of guiding from a cold model; `settled` is the
//!   pointing RMS over its hours 1-3.
//! - **Power cycle.** Night 1's firmware has a store (`store_sim`: the
//!   firmware's store on a simulated flash), into which its learning task
//!   saves the model as the library's `LearningPolicy` asks, every 10
//!   minutes, and at the end serves the save asked on the port: `:~W#`, or
//!   the park's `:hP#` with `--park`. The newest model in that flash (the
//!   learner's model and pulse share, as `Learner::snapshot` wrote it at
//!   the end) is restored with `Learner::restore` into the fresh learner of
//!   a new rig booting from that flash: the step counter, and with it gear
//!   time, starts again at 0.
//! - **Night 2.** The gear stands at a phase drawn from the seed (uniform
//!   over a day of gear time; the same for the three variants;
//!   [`Night2Start::Moved`]), or where night 1 left it
//!   ([`Night2Start::Parked`], `--park`): its error at the new gear time `t`
//!   is the case's at `t + phase`. Three variants, each scored over its
//!   first 30 minutes: cold (a new model), restored without an index
//!   (`Phase::Unknown`) and restored with the index, or from park
//!   (`Phase::Known`: with the index the worm's phase only,
//!   [`index_offset`]; from park the exact offset).
//! - The guider locks where the star is at the start of each night (PHD2's
//!   lock), so that no night starts with a pull to an old lock position.
//!   With `--calibrate` night 2 starts with the guider's calibration
//!   (PHD2's, as a night's sections start in `guide-sim night`), which the
//!   firmware does not learn from, and its 30 minutes are scored from the
//!   calibration's end.
//!   Every row is the mean of seeds 1-3 (`st4_sim::SEEDS`), each with its
//!   own night-2 phase and, with noise, night 2 with its own noise.

use crate::cases::Case;
use crate::night::calibration::{Calibration, Next};
use crate::st4_sim::{self, Firmware, Rig, Setup, SEEDS};
use crate::store_sim::SimStore;
use mkgp_mount::control_loop::port_mount::StoreRequest;
use mkgp_mount::model::additions::Additions;
use mkgp_mount::model::snapshot::Phase;
use mkgp_mount::mount::config::MountConfig;
use mkgp_mount::mount::learner::RECORD_FORMAT;
use mkgp_mount::port::mount_port::StepCounts;
use mkgp_mount::testing::SplitMix64;
use rayon::prelude::*;

/// Night 1, s.
pub const NIGHT_1_S: f64 = 10_800.0;
/// `settled` covers night 1 from here, s.
pub const SETTLED_FROM_S: f64 = 3_600.0;
/// The scored start of night 2, s.
pub const FIRST_S: f64 = 1_800.0;
/// Night 2's gear phase is drawn from this span, s of gear time.
pub const PHASE_SPAN_S: f64 = 86_400.0;
/// Added to the seed of night 2's noise (another night, other noise).
const NIGHT_2_NOISE_SEED: u64 = 1000;

pub const CSV_HEADER: &str =
    "case,noise_px,settled,cold_first30,restored_first30,restored_index_first30";

/// One row: pointing RMS, arcsec.
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    pub case: String,
    pub noise_px: f64,
    pub settled: f64,
    pub cold_first30: f64,
    pub restored_first30: f64,
    pub restored_index_first30: f64,
}

/// Where the gear stands when night 2 starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Night2Start {
    /// Moved while off, to a phase drawn from the seed
    /// ([`night_2_phase`]); the index sensor then gives the worm's phase,
    /// not the other stages' ([`index_offset`]).
    Moved,
    /// Parked at the end of night 1 with its RA step count saved, and not
    /// moved: every stage's phase carries over.
    Parked,
}

/// What a worm-index sensor tells the firmware at night 2 (gear at
/// `phase`, night 1 ended at gear time `end_1`): the worm's phase, i.e.
/// the gear-time offset modulo the worm's true period (the case's first
/// sinusoid), given as the offset that puts night 2 within one worm period
/// after night 1's end.
pub fn index_offset(case: &Case, end_1: f64, phase: f64) -> f64 {
    let worm = case.sinusoids.first().map_or(f64::INFINITY, |s| s.period_s);
    end_1 + (phase - end_1).rem_euclid(worm)
}

/// Night 2's gear phase for a seed, s.
pub fn night_2_phase(seed: u64) -> f64 {
    SplitMix64::new(seed).uniform() * PHASE_SPAN_S
}

/// What every night of a seed shares: the gear, its noise, the guider,
/// the sky and the additions the firmware runs (`setup`), and the mount's
/// configuration.
#[derive(Clone, Copy)]
pub struct Run<'a> {
    pub case: &'a Case,
    pub noise_px: f64,
    pub setup: Setup,
    pub config: MountConfig,
    /// Night 2 starts with the guider's calibration.
    pub calibrates: bool,
}

impl<'a> Run<'a> {
    /// `case` as the table runs it: the default guider and sky, the
    /// case's mount, the firmware running `additions`.
    pub fn case(case: &'a Case, noise_px: f64, additions: Additions) -> Self {
        Run {
            case,
            noise_px,
            setup: Setup {
                additions,
                ..Setup::default()
            },
            config: st4_sim::mount_config(case),
            calibrates: false,
        }
    }
}

/// The guider's calibration (PHD2's, [`Calibration`]): each step's pulse,
/// one exposure after each, the guider's own loop off; then it locks where
/// the star is. Returns when it ends, us.
fn calibrate(rig: &mut Rig) -> u64 {
    rig.guider_on = false;
    let mut plan = Calibration::new(rig.believed_guide_rate());
    while let Some(e) = rig.run_to_exposure(u64::MAX) {
        match plan.after_exposure() {
            Next::Row { pulse, .. } => {
                if let Some(leg) = pulse {
                    let sent = rig.send_pulse(leg.line(), plan.pulse_us());
                    rig.hold_camera(sent.start_us + sent.duration_us);
                }
            }
            Next::Done => {
                rig.lock_arcsec += e.measured_arcsec;
                break;
            }
        }
    }
    rig.guider_on = true;
    rig.now_us
}

/// A night of `length_s` on the MKGP firmware, scored from `score_from_s`,
/// the gear at `gear_phase_s`. Its firmware boots from `boot`'s store,
/// restoring its newest model with the phase given; without, from an
/// erased store and a cold model. With `calibrates` the guider calibrates
/// first, and the night's length and score start at the calibration's
/// end.
fn night(
    run: Run,
    seed: u64,
    gear_phase_s: f64,
    boot: Option<(SimStore, Phase)>,
    (length_s, score_from_s): (f64, f64),
    calibrates: bool,
) -> Rig {
    let mut rig = Rig::with_additions(
        run.case,
        Firmware::Mkgp,
        run.noise_px,
        seed,
        run.config,
        run.setup.additions,
    );
    rig.set_guider(run.setup.guider);
    rig.set_sky(run.setup.sky);
    rig.gear_phase_s = gear_phase_s;
    rig.lock_arcsec = rig.pointing_arcsec();
    let store = match boot {
        Some((mut store, phase)) => {
            let bytes = store.load_model().expect("night 1's model loads");
            let learner = rig.mkgp_learner().expect("the MKGP firmware has a learner");
            learner
                .restore(&bytes, RECORD_FORMAT, phase)
                .unwrap_or_else(|e| panic!("restore: {e:?}"));
            store
        }
        None => SimStore::default(),
    };
    rig.set_store(store);
    let start_us = if calibrates { calibrate(&mut rig) } else { 0 };
    let start_s = start_us as f64 * 1e-6;
    rig.score_window_s = (start_s + score_from_s, f64::INFINITY);
    rig.run_until(start_us + (length_s * 1e6) as u64);
    rig
}

/// The four figures for one seed: settled, cold, restored without and with
/// the phase.
pub fn one_seed(run: Run, seed: u64, start: Night2Start) -> [f64; 4] {
    let case = run.case;
    let mut first = night(run, seed, 0.0, None, (NIGHT_1_S, SETTLED_FROM_S), false);
    let request = match start {
        Night2Start::Moved => StoreRequest::Model { port: 0 },
        Night2Start::Parked => StoreRequest::Park(StepCounts {
            ra: first.ra_steps(),
            dec: first.dec_steps(),
        }),
    };
    let outcome = first.ask_store(request);
    assert!(outcome.saved, "night 1's model not saved: {outcome:?}");
    let flash = first.store().expect("night 1 has a store").clone();
    // Night 1's gear time at its end: where a park leaves the gear.
    let end_1 = first.ra_steps() as f64 / first.mount.sidereal_ra_steps_per_s_f64();
    let (phase, known_offset) = match start {
        Night2Start::Moved => (
            night_2_phase(seed),
            index_offset(case, end_1, night_2_phase(seed)),
        ),
        Night2Start::Parked => (end_1, end_1),
    };
    let seed_2 = seed + NIGHT_2_NOISE_SEED;
    let second = |restore: Option<Phase>| {
        let boot = restore.map(|p| (flash.clone(), p));
        night(run, seed_2, phase, boot, (FIRST_S, 0.0), run.calibrates).score()
    };
    let known = match start {
        Night2Start::Moved => Phase::Worm {
            gear_time_offset_s: known_offset,
        },
        Night2Start::Parked => Phase::Known {
            gear_time_offset_s: known_offset,
        },
    };
    let (cold, (unknown, index)) = rayon::join(
        || second(None),
        || rayon::join(|| second(Some(Phase::Unknown)), || second(Some(known))),
    );
    [first.score(), cold, unknown, index]
}

/// One row: the mean over [`SEEDS`], each its own night-2 phase (and
/// noise), the firmware running `additions`; night 2 starts with a
/// calibration if `calibrates`.
fn row(
    case: &Case,
    noise_px: f64,
    (start, calibrates): (Night2Start, bool),
    additions: Additions,
) -> Row {
    let run = Run {
        calibrates,
        ..Run::case(case, noise_px, additions)
    };
    let runs: Vec<[f64; 4]> = SEEDS
        .par_iter()
        .map(|&seed| one_seed(run, seed, start))
        .collect();
    let mean = |k: usize| runs.iter().map(|r| r[k]).sum::<f64>() / runs.len() as f64;
    Row {
        case: case.name.clone(),
        noise_px,
        settled: mean(0),
        cold_first30: mean(1),
        restored_first30: mean(2),
        restored_index_first30: mean(3),
    }
}

/// The table for `cases` and noise levels, one row per case and level in
/// that order, night 2 starting at `start` and with a calibration if
/// `calibrates`; the rows run in parallel.
pub fn table(
    cases: &[Case],
    noise_levels: &[f64],
    night_2: (Night2Start, bool),
    additions: Additions,
) -> Vec<Row> {
    let rows: Vec<(&Case, f64)> = cases
        .iter()
        .flat_map(|case| noise_levels.iter().map(move |&noise| (case, noise)))
        .collect();
    rows.into_par_iter()
        .map(|(case, noise)| row(case, noise, night_2, additions))
        .collect()
}

/// A row as CSV, in [`CSV_HEADER`]'s order.
pub fn csv_line(r: &Row) -> String {
    format!(
        "{},{},{:.3},{:.3},{:.3},{:.3}",
        r.case, r.noise_px, r.settled, r.cold_first30, r.restored_first30, r.restored_index_first30
    )
}
