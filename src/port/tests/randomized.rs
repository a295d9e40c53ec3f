//! Random and mutated command streams through the interpreter and the test
//! double: nothing panics, every byte and every frame is accounted for by
//! the port's counters (checked against a second, plain statement of the
//! framing rules), a refused command reaches neither the mount nor the
//! reply beyond its documented `0`, and nothing asks the mount for a pulse
//! longer than 60 s. Memory is bounded by construction (fixed-size state,
//! checked by `commands::size`).
//!
//! Volume: [`STREAMS`] streams per run (about 41 MB of valid and mutated
//! commands, ACKs and random bytes), and 5 MB of uniformly random bytes;
//! about 1.3 s in release. `MKGP_RANDOMIZED_SCALE=N` multiplies both for
//! longer runs.

use super::double::{Call, DoubleMount};
use crate::port::lexer::{ACK, COMMAND_CAPACITY, COMMAND_TIMEOUT_US};
use crate::port::mount_port::GuidePulse;
use crate::port::reply::{ReplySink, REPLY_CAPACITY};
use crate::port::{Interpreter, PortCounters};
use crate::testing::SplitMix64;
use std::vec::Vec;

/// Streams per CI run.
const STREAMS: u64 = 1_000_000;

fn scale() -> u64 {
    std::env::var("MKGP_RANDOMIZED_SCALE")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1)
}

/// Commands without arguments, as clients send them.
const FIXED: &[&[u8]] = &[
    b"GR",
    b"GD",
    b"U",
    b"Gc",
    b"GM",
    b"GT",
    b"Gt",
    b"Gg",
    b"GG",
    b"GL",
    b"GC",
    b"GU",
    b"GVP",
    b"GVN",
    b"GVD",
    b"GVT",
    b"CM",
    b"MS",
    b"D",
    b"RG",
    b"RC",
    b"RM",
    b"RS",
    b"Mn",
    b"Ms",
    b"Me",
    b"Mw",
    b"Qn",
    b"Qs",
    b"Qe",
    b"Qw",
    b"Q",
    b"Te",
    b"Td",
    b"~L",
    b"~S0",
    b"~S1",
    b"~S7",
    b"~P",
    b"~F0",
    b"~F1",
    b"~R",
    b"~V",
    b"~T0",
    b"~T1",
    b"~Cp",
    b"~Cs",
    b"~Cg",
    b"~Cl",
    b"~Cf",
    b"~Cf7",
    b"~Cs99",
    b"~K",
    b"~K5",
    b"~K11",
    b"~KD",
    b"~KW",
    b"~Kworm_period_s",
    b"~Kglitch_us",
    b"hP",
    b"hR",
    b"~W",
];

fn pick<'a>(rng: &mut SplitMix64, from: &[&'a [u8]]) -> &'a [u8] {
    from.get(rng.below(from.len() as u64) as usize)
        .copied()
        .unwrap_or(b"GR")
}

/// A number of `digits` digits, sometimes out of range.
fn number(rng: &mut SplitMix64, digits: usize, out: &mut Vec<u8>) {
    let n = if rng.below(8) == 0 {
        rng.below(10u64.pow(digits as u32))
    } else {
        rng.below(60)
    };
    out.extend_from_slice(std::format!("{n:0digits$}").as_bytes());
}

/// A valid command, or one with its numbers out of range.
fn command(rng: &mut SplitMix64, out: &mut Vec<u8>) {
    out.push(b':');
    match rng.below(10) {
        0..=3 => out.extend_from_slice(pick(rng, FIXED)),
        4 | 5 => {
            out.extend_from_slice(b"Mg");
            out.push(
                *pick(rng, &[b"n", b"s", b"e", b"w"])
                    .first()
                    .unwrap_or(&b'n'),
            );
            let ms = match rng.below(4) {
                0 => rng.below(100_000),
                1 => 60_000,
                _ => rng.below(3_000),
            };
            out.extend_from_slice(std::format!("{ms:04}").as_bytes());
        }
        6 => {
            out.extend_from_slice(pick(rng, &[b"Sr ", b"SL ", b"Sr"]));
            number(rng, 2, out);
            out.push(b':');
            number(rng, 2, out);
            out.extend_from_slice(pick(rng, &[b":", b"."]));
            number(rng, 2, out);
        }
        7 => {
            out.extend_from_slice(pick(rng, &[b"Sd ", b"St", b"Sg ", b"Sd"]));
            out.extend_from_slice(pick(rng, &[b"+", b"-", b""]));
            number(rng, 2, out);
            out.extend_from_slice(pick(rng, &[b"*", b"\xdf", b":"]));
            number(rng, 2, out);
            if rng.below(2) == 0 {
                out.push(b':');
                number(rng, 2, out);
            }
        }
        8 if rng.below(2) == 0 => {
            // A configuration field set, often out of range.
            let field = crate::mount::config::Field::ALL
                [rng.below(crate::mount::config::Field::ALL.len() as u64) as usize];
            out.extend_from_slice(b"~K");
            out.extend_from_slice(field.name().as_bytes());
            out.push(b'=');
            out.extend_from_slice(pick(rng, &[b"", b"-", b"+"]));
            let digits = 1 + rng.below(6) as usize;
            number(rng, digits, out);
            if rng.below(2) == 0 {
                out.push(b'.');
                let digits = 1 + rng.below(4) as usize;
                number(rng, digits, out);
            }
        }
        8 => {
            out.extend_from_slice(b"SC ");
            number(rng, 2, out);
            out.push(b'/');
            number(rng, 2, out);
            out.push(b'/');
            number(rng, 2, out);
        }
        _ => {
            out.extend_from_slice(b"SG");
            out.extend_from_slice(pick(rng, &[b"+", b"-"]));
            number(rng, 2, out);
            out.extend_from_slice(b".5");
        }
    }
    out.push(b'#');
}

