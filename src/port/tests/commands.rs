//! One test per command (or family), with the exact bytes of each reply.

use super::double::{Bench, Call};
use crate::mount::config::{Field, MountConfig};
use crate::mount::learner::FIRMWARE_STAGES;
use crate::port::coords::{Dec, Equatorial, Ra};
use crate::port::interpreter::{Interpreter, STORE_REPLY_TIMEOUT_US};
use crate::port::lexer::{COMMAND_CAPACITY, COMMAND_TIMEOUT_US};
use crate::port::mount_port::{Axis, GuidePulse, Line, ManualRate, PecState, Stage};
use crate::port::telemetry::TelemetryFrame;
use crate::port::ReplySink;
use std::vec;

#[test]
fn ack_is_polar() {
    let mut b = Bench::new();
    assert_eq!(b.feed(&[0x06]), b"P");
    assert_eq!(b.port.counters().acks, 1);
}

#[test]
fn coordinates_in_both_precisions() {
    let mut b = Bench::new();
    assert_eq!(b.ask(":GR#"), "06:30:45#");
    assert_eq!(b.ask(":GD#"), "-05*07:09#");
    assert_eq!(b.ask(":U#"), "");
    assert_eq!(b.ask(":GR#:GD#"), "06:30.7#-05*07#");
    assert_eq!(b.ask(":U#:GR#"), "06:30:45#");
}

#[test]
fn connect_queries() {
    let mut b = Bench::new();
    assert_eq!(b.ask(":Gc#"), "24#");
    assert_eq!(b.ask(":GM#"), "Site#");
    assert_eq!(b.ask(":GT#"), "60.1#");
    assert_eq!(b.ask(":Gt#"), "+00*00#");
    assert_eq!(b.ask(":Gg#"), "+000*00#");
    assert_eq!(b.ask(":GG#"), "+00#");
    assert_eq!(b.ask(":GL#"), "00:00:00#");
    assert_eq!(b.ask(":GC#"), "01/01/00#");
    b.mount.status.tracking = false;
    assert_eq!(b.ask(":GT#"), "00.0#");
}

#[test]
fn setters_answer_and_read_back() {
    let mut b = Bench::new();
    assert_eq!(b.ask(":St+48*07#"), "1");
    assert_eq!(b.ask(":Gt#"), "+48*07#");
    assert_eq!(b.ask(":Sg 348*25#"), "1");
    assert_eq!(b.ask(":Gg#"), "+348*25#");
    assert_eq!(b.ask(":SG-01.0#"), "1");
    assert_eq!(b.ask(":GG#"), "-01#");
    assert_eq!(b.ask(":SL 21:15:00#"), "1");
    b.now_us += 61_000_000;
    assert_eq!(b.ask(":GL#"), "21:16:01#");
    assert_eq!(
        b.ask(":SC 11/23/26#"),
        "1Updating Planetary Data#                              #"
    );
    assert_eq!(b.ask(":GC#"), "11/23/26#");
    assert_eq!(b.port.counters().bad_values, 0);
}

#[test]
fn setters_refuse_with_zero() {
    let mut b = Bench::new();
    for bad in [
        ":Sr 24:00:00#",
        ":Sd +91*00:00#",
        ":St+95*00#",
        ":Sg 400*00#",
        ":SG+15#",
        ":SL 12:60:00#",
        ":SC 02/30/26#",
        ":Sr 1a:00:00#",
        ":Sr#",
    ] {
        assert_eq!(b.ask(bad), "0", "{bad}");
    }
    assert_eq!(b.port.counters().bad_values, 9);
    assert_eq!(b.ask(":GC#"), "01/01/00#");
}

#[test]
fn sync_to_the_target() {
    let mut b = Bench::new();
    assert_eq!(b.ask(":Sr 06:00:00#"), "1");
    assert_eq!(b.ask(":Sd +10*00:00#"), "1");
    assert_eq!(b.ask(":CM#"), "N/A#");
    let to = Equatorial {
        ra: Ra::from_seconds(6 * 3600).unwrap(),
        dec: Dec::from_arcsec(36_000).unwrap(),
    };
    assert_eq!(b.mount.calls, vec![Call::Sync(to)]);
    assert_eq!(b.ask(":GR#:GD#"), "06:00:00#+10*00:00#");
    // The low-precision forms and Meade's degree sign parse too.
    let mut b = Bench::new();
    b.feed(b":Sr 06:00.5#:Sd -10\xdf30#:CM#");
    let to = Equatorial {
        ra: Ra::from_seconds(6 * 3600 + 30).unwrap(),
        dec: Dec::from_arcsec(-37_800).unwrap(),
    };
    assert_eq!(b.mount.calls, vec![Call::Sync(to)]);
}

