//! The simulated guider's side of a night as a PHD2 guide log, in PHD2's
//! own format (its `guidinglog.cpp`, log version 2.5, and the logs in
//! `data/phd2-logs`):
//!
//! - the file opens with `PHD2 version ..., Log version 2.5. Log enabled
//!   at DATE`, and closes with `Log closed at DATE`;
//! - a calibration section: a blank line, `Calibration Begins at DATE`,
//!   its header lines (`Exposure = N ms`, `Pixel scale = ...`, the mount
//!   line with the calibration step and distance, `Dec = .. deg, Hour angle
//!   = .. hr, Pier side = ..`, the lock line), `Direction,Step,dx,dy,x,y,
//!   Dist`, one row per step (dx, dy: the starting point minus the star's,
//!   camera px), `West calibration complete. Angle = .. deg, Rate = ..
//!   px/sec, Parity = ..` after the west leg and the same for north, and
//!   `Calibration complete, mount = NAME.`;
//! - a guiding section: a blank line, `Guiding Begins at DATE`, the
//!   settings header (as PHD2's `GuidingHeader`: `Exposure =`, `Pixel
//!   scale =`, the mount line with `xAngle`, `xRate`, `yAngle`, `yRate`,
//!   the algorithms, `Dec = .., Hour angle = .., Pier side = ..`, the lock
//!   line), the CSV header `Frame,Time,mount,dx,dy,RARawDistance,...,
//!   ErrorCode`, one row per frame (Frame from 1, Time in s since guiding
//!   began, dx and dy the star minus the lock in camera px, the raw and
//!   guide distances in the mount's axes, px), `N,T,"DROP",,,,,,,,,,,,,
//!   MASS,SNR,CODE,"MESSAGE"` for a frame without its star, `INFO:` lines
//!   (`DITHER by X, Y, new lock pos = ..`, `SETTLING STATE CHANGE, ..`,
//!   `Server received PAUSE`/`RESUME`), and `Guiding Ends at DATE`.
//!
//! Dates run from [`NIGHT_START`]; 1 px = 1 arcsec (`Pixel scale = 1.00`).

use std::fmt::Write;

/// When the night begins: 2026-11-26 20:00:00, local time as PHD2 writes it.
pub const NIGHT_START: (u32, u32, u32, u32) = (2026, 11, 26, 20);

/// The mount's name in the log.
pub const MOUNT: &str = "guide-sim ST4 (mkgp-mount)";

/// PHD2's date and time `t_s` seconds into the night. The night starts
/// late on the 26th of a 30-day month and lasts less than four days.
pub fn date_time(t_s: f64) -> String {
    let (year, month, day, hour) = NIGHT_START;
    let s = (hour as u64) * 3600 + t_s.max(0.0) as u64;
    let (d, rest) = (s / 86_400, s % 86_400);
    assert!(d < 4, "the night lasts less than four days");
    format!(
        "{year}-{month:02}-{:02} {:02}:{:02}:{:02}",
        day as u64 + d,
        rest / 3600,
        rest / 60 % 60,
        rest % 60
    )
}

/// Where the mount points, for a section's header.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pointing {
    pub dec_deg: f64,
    pub hour_angle_hr: f64,
    pub pier_west: bool,
}

/// The guider's calibration as the guiding header gives it: the west and
/// north legs' angles (deg) and rates (px/s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Calibrated {
    pub x_angle_deg: f64,
    pub x_rate: f64,
    pub y_angle_deg: f64,
    pub y_rate: f64,
}

/// A section's header: what PHD2 writes above its rows.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Header {
    pub exposure_ms: u64,
    pub pointing: Pointing,
    /// Lock and star position, camera px.
    pub lock: (f64, f64),
    pub star: (f64, f64),
}

/// One guide frame's row.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Row {
    pub frame: u32,
    pub time_s: f64,
    pub dx: f64,
    pub dy: f64,
    pub ra_raw: f64,
    pub dec_raw: f64,
    pub ra_guide: f64,
    /// The RA pulse, ms, and its direction (`W` or `E`).
    pub ra_ms: u64,
    pub ra_west: bool,
    pub mass: f64,
    pub snr: f64,
}

/// The log being written.
pub struct Phd2Writer {
    out: String,
}

