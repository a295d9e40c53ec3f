//! Reading INDIGO's reference traces
//! (`time_s,input_px,snr,output_correction_px,period_s,learning_progress`).

#![allow(dead_code)]

use host_tests::data;

#[derive(Debug, Clone, Copy)]
pub struct TraceRow {
    pub time_s: f64,
    pub input_px: f64,
    pub snr: f64,
    pub output_correction_px: f64,
}

pub fn trace(name: &str) -> Vec<TraceRow> {
    let path = data::reference_trace(name);
    let text = data::read_text(&path).unwrap_or_else(|e| panic!("{e}"));
    let mut lines = text.lines();
    assert!(lines
        .next()
        .unwrap()
        .starts_with("time_s,input_px,snr,output_correction_px"));
    lines
        .enumerate()
        .map(|(i, l)| {
            let f: Vec<f64> = l
                .split(',')
                .map(|x| {
                    x.parse().unwrap_or_else(|_| {
                        panic!("{}:{}: bad number {x:?}", path.display(), i + 2)
                    })
                })
                .collect();
            TraceRow {
                time_s: f[0],
                input_px: f[1],
                snr: f[2],
                output_correction_px: f[3],
            }
        })
        .collect()
}