#[test]
fn goto_is_not_possible() {
    let mut b = Bench::new();
    assert_eq!(b.ask(":MS#"), "1No goto on this mount#");
    assert_eq!(b.ask(":D#"), "#");
    assert!(b.mount.calls.is_empty());
}

#[test]
fn timed_guide_pulses() {
    let mut b = Bench::new();
    assert_eq!(b.ask(":Mgn1200#:Mgs0000#:Mge60000#:Mgw7#"), "");
    let pulse = |line, ms| Call::Guide(GuidePulse::new(line, ms).unwrap());
    assert_eq!(
        b.mount.calls,
        vec![
            pulse(Line::DecPlus, 1200),
            pulse(Line::DecMinus, 0),
            pulse(Line::RaMinus, 60_000),
            pulse(Line::RaPlus, 7),
        ]
    );
}

#[test]
fn guide_pulses_out_of_range_are_refused_silently() {
    let mut b = Bench::new();
    for bad in [
        ":Mgn60001#",
        ":Mgn99999#",
        ":Mgn-100#",
        ":Mgn12a0#",
        ":Mgn123456#",
        ":Mgn#",
        ":Mgx1000#",
        ":Mg#",
        ":Mgn 100#",
    ] {
        assert_eq!(b.ask(bad), "", "{bad}");
    }
    assert!(b.mount.calls.is_empty());
    assert_eq!(b.port.counters().bad_values, 9);
}

#[test]
fn move_at_guide_rate_is_a_pulse_until_stopped() {
    let mut b = Bench::new();
    assert_eq!(b.ask(":RG#:Mw#:Qw#:Ms#:Qs#"), "");
    assert_eq!(
        b.mount.calls,
        vec![
            Call::Guide(GuidePulse::longest(Line::RaPlus)),
            Call::Stop(Axis::Ra),
            Call::Guide(GuidePulse::longest(Line::DecMinus)),
            Call::Stop(Axis::Dec),
        ]
    );
    assert_eq!(GuidePulse::longest(Line::RaPlus).duration_ms(), 60_000);
}

#[test]
fn manual_rates_and_stop_all() {
    let mut b = Bench::new();
    assert_eq!(b.ask(":RC#:Mn#:RM#:Me#:RS#:Ms#:Qe#:Q#"), "");
    assert_eq!(
        b.mount.calls,
        vec![
            Call::MoveAt(Line::DecPlus, ManualRate::Centering),
            Call::MoveAt(Line::RaMinus, ManualRate::Find),
            Call::MoveAt(Line::DecMinus, ManualRate::Max),
            Call::Stop(Axis::Ra),
            Call::Stop(Axis::Ra),
            Call::Stop(Axis::Dec),
        ]
    );
}

#[test]
fn tracking_on_and_off() {
    let mut b = Bench::new();
    assert_eq!(b.ask(":Td#"), "1");
    assert_eq!(b.ask(":GU#"), "nNp~#");
    assert_eq!(b.ask(":Te#"), "1");
    assert_eq!(
        b.mount.calls,
        vec![Call::Tracking(false), Call::Tracking(true)]
    );
}

#[test]
fn status_flags() {
    let mut b = Bench::new();
    assert_eq!(b.ask(":GU#"), "Np~#");
    b.mount.status.guiding = true;
    b.mount.status.pec = PecState::Learning;
    assert_eq!(b.ask(":GU#"), "NpG^#");
    b.mount.status.pec = PecState::Off;
    b.mount.status.tracking = false;
    assert_eq!(b.ask(":GU#"), "nNpG/#");
}

#[test]
fn identity() {
    let mut b = Bench::new();
    assert_eq!(b.ask(":GVP#"), "mkgp-mount#");
    assert_eq!(b.ask(":GVN#"), "0.1.0#");
    assert_eq!(b.ask(":GVD#"), "Nov 23 2026#");
    assert_eq!(b.ask(":GVT#"), "04:30:00#");
}