impl Default for Phd2Writer {
    fn default() -> Self {
        Self::new()
    }
}

/// The guider's settings as the guiding header lists them (the rig's
/// guider: `st4_sim`'s PHD2-like hysteresis, RA only).
const SETTINGS: &str = "Dither = RA only, Dither scale = 1.000, Image noise reduction = none, \
Guide-frame time lapse = 0, Server enabled\n";
const PIXEL_SCALE: &str = "Pixel scale = 1.00 arc-sec/px, Binning = 1, Focal length = 784 mm\n";
const PROFILE: &str = "Equipment Profile = guide-sim night\n";
const CAMERA: &str = "guide-sim camera";
const SPEEDS: &str = "RA Guide Speed = 7.5 a-s/s, Dec Guide Speed = 7.5 a-s/s";

impl Phd2Writer {
    /// A new log, enabled when the night begins.
    pub fn new() -> Self {
        let mut w = Phd2Writer { out: String::new() };
        let _ = writeln!(
            w.out,
            "PHD2 version 2.6.13, Log version 2.5. Log enabled at {}",
            date_time(0.0)
        );
        w
    }

    fn pointing_lines(&mut self, h: &Header) {
        let p = h.pointing;
        let _ = writeln!(
            self.out,
            "Dec = {:.1} deg, Hour angle = {:.2} hr, Pier side = {}, Rotator pos = N/A",
            p.dec_deg,
            p.hour_angle_hr,
            if p.pier_west { "West" } else { "East" }
        );
        let _ = writeln!(
            self.out,
            "Lock position = {:.3}, {:.3}, Star position = {:.3}, {:.3}, HFD = 2.50 px",
            h.lock.0, h.lock.1, h.star.0, h.star.1
        );
    }

    pub fn calibration_begins(&mut self, t_s: f64, h: &Header, step_ms: u64, distance_px: f64) {
        let _ = write!(
            self.out,
            "\nCalibration Begins at {}\n{PROFILE}Camera = {CAMERA}\nExposure = {} ms\n{PIXEL_SCALE}",
            date_time(t_s),
            h.exposure_ms
        );
        let _ = writeln!(
            self.out,
            "Mount = {MOUNT}, Calibration Step = {step_ms} ms, Calibration Distance = {distance_px:.0} px, \
             Assume orthogonal axes = no\n{SPEEDS}"
        );
        self.pointing_lines(h);
        self.out.push_str("Direction,Step,dx,dy,x,y,Dist\n");
    }

    /// A calibration step: `d` the starting point minus the star, `at` the
    /// star, camera px.
    pub fn calibration_row(&mut self, leg: &str, step: u32, d: (f64, f64), at: (f64, f64)) {
        let _ = writeln!(
            self.out,
            "{leg},{step},{:.3},{:.3},{:.3},{:.3},{:.3}",
            d.0,
            d.1,
            at.0,
            at.1,
            d.0.hypot(d.1)
        );
    }

    pub fn leg_complete(&mut self, leg: &str, angle_deg: f64, rate_px_s: f64) {
        let _ = writeln!(
            self.out,
            "{leg} calibration complete. Angle = {angle_deg:.1} deg, Rate = {rate_px_s:.3} px/sec, Parity = N/A"
        );
    }

    pub fn calibration_complete(&mut self) {
        let _ = writeln!(self.out, "Calibration complete, mount = {MOUNT}.");
    }

    /// PHD2's notice of a frame without its star during calibration.
    pub fn star_lost_in_calibration(&mut self) {
        self.out.push_str(
            "INFO: STAR LOST during calibration, Mass= 0, SNR= 0.00, Error= 3, Status=Star lost - low mass\n",
        );
    }

