//! A hand-written SVG bar chart of the table.

use crate::table::TableRow;
use std::fmt::Write;

const COLOURS: [(&str, &str); 4] = [
    ("reactive", "#9e9e9e"),
    ("ppec", "#1f77b4"),
    ("mkgp", "#d62728"),
    ("mkgp3", "#ff7f0e"),
];
/// Bars per case.
const BARS: f64 = COLOURS.len() as f64;

/// The bars of a row, in the order of [`COLOURS`].
fn bars(r: &TableRow) -> [f64; 4] {
    [r.reactive, r.ppec, r.mkgp, r.mkgp3]
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// Bars of the reactive, ppec, mkgp and mkgp3 residuals, one panel per noise level,
/// the open-loop RMS written above each case. `note` goes under the title.
pub fn table_chart(rows: &[TableRow], note: &str) -> String {
    let mut levels: Vec<f64> = Vec::new();
    for r in rows {
        if !levels.contains(&r.noise_px) {
            levels.push(r.noise_px);
        }
    }
    let max = rows.iter().flat_map(bars).fold(0.0f64, f64::max).max(1e-9);
    let top = (max * 1.15 * 10.0).ceil() / 10.0;
    let (bar_w, gap, left, panel_h, panel_gap, head) = (12.0, 16.0, 60.0, 220.0, 70.0, 70.0);
    let ncases = rows.iter().filter(|r| r.noise_px == levels[0]).count();
    let width = left + ncases as f64 * (BARS * bar_w + gap) + 20.0;
    let height = head + levels.len() as f64 * (panel_h + panel_gap);
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{width:.0}" height="{height:.0}" font-family="sans-serif" font-size="11">"#
    );
    let _ = writeln!(s, r#"<rect width="100%" height="100%" fill="white"/>"#);
    let _ = writeln!(
        s,
        r#"<text x="{left}" y="20" font-size="14">Residual RMS (px) over t &gt;= 3600 s, synthetic cases</text>"#
    );
    let _ = writeln!(
        s,
        r##"<text x="{left}" y="36" fill="#c00">{}</text>"##,
        esc(note)
    );
    for (k, (name, colour)) in COLOURS.iter().enumerate() {
        let x = left + k as f64 * 90.0;
        let _ = writeln!(
            s,
            r#"<rect x="{x}" y="46" width="10" height="10" fill="{colour}"/><text x="{}" y="55">{name}</text>"#,
            x + 14.0
        );
    }
    for (p, &level) in levels.iter().enumerate() {
        let y0 = head + p as f64 * (panel_h + panel_gap) + 20.0;
        let base = y0 + panel_h;
        let scale = panel_h / top;
        let _ = writeln!(
            s,
            r#"<text x="{left}" y="{}" font-size="12">noise {level} px{}</text>"#,
            y0 - 6.0,
            if level > 0.0 {
                " (mean of seeds 1-3)"
            } else {
                ""
            }
        );
        for t in 0..=4 {
            let v = top * t as f64 / 4.0;
            let y = base - v * scale;
            let _ = writeln!(
                s,
                r##"<line x1="{left}" x2="{}" y1="{y:.1}" y2="{y:.1}" stroke="#ddd"/><text x="{}" y="{:.1}" text-anchor="end">{v:.2}</text>"##,
                width - 20.0,
                left - 4.0,
                y + 4.0
            );
        }
        for (i, r) in rows.iter().filter(|r| r.noise_px == level).enumerate() {
            let x0 = left + gap / 2.0 + i as f64 * (BARS * bar_w + gap);
            for (k, v) in bars(r).into_iter().enumerate() {
                let h = v * scale;
                let _ = writeln!(
                    s,
                    r#"<rect x="{:.1}" y="{:.1}" width="{bar_w}" height="{h:.1}" fill="{}"><title>{} {}: {v:.3}</title></rect>"#,
                    x0 + k as f64 * bar_w,
                    base - h,
                    COLOURS[k].1,
                    esc(&r.case),
                    COLOURS[k].0
                );
            }
            let cx = x0 + BARS / 2.0 * bar_w;
            let _ = writeln!(
                s,
                r#"<text x="{cx:.1}" y="{:.1}" text-anchor="middle">{}</text>"#,
                base + 14.0,
                esc(&r.case)
            );
            let _ = writeln!(
                s,
                r##"<text x="{cx:.1}" y="{:.1}" text-anchor="middle" font-size="9" fill="#555">open {:.2}</text>"##,
                base + 26.0,
                r.open_loop
            );
        }
        let _ = writeln!(
            s,
            r#"<line x1="{left}" x2="{}" y1="{base}" y2="{base}" stroke="black"/>"#,
            width - 20.0
        );
    }
    s.push_str("</svg>\n");
    s
}