#[test]
fn own_learning_and_stages() {
    let mut b = Bench::new();
    assert_eq!(
        b.ask(":~L#"),
        "learn_pm=423 ff_mas_s=-1250 ff_on=1 stages=2 from=relearn#"
    );
    assert_eq!(
        b.ask(":~S0#"),
        "period_ms=600000 amp_mas=4250 gate_pm=1000#"
    );
    assert_eq!(b.ask(":~S1#"), "period_ms=86400 amp_mas=730 gate_pm=412#");
    assert_eq!(b.ask(":~S2#"), "none#");
    assert_eq!(b.ask(":~S#"), "");
    assert_eq!(b.port.counters().unknown, 1);
}

#[test]
fn own_switches_steps_and_firmware() {
    let mut b = Bench::new();
    assert_eq!(b.ask(":~F0#:~F1#:~R#"), "111");
    assert_eq!(
        b.mount.calls,
        vec![
            Call::FeedForward(false),
            Call::FeedForward(true),
            Call::ResetModel
        ]
    );
    b.now_us = 61_234_567;
    assert_eq!(
        b.ask(":~P#"),
        "ra_steps=123456789 dec_steps=-42 t_ms=61234#"
    );
    assert_eq!(b.ask(":~V#"), "version=0.1.0 reset=reset_pin#");
}

#[test]
fn own_counters_and_their_continuation() {
    let mut b = Bench::new();
    assert_eq!(
        b.ask(":~Cs#"),
        "glitches=4000000000 glitches=4000000001 glitches=4000000002#"
    );
    assert_eq!(b.ask(":~Cs2#"), "glitches=4000000002#");
    assert_eq!(b.ask(":~Cs9#"), "#");
    // Forty long counters do not fit one reply: the rest from `more=`.
    let first = b.ask(":~Cf#");
    let (_, more) = first.trim_end_matches('#').rsplit_once(" more=").unwrap();
    let next: usize = more.parse().unwrap();
    assert_eq!(first.matches("fault_counter").count(), next);
    let second = b.ask(&std::format!(":~Cf{next}#"));
    assert!(second.starts_with(&std::format!(
        "fault_counter_with_a_long_name={}",
        4_000_000_000u32 + next as u32
    )));
    assert_eq!(b.port.counters().replies_cut, 0);
    assert_eq!(b.ask(":~Cx#"), "");
    assert_eq!(b.port.counters().bad_values, 1);
}

/// The pending configuration by name: read, set with the library's own
/// validation (an error names the field and the rule), listed in pieces,
/// back to the defaults, saved on request.
#[test]
fn own_configuration() {
    let mut b = Bench::new();
    assert_eq!(b.ask(":~Kworm_period_s#"), "worm_period_s=478.6894#");
    assert_eq!(b.ask(":~Kno_such_field#"), "none#");
    assert_eq!(b.ask(":~Kworm_period_s=598.36#"), "1");
    assert_eq!(b.mount.config.worm_period_s, 598.36);
    // The longest command: a count field at its widest (refused: too many
    // steps for the step tick).
    let refused = b.ask(":~Kra_steps_per_worm_turn=4294967295#");
    assert!(
        refused.starts_with("0 field=ra_steps_per_worm_turn rule=too_many"),
        "{refused}"
    );
    assert_eq!(b.ask(":~Kra_steps_per_worm_turn=1000000#"), "1");
    assert_eq!(
        b.ask(":~Kguide_rate_sidereal=0#"),
        "0 field=guide_rate_sidereal rule=must_be_0.1_to_1_(x_sidereal)#"
    );
    assert_eq!(b.mount.config.guide_rate_sidereal, 0.5);
    assert_eq!(
        b.ask(":~Kstep_tick_hz=5.5#"),
        "0 field=step_tick_hz rule=not_a_value_of_its_kind#"
    );
    assert_eq!(b.ask(":~Kno_such_field=1#"), "0");
    // Every field in one or more replies.
    let first = b.ask(":~K#");
    let mut listed = first.matches('=').count();
    let mut reply = first;
    while let Some((_, more)) = reply.trim_end_matches('#').rsplit_once(" more=") {
        listed -= 1;
        reply = b.ask(&std::format!(":~K{more}#"));
        listed += reply.matches('=').count();
    }
    assert_eq!(listed, Field::ALL.len());
    assert_eq!(b.ask(":~KD#"), "1");
    assert_eq!(b.mount.config, MountConfig::default());
    // A save's reply waits for the store's outcome.
    assert_eq!(b.ask(":~KW#"), "");
    assert_eq!(b.mount.calls.last(), Some(&Call::SaveConfig));
    assert_eq!(b.stored(true), "1");
}

