//! Our own commands, `:~...#`: what no LX200 client knows. Replies are
//! `key=value` fields separated by spaces and ended by `#` (docs/port.md);
//! switches answer `1`.

use super::command::{Counters, Own};
use super::interpreter::PortCounters;
use super::mount_port::{Counter, MountPort};
use super::reply::Reply;

/// The most stages `:~L#` counts (`:~S<n>#` takes one digit).
const MAX_STAGES: usize = 10;

/// Carries out `command`, writing its reply. Returns the telemetry switch
/// if the command set it (the interpreter keeps it, per port).
pub fn carry_out(
    command: Own,
    port: PortCounters,
    mount: &mut impl MountPort,
    reply: &mut Reply,
) -> Option<bool> {
    match command {
        Own::Learning => {
            let learning = mount.learning();
            let stages = (0..MAX_STAGES)
                .take_while(|&i| mount.stage(i).is_some())
                .count();
            reply.key_value(b"learn_pm", learning.learned_permille.into());
            reply.key_value(b"ff_mas_s", learning.feed_forward_mas_per_s.into());
            reply.key_value(b"ff_on", learning.feed_forward_on.into());
            // At most MAX_STAGES: the cast is exact.
            reply.key_value(b"stages", stages as i64);
            reply.byte(b'#');
        }
        Own::Stage(index) => {
            match mount.stage(index) {
                Some(stage) => {
                    reply.key_value(b"period_ms", stage.period_ms.into());
                    reply.key_value(b"amp_mas", stage.amplitude_mas.into());
                    reply.key_value(b"gate_pm", stage.gate_permille.into());
                }
                None => {
                    reply.text(b"none");
                }
            }
            reply.byte(b'#');
        }
        Own::Counters { group, start } => {
            let counter = |i| match group {
                Counters::Port => port.get(i),
                Counters::Mount(group) => mount.counter(group, i),
            };
            list(start, counter, reply);
        }
        Own::Steps => {
            let steps = mount.step_counts();
            reply.key_value(b"ra_steps", steps.ra);
            reply.key_value(b"dec_steps", steps.dec);
            reply.byte(b'#');
        }
        Own::FeedForward(on) => {
            mount.set_feed_forward(on);
            reply.byte(b'1');
        }
        Own::ResetModel => {
            mount.reset_model();
            reply.byte(b'1');
        }
        Own::Firmware => {
            reply
                .text(b"version=")
                .text(mount.identity().version.as_bytes());
            reply.text(b" reset=");
            // Names like "reset pin": a space would end the value.
            for b in mount.reset_cause().name().bytes() {
                reply.byte(if b == b' ' { b'_' } else { b });
            }
            reply.byte(b'#');
        }
        Own::Telemetry(on) => {
            reply.byte(b'1');
            return Some(on);
        }
    }
    None
}

/// `name=value ...#` from counter `start` on; if they do not all fit,
/// ` more=K#` where `K` is the first left out (ask again from there). At
/// most a hundred counters are listed, however many a group claims.
fn list(start: usize, mut counter: impl FnMut(usize) -> Option<Counter>, reply: &mut Reply) {
    for i in start..100 {
        let Some(Counter { name, value }) = counter(i) else {
            break;
        };
        if !reply.key_value(name.as_bytes(), value.into()) {
            if !reply.is_empty() {
                reply.byte(b' ');
            }
            // i < 100: the cast is exact.
            reply.text(b"more=").uint(i as u64);
            break;
        }
    }
    reply.byte(b'#');
}