/// One mutation of the bytes from `start` on.
fn mutate(rng: &mut SplitMix64, bytes: &mut Vec<u8>, start: usize) {
    let len = bytes.len() - start;
    if len == 0 {
        return;
    }
    let at = start + rng.below(len as u64) as usize;
    match rng.below(9) {
        // A bit flip.
        0 => bytes[at] ^= 1 << rng.below(8),
        // Truncation.
        1 => bytes.truncate(at),
        // A piece duplicated.
        2 => {
            let piece: Vec<u8> = bytes[at..]
                .iter()
                .take(1 + rng.below(8) as usize)
                .copied()
                .collect();
            bytes.splice(at..at, piece);
        }
        // A NUL.
        3 => bytes.insert(at, 0),
        // A letter where a digit was.
        4 => {
            if let Some(d) = bytes[start..].iter_mut().find(|b| b.is_ascii_digit()) {
                *d = b'a' + rng.below(26) as u8;
            }
        }
        // A huge number.
        5 => {
            let digits = 1 + rng.below(3 * COMMAND_CAPACITY as u64) as usize;
            bytes.splice(at..at, std::iter::repeat_n(b'9', digits));
        }
        // A byte lost.
        6 => {
            bytes.remove(at);
        }
        // A sign.
        7 => bytes.insert(at, b'-'),
        // Any byte.
        _ => bytes.insert(at, rng.below(256) as u8),
    }
}

/// A stream: commands, mutated commands, ACKs and random bytes.
fn stream(rng: &mut SplitMix64, out: &mut Vec<u8>) {
    out.clear();
    for _ in 0..1 + rng.below(6) {
        let start = out.len();
        match rng.below(8) {
            0 => out.push(ACK),
            1 => {
                for _ in 0..rng.below(24) {
                    // Random bytes, rich in the framing ones.
                    let b = match rng.below(4) {
                        0 => *pick(rng, &[b":", b"#", b"\x06", b"\0"])
                            .first()
                            .unwrap_or(&0),
                        _ => rng.below(256) as u8,
                    };
                    out.push(b);
                }
            }
            2..=4 => command(rng, out),
            _ => {
                command(rng, out);
                for _ in 0..1 + rng.below(3) {
                    mutate(rng, out, start);
                }
            }
        }
    }
}

/// The framing rules again, stated plainly, to check the port's counters.
#[derive(Default)]
struct Oracle {
    /// A command being received: when it began, its length, whether it
    /// overflowed.
    partial: Option<(u64, usize, bool)>,
    frames: u64,
    acks: u64,
    garbage: u64,
    overflows: u64,
    timeouts: u64,
}

impl Oracle {
    fn chunk(&mut self, bytes: &[u8], now_us: u64) {
        if let Some((since, _, _)) = self.partial {
            if now_us.saturating_sub(since) >= COMMAND_TIMEOUT_US {
                self.timeouts += 1;
                self.partial = None;
            }
        }
        for &b in bytes {
            self.partial = match self.partial {
                None if b == ACK => {
                    self.acks += 1;
                    None
                }
                None if b == b':' => Some((now_us, 0, false)),
                None => {
                    self.garbage += 1;
                    None
                }
                Some((_, _, true)) if b == b'#' => None,
                Some(p @ (_, _, true)) => Some(p),
                Some(_) if b == b'#' => {
                    self.frames += 1;
                    None
                }
                Some((_, len, _)) if b == ACK => {
                    self.garbage += 1 + len as u64;
                    self.acks += 1;
                    None
                }
                Some((_, len, _)) if b < 0x20 || b == 0x7f => {
                    self.garbage += 2 + len as u64;
                    None
                }
                Some((since, len, _)) if len == COMMAND_CAPACITY => {
                    self.overflows += 1;
                    Some((since, len, true))
                }
                Some((since, len, _)) => Some((since, len + 1, false)),
            };
        }
    }