/// Park and unpark answer nothing (INDI reads no reply); `:GU#` shows the
/// park; `:~W#` asks for a model save and answers its outcome: one at a
/// time, other commands answered meanwhile, `0` if none comes in time.
#[test]
fn park_unpark_and_model_save() {
    let mut b = Bench::new();
    assert_eq!(b.ask(":hP#"), "");
    assert_eq!(b.ask(":GU#"), "NP~#");
    assert_eq!(b.ask(":hR#:~W#"), "");
    assert!(b.port.awaits_store());
    assert_eq!(b.ask(":GU#:~W#"), "Np~#0");
    assert_eq!(
        b.mount.calls[b.mount.calls.len() - 3..],
        [Call::Park, Call::Unpark, Call::SaveModel]
    );
    assert_eq!(b.stored(false), "0");
    assert!(!b.port.awaits_store());
    assert_eq!(b.stored(true), "");
    assert_eq!(b.ask(":~W#"), "");
    b.now_us += STORE_REPLY_TIMEOUT_US;
    assert_eq!(b.ask(""), "0");
    assert_eq!(b.port.counters().store_timeouts, 1);
    // Refused by the mount (no store): `0` at once.
    b.mount.store = false;
    assert_eq!(b.ask(":~W#:~KW#"), "00");
}

#[test]
fn own_port_counters() {
    let mut b = Bench::new();
    b.feed(b"xx:GR#:Zz#:Mgn99999#");
    assert_eq!(
        b.ask(":~Cp#"),
        "commands=1 acks=0 garbage_bytes=2 overflows=0 timeouts=0 unknown=1 bad_values=1 replies_cut=0 replies_dropped=0 store_timeouts=0#"
    );
}

/// A transport with no room refuses replies and telemetry lines whole: the
/// interpreter counts each, and goes on answering once there is room.
#[test]
fn replies_the_transport_drops_are_counted() {
    struct Full(usize);
    impl ReplySink for Full {
        fn send(&mut self, _: &[u8]) -> bool {
            self.0 += 1;
            false
        }
    }
    let mut b = Bench::new();
    let mut full = Full(0);
    b.port
        .feed(b"\x06:GR#:GD#:~T1#", 0, &mut b.mount, &mut full);
    let frame = TelemetryFrame {
        time_ms: 0,
        gear_time_ms: 0,
        kind: b'm',
        observation_mas: 0,
        pulse_mas: 0,
        applied_mas: 0,
        prediction_mas: 0,
        feed_forward_mas_per_s: 0,
        learned_permille: 0,
        stages: &[],
    };
    b.port.send_telemetry(&frame, &mut full);
    assert_eq!(full.0, 5);
    assert_eq!(b.port.counters().replies_dropped, 5);
    assert_eq!(b.ask(":GR#"), "06:30:45#");
}

#[test]
fn telemetry_only_when_asked() {
    let mut b = Bench::new();
    let frame = TelemetryFrame {
        time_ms: 1_234_567,
        gear_time_ms: 1_200_000,
        kind: b'm',
        observation_mas: -1_500,
        pulse_mas: -700,
        applied_mas: -480,
        prediction_mas: -1_420,
        feed_forward_mas_per_s: 35,
        learned_permille: 423,
        stages: &super::double::STAGES,
    };
    let mut sink = super::double::Replies::default();
    b.port.send_telemetry(&frame, &mut sink);
    assert!(sink.0.is_empty());
    assert_eq!(b.ask(":~T1#"), "1");
    assert!(b.port.telemetry());
    b.port.send_telemetry(&frame, &mut sink);
    assert_eq!(
        sink.0.concat(),
        b"~T t_ms=1234567 gear_ms=1200000 kind=m obs_mas=-1500 pulse_mas=-700 applied_mas=-480 \
          pred_mas=-1420 ff_mas_s=35 learn_pm=423 \
          stage=600000,4250,1000 stage=86400,730,412#"
    );
    // Every number at its widest: the firmware's stages still fit.
    let wide = Stage {
        period_ms: u32::MAX,
        amplitude_mas: u32::MAX,
        gate_permille: u16::MAX,
    };
    let frame = TelemetryFrame {
        time_ms: u64::MAX,
        gear_time_ms: u64::MAX,
        kind: b'd',
        observation_mas: i32::MIN,
        pulse_mas: i32::MIN,
        applied_mas: i32::MIN,
        prediction_mas: i32::MIN,
        feed_forward_mas_per_s: i32::MIN,
        learned_permille: u16::MAX,
        stages: &[wide; 5],
    };
    let mut sink = super::double::Replies::default();
    b.port.send_telemetry(&frame, &mut sink);
    let line = std::string::String::from_utf8(sink.0.concat()).unwrap();
    assert!(
        line.matches("stage=").count() >= FIRMWARE_STAGES && line.ends_with('#'),
        "{line}"
    );
    assert_eq!(b.ask(":~T0#"), "1");
    assert!(!b.port.telemetry());
}

