//! The telemetry line: one per guide frame on a port whose client asked for
//! it (`:~T1#`), for a host tool to plot. It is sent unasked, so it starts
//! with `~T ` where no reply does; fields are `key=value` like our replies.

use super::mount_port::Stage;
use super::reply::Reply;

/// One guide frame as the telemetry line shows it, in fixed point.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TelemetryFrame<'a> {
    /// The board's time, milliseconds since start-up.
    pub time_ms: u64,
    /// Gear time (RA steps over the sidereal step rate), milliseconds.
    pub gear_time_ms: u64,
    /// What made the frame: `m` a measured pulse, `f` filled by the
    /// cadence, `u` unmeasured, `d` a dither.
    pub kind: u8,
    /// The frame's observed gear error, milliarcseconds: where the mount
    /// would have pointed with no correction at all.
    pub observation_mas: i32,
    /// The correction the guider's pulse asked for, milliarcseconds.
    pub pulse_mas: i32,
    /// The mean correction the mount applied over the frame (tracking
    /// corrections: pulses and feed-forward), milliarcseconds.
    pub applied_mas: i32,
    /// The model's prediction for the frame, milliarcseconds.
    pub prediction_mas: i32,
    pub feed_forward_mas_per_s: i32,
    pub learned_permille: u16,
    pub stages: &'a [Stage],
}

/// Bytes one `stage=` field takes at most: ` stage=` and three u32 with two
/// commas.
const STAGE_FIELD_MAX: usize = 7 + 3 * 10 + 2;

/// `~T t_ms=.. gear_ms=.. kind=.. obs_mas=.. pulse_mas=.. applied_mas=..
/// pred_mas=.. ff_mas_s=.. learn_pm=.. stage=PERIOD_MS,AMP_MAS,GATE_PM
/// ...#`, one `stage=` per stage that fits the reply: the firmware's three
/// always do, with every number at its widest.
pub fn write(frame: &TelemetryFrame, out: &mut Reply) {
    out.text(b"~T t_ms=").uint(frame.time_ms);
    out.text(b" gear_ms=").uint(frame.gear_time_ms);
    out.text(b" kind=").byte(frame.kind);
    out.text(b" obs_mas=").int(frame.observation_mas.into());
    out.text(b" pulse_mas=").int(frame.pulse_mas.into());
    out.text(b" applied_mas=").int(frame.applied_mas.into());
    out.text(b" pred_mas=").int(frame.prediction_mas.into());
    out.text(b" ff_mas_s=")
        .int(frame.feed_forward_mas_per_s.into());
    out.text(b" learn_pm=").uint(frame.learned_permille.into());
    for stage in frame.stages {
        if out.room() < STAGE_FIELD_MAX + 1 {
            break;
        }
        out.text(b" stage=").uint(stage.period_ms.into());
        out.byte(b',').uint(stage.amplitude_mas.into());
        out.byte(b',').uint(stage.gate_permille.into());
    }
    out.byte(b'#');
}
