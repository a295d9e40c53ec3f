//! The paper's table: residual RMS per case and noise level for the open
//! loop, the reactive guide algorithm (hysteresis 0.6), PPEC and MKGP.

use crate::cases::Case;
use crate::closed_loop::{self, Noise, NOISY_SEEDS};
use crate::guide_algorithm::{GuideAlgorithm, Hysteresis};
use crate::models::{self, Model};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

/// The noise levels of the table (px): noise-free, and 1 px (mean of seeds 1-3).
pub const NOISE_LEVELS: [f64; 2] = [0.0, 1.0];

#[derive(Debug, Clone, PartialEq)]
pub struct TableRow {
    pub case: String,
    pub noise_px: f64,
    pub open_loop: f64,
    pub reactive: f64,
    pub ppec: f64,
    pub mkgp: f64,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Column {
    Reactive,
    Model(Model),
}

#[derive(Debug, Clone, Copy)]
struct Job {
    case: usize,
    level: usize,
    column: Column,
    noise: Noise,
}

fn make(column: Column) -> Box<dyn GuideAlgorithm + Send> {
    match column {
        Column::Reactive => Box::new(Hysteresis::paper()),
        Column::Model(m) => models::algorithm(m, None, None),
    }
}

/// Compute the table on `threads` worker threads (one closed-loop run per
/// job; the slow model runs are queued first).
pub fn compute(cases: &[Case], threads: usize) -> Vec<TableRow> {
    let mut jobs = Vec::new();
    for column in [
        Column::Model(Model::Mkgp),
        Column::Model(Model::Ppec),
        Column::Reactive,
    ] {
        for (ci, _) in cases.iter().enumerate() {
            for (level, &sigma_px) in NOISE_LEVELS.iter().enumerate() {
                if sigma_px == 0.0 {
                    jobs.push(Job {
                        case: ci,
                        level,
                        column,
                        noise: Noise::None,
                    });
                } else {
                    for &seed in &NOISY_SEEDS {
                        jobs.push(Job {
                            case: ci,
                            level,
                            column,
                            noise: Noise::Gaussian { sigma_px, seed },
                        });
                    }
                }
            }
        }
    }
    let next = AtomicUsize::new(0);
    let results = Mutex::new(vec![0.0f64; jobs.len()]);
    std::thread::scope(|s| {
        for _ in 0..threads.max(1) {
            s.spawn(|| loop {
                let k = next.fetch_add(1, Ordering::Relaxed);
                let Some(job) = jobs.get(k) else { break };
                let rms = closed_loop::run(&cases[job.case], &mut make(job.column), job.noise);
                results.lock().unwrap()[k] = rms;
            });
        }
    });
    let results = results.into_inner().unwrap();
    let mean = |ci: usize, level: usize, column: Column| {
        let v: Vec<f64> = jobs
            .iter()
            .zip(&results)
            .filter(|(j, _)| j.case == ci && j.level == level && j.column == column)
            .map(|(_, &r)| r)
            .collect();
        v.iter().sum::<f64>() / v.len() as f64
    };
    let mut rows = Vec::new();
    for (ci, case) in cases.iter().enumerate() {
        let open_loop = closed_loop::open_loop_rms(case);
        for (level, &noise_px) in NOISE_LEVELS.iter().enumerate() {
            rows.push(TableRow {
                case: case.name.clone(),
                noise_px,
                open_loop,
                reactive: mean(ci, level, Column::Reactive),
                ppec: mean(ci, level, Column::Model(Model::Ppec)),
                mkgp: mean(ci, level, Column::Model(Model::Mkgp)),
            });
        }
    }
    rows
}