#[test]
fn framing_garbage_binary_and_ack_mid_command() {
    let mut b = Bench::new();
    // Garbage between commands, a leading '#', CR/LF after a command.
    assert_eq!(b.ask("#junk:GR#\r\n"), "06:30:45#");
    assert_eq!(b.port.counters().garbage_bytes, 7);
    // NUL inside a command abandons it (":G" + NUL = 3 bytes); the next is whole.
    assert_eq!(b.feed(b":G\0R#:GR#"), b"06:30:45#");
    assert_eq!(b.port.counters().garbage_bytes, 7 + 3 + 2);
    // ACK inside a command is answered; the half command is dropped.
    assert_eq!(b.feed(b":GR\x06:GD#"), b"P-05*07:09#");
}

#[test]
fn framing_overflow() {
    let mut b = Bench::new();
    let mut long = std::vec![b':'];
    long.extend(std::iter::repeat_n(b'9', COMMAND_CAPACITY + 10));
    long.extend_from_slice(b"#:GR#");
    assert_eq!(b.feed(&long), b"06:30:45#");
    assert_eq!(b.port.counters().overflows, 1);
    // Exactly the capacity is not an overflow (an unknown command).
    let mut full = std::vec![b':'];
    full.extend(std::iter::repeat_n(b'9', COMMAND_CAPACITY));
    full.push(b'#');
    assert_eq!(b.feed(&full), b"");
    assert_eq!(b.port.counters().overflows, 1);
    assert_eq!(b.port.counters().unknown, 1);
}

#[test]
fn framing_timeout() {
    let mut b = Bench::new();
    b.feed(b":GR");
    b.now_us += COMMAND_TIMEOUT_US - 1;
    // In time: the rest completes it.
    assert_eq!(b.ask("#"), "06:30:45#");
    b.feed(b":Sr 06:00");
    b.now_us += COMMAND_TIMEOUT_US;
    // Too late: the half command is gone, and its tail is garbage.
    assert_eq!(b.ask("00#:GR#"), "06:30:45#");
    let c = b.port.counters();
    assert_eq!((c.timeouts, c.garbage_bytes), (1, 3));
    // An overflow being dropped times out too.
    let mut long = std::vec![b':'];
    long.extend(std::iter::repeat_n(b'x', COMMAND_CAPACITY + 1));
    b.feed(&long);
    b.now_us += COMMAND_TIMEOUT_US;
    assert_eq!(b.ask(":GR#"), "06:30:45#");
    assert_eq!(b.port.counters().timeouts, 2);
    // Feeding nothing is enough to let a half command time out.
    b.feed(b":G");
    b.now_us += COMMAND_TIMEOUT_US;
    b.feed(b"");
    assert_eq!(b.port.counters().timeouts, 3);
}

#[test]
fn unknown_commands_are_silent_and_counted() {
    let mut b = Bench::new();
    for unknown in [
        ":GX98#", ":GXY0#", ":GtH#", ":#", ":Mx#", ":Qx#", ":SX 1#", ":~#", ":~Z#",
    ] {
        assert_eq!(b.ask(unknown), "", "{unknown}");
    }
    assert_eq!(b.port.counters().unknown, 9);
}

#[test]
fn size() {
    // The lexer's buffer and the session: a port costs this much RAM.
    let size = core::mem::size_of::<Interpreter>();
    assert!(size <= 192, "{size}");
    // And the reply on the stack while a command is answered.
    let reply = core::mem::size_of::<crate::port::reply::Reply>();
    assert!(reply <= crate::port::reply::REPLY_CAPACITY + 16, "{reply}");
}