    fn check(&self, c: &PortCounters) {
        let frames = u64::from(c.commands) + u64::from(c.unknown) + u64::from(c.bad_values);
        assert_eq!(frames, self.frames, "every frame understood or refused");
        assert_eq!(u64::from(c.acks), self.acks);
        assert_eq!(u64::from(c.garbage_bytes), self.garbage);
        assert_eq!(u64::from(c.overflows), self.overflows);
        assert_eq!(u64::from(c.timeouts), self.timeouts);
        assert_eq!(c.replies_cut, 0);
    }
}

/// Counts replies and checks each is whole and bounded.
#[derive(Default)]
struct Sink {
    replies: u64,
    zeros: u64,
}

impl ReplySink for Sink {
    fn send(&mut self, reply: &[u8]) -> bool {
        assert!(!reply.is_empty() && reply.len() <= REPLY_CAPACITY);
        self.replies += 1;
        self.zeros += u64::from(reply == b"0");
        true
    }
}

#[test]
fn random_and_mutated_streams() {
    let streams = STREAMS * scale();
    let mut rng = SplitMix64::new(8);
    let mut port = Interpreter::new();
    let mut mount = DoubleMount::new();
    let mut oracle = Oracle::default();
    let mut bytes = Vec::new();
    let mut now_us: u64 = 0;
    let mut pulses = 0u64;
    for i in 0..streams {
        // A fresh port now and then, so that early states are met often.
        if i % 1000 == 0 {
            port = Interpreter::new();
            oracle = Oracle::default();
        }
        stream(&mut rng, &mut bytes);
        let mut rest = &bytes[..];
        while !rest.is_empty() {
            let (chunk, tail) = rest.split_at((1 + rng.below(64) as usize).min(rest.len()));
            rest = tail;
            now_us = match rng.below(64) {
                0 => now_us + COMMAND_TIMEOUT_US,
                1 => now_us.saturating_sub(rng.below(2 * COMMAND_TIMEOUT_US)),
                _ => now_us + rng.below(2_000),
            };
            let before = port.counters();
            let mut sink = Sink::default();
            mount.calls.clear();
            port.feed(chunk, now_us, &mut mount, &mut sink);
            oracle.chunk(chunk, now_us);
            let after = port.counters();
            // Refusals reach neither the mount nor the reply (but a setter's
            // `0`); each understood command makes at most two calls (`:Q#`)
            // and one reply, each ACK one reply.
            let commands = u64::from(after.commands.wrapping_sub(before.commands));
            let acks = u64::from(after.acks.wrapping_sub(before.acks));
            let bad = u64::from(after.bad_values.wrapping_sub(before.bad_values));
            // A save's reply may come later: at its outcome or its timeout.
            let late = u64::from(after.store_timeouts.wrapping_sub(before.store_timeouts));
            assert!(mount.calls.len() as u64 <= 2 * commands);
            assert!(sink.replies <= commands + acks + bad + late);
            assert!(sink.zeros <= commands + bad + late);
            if rng.below(16) == 0 {
                let waited = port.awaits_store();
                let mut out = Sink::default();
                port.store_done(rng.below(2) == 0, &mut out);
                assert_eq!(out.replies, u64::from(waited));
            }
            for call in &mount.calls {
                if let Call::Guide(pulse) = call {
                    assert!(pulse.duration_ms() <= GuidePulse::MAX_MS);
                    pulses += 1;
                }
            }
        }
        oracle.check(&port.counters());
    }
    // The streams reached the mount, not only the refusals.
    assert!(
        pulses > streams / 10,
        "{pulses} pulses in {streams} streams"
    );
}

#[test]
fn uniform_random_bytes() {
    let mut rng = SplitMix64::new(9);
    let mut port = Interpreter::new();
    let mut mount = DoubleMount::new();
    let mut oracle = Oracle::default();
    let mut chunk = [0u8; 256];
    for i in 0..(20_000 * scale()) {
        for b in chunk.iter_mut() {
            *b = rng.below(256) as u8;
        }
        let now_us = i * 1_000;
        mount.calls.clear();
        port.feed(&chunk, now_us, &mut mount, &mut Sink::default());
        oracle.chunk(&chunk, now_us);
        for call in &mount.calls {
            if let Call::Guide(pulse) = call {
                assert!(pulse.duration_ms() <= GuidePulse::MAX_MS);
            }
        }
    }
    oracle.check(&port.counters());
}