    /// A guiding section at `t_s`, right after the calibration `cal`.
    pub fn guiding_begins(&mut self, t_s: f64, h: &Header, cal: &Calibrated) {
        let _ = write!(
            self.out,
            "\nGuiding Begins at {}\n{SETTINGS}{PIXEL_SCALE}\
             Search region = 50 px, Star mass tolerance = 50.0%\n{PROFILE}\
             Camera = {CAMERA}, gain = 95, full size = 1280 x 960, no dark, no defect map, pixel size = 3.8 um\n\
             Exposure = {} ms\n",
            date_time(t_s),
            h.exposure_ms
        );
        let _ = writeln!(
            self.out,
            "Mount = {MOUNT},  connected, guiding enabled, xAngle = {:.1}, xRate = {:.3}, \
             yAngle = {:.1}, yRate = {:.3}, parity = +/-,",
            cal.x_angle_deg, cal.x_rate, cal.y_angle_deg, cal.y_rate
        );
        let _ = writeln!(
            self.out,
            "X guide algorithm = Hysteresis, Hysteresis = 0.100, Aggression = 0.700, Minimum move = 0.200\n\
             Y guide algorithm = Hysteresis, Hysteresis = 0.100, Aggression = 0.700, Minimum move = 0.200\n\
             Backlash comp = disabled, pulse = 0 ms\n\
             Calibration step = 750 ms, Max RA duration = 2500, Max DEC duration = 2500, DEC guide mode = Off\n\
             {SPEEDS}, Cal Dec = {:.1}, Last Cal Issue = None, Timestamp = {}",
            h.pointing.dec_deg,
            date_time(t_s)
        );
        self.pointing_lines(h);
        self.out.push_str(
            "Frame,Time,mount,dx,dy,RARawDistance,DECRawDistance,RAGuideDistance,DECGuideDistance,\
             RADuration,RADirection,DECDuration,DECDirection,XStep,YStep,StarMass,SNR,ErrorCode\n",
        );
    }

    pub fn row(&mut self, r: &Row) {
        let dir = match (r.ra_ms, r.ra_west) {
            (0, _) => "",
            (_, true) => "W",
            (_, false) => "E",
        };
        let _ = writeln!(
            self.out,
            "{},{:.3},\"Mount\",{:.3},{:.3},{:.3},{:.3},{:.3},0.000,{},{dir},0,,,,{:.0},{:.2},0",
            r.frame, r.time_s, r.dx, r.dy, r.ra_raw, r.dec_raw, r.ra_guide, r.ra_ms, r.mass, r.snr
        );
    }

    /// A frame whose star was not found (PHD2's error 3).
    pub fn drop_row(&mut self, frame: u32, time_s: f64) {
        let _ = writeln!(
            self.out,
            "{frame},{time_s:.3},\"DROP\",,,,,,,,,,,,,0,0.00,3,\"Star lost - low mass\""
        );
    }

    /// An `INFO: ` line.
    pub fn info(&mut self, message: &str) {
        let _ = writeln!(self.out, "INFO: {message}");
    }

    pub fn guiding_ends(&mut self, t_s: f64) {
        let _ = writeln!(self.out, "Guiding Ends at {}", date_time(t_s));
    }

    /// The log, closed at `t_s`.
    pub fn close(mut self, t_s: f64) -> String {
        let _ = writeln!(self.out, "\nLog closed at {}", date_time(t_s));
        self.out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dates_roll_over_midnight() {
        assert_eq!(date_time(0.0), "2026-11-26 20:00:00");
        assert_eq!(date_time(4.0 * 3600.0 + 61.5), "2026-11-27 00:01:01");
    }

    #[test]
    fn rows_as_phd2_writes_them() {
        let mut w = Phd2Writer::new();
        w.row(&Row {
            frame: 7,
            time_s: 14.0,
            dx: -0.25,
            dy: 0.5,
            ra_raw: 0.3,
            dec_raw: -0.1,
            ra_guide: 0.189,
            ra_ms: 25,
            ra_west: true,
            mass: 15000.0,
            snr: 30.0,
        });
        w.drop_row(8, 16.0);
        let text = w.close(20.0);
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(
            lines[1],
            "7,14.000,\"Mount\",-0.250,0.500,0.300,-0.100,0.189,0.000,25,W,0,,,,15000,30.00,0"
        );
        assert_eq!(
            lines[2],
            "8,16.000,\"DROP\",,,,,,,,,,,,,0,0.00,3,\"Star lost - low mass\""
        );
        // The same number of fields as the header, the DROP row one more
        // (its message), as PHD2 writes them.
        assert_eq!(lines[1].split(',').count(), 18);
        assert_eq!(lines[2].split(',').count(), 19);
    }
}
