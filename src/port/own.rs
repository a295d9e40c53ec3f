//! Our own commands, `:~...#`: what no LX200 client knows. Replies are
//! `key=value` fields separated by spaces and ended by `#` (docs/port.md);
//! switches answer `1`.

use super::command::{Counters, Own};
use super::config_value;
use super::mount_port::{Counter, MountPort};
use super::reply::{Reply, LIST_END_ROOM};
use super::PortCounters;
use crate::counters::Counters as _;
use crate::mount::config::{ConfigError, Field, MountConfig};

/// The most stages `:~L#` counts (`:~S<n>#` takes one digit).
const MAX_STAGES: usize = 10;

/// Answers our own `command` (carrying it out) received at `now_us` (the
/// board's clock), writing its reply. Returns the telemetry switch if the
/// command set it (the interpreter keeps it, per port).
pub fn answer(
    command: Own,
    now_us: u64,
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
            reply
                .text(b" from=")
                .text(learning.origin.name().as_bytes());
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
                Counters::Port => port.get(i).map(|(name, value)| Counter { name, value }),
                Counters::Mount(group) => mount.counter(group, i),
            };
            list(start, counter, reply);
        }
        Own::Steps => {
            let steps = mount.step_counts();
            reply.key_value(b"ra_steps", steps.ra);
            reply.key_value(b"dec_steps", steps.dec);
            // The firmware's clock with them: a client measures rates
            // against it, not against its own clock and the link's delays.
            reply.key_value(b"t_ms", i64::try_from(now_us / 1_000).unwrap_or(i64::MAX));
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
        Own::ConfigList(start) => config_list(&mount.pending_config(), start, reply),
        Own::ConfigGet(field) => {
            match field {
                Some(field) => {
                    reply.text(field.name().as_bytes()).byte(b'=');
                    config_value::write(mount.pending_config().get(field), reply);
                }
                None => {
                    reply.text(b"none");
                }
            }
            reply.byte(b'#');
        }
        Own::ConfigSet { field, value } => {
            let mut config = mount.pending_config();
            let checked = match value {
                Some(value) => config
                    .set(field, value)
                    .ok()
                    .map(|()| config.validate().map(|_| ())),
                None => None,
            };
            match checked {
                Some(Ok(())) => {
                    mount.set_pending_config(config);
                    reply.byte(b'1');
                }
                Some(Err(e)) => refused(&e, reply),
                None => {
                    reply.text(b"0 field=").text(field.name().as_bytes());
                    reply.text(b" rule=not_a_value_of_its_kind#");
                }
            }
        }
        Own::ConfigDefaults => {
            mount.set_pending_config(MountConfig::default());
            reply.byte(b'1');
        }
        // The interpreter's: their reply waits for the store.
        Own::ConfigSave | Own::SaveModel => {}
    }
    None
}

/// A refused configuration: `0 field=NAME rule=WHAT_IT_MUST_BE#`, the rule's
/// spaces as `_` (a space would end the value).
fn refused(e: &ConfigError, reply: &mut Reply) {
    reply.text(b"0 field=").text(e.field.name().as_bytes());
    reply.text(b" rule=");
    for b in e.rule.bytes() {
        reply.byte(if b == b' ' { b'_' } else { b });
    }
    reply.byte(b'#');
}

/// `name=value ...#` of `config` from field `start` on, ended ` more=K#`
/// where the rest does not fit.
fn config_list(config: &MountConfig, start: usize, reply: &mut Reply) {
    for (i, field) in Field::ALL.iter().enumerate().skip(start) {
        let mut value = Reply::new();
        config_value::write(config.get(*field), &mut value);
        let name = field.name().as_bytes();
        let space = usize::from(!reply.is_empty());
        if space + name.len() + 1 + value.as_bytes().len() + LIST_END_ROOM > reply.room() {
            if space == 1 {
                reply.byte(b' ');
            }
            // Fewer than a hundred fields: the cast is exact.
            reply.text(b"more=").uint(i as u64);
            break;
        }
        if space == 1 {
            reply.byte(b' ');
        }
        reply.text(name).byte(b'=').text(value.as_bytes());
    }
    reply.byte(b'#');
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
