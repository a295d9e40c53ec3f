//! Bytes to commands: finds the LX200 commands `:...#` and the lone ACK
//! byte (the [`Token`]s) in whatever arrives, and throws the rest away,
//! counting it.
//!
//! Rules, in the order a byte meets them:
//! - Outside a command, ACK (0x06) is a token of its own, `:` opens a
//!   command, anything else is garbage (counted per byte).
//! - Inside a command, `#` closes it. A control byte (below 0x20, or DEL)
//!   abandons it: no client puts one inside a command, so it is line noise
//!   or a reconnecting client, and the bytes so far are garbage. ACK inside a
//!   command abandons it and is then an ACK: INDI's connect probe must be
//!   answered even after a half-sent command. Bytes of 0x80 and above stay
//!   in: Meade's degree sign is 0xDF, and the parser judges them.
//! - A command longer than [`COMMAND_CAPACITY`] is an overflow (counted
//!   once); the rest of it, up to its `#`, is dropped.
//! - A command (or an overflow being dropped) that has not ended
//!   [`COMMAND_TIMEOUT_US`] after its `:` is dropped (counted) when the next
//!   bytes arrive, so a client that died mid-command cannot wedge the port.

use heapless::Vec;

/// The longest command body (between `:` and `#`) kept. The longest the
/// LX200 clients send is `Sd sDD*MM:SS` (12 bytes) or `SC MM/DD/YY` (11);
/// ours is a configuration field set, `~Kra_steps_per_worm_turn=` and ten
/// digits (35), or a real with twelve digits, a sign and a point. RAM:
/// this many bytes plus the lexer's state, about 64 bytes per port.
pub const COMMAND_CAPACITY: usize = 48;

/// How long a command may take from its `:` to its `#`. A client writes a
/// command at once (48 bytes take 50 ms at 9600 baud); a second covers a
/// serial bridge that delivers it in pieces.
pub const COMMAND_TIMEOUT_US: u64 = 1_000_000;

/// The single byte LX200 clients send to ask for the alignment mode.
pub const ACK: u8 = 0x06;

/// A complete token.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Token<'a> {
    /// The ACK byte.
    Ack,
    /// A command's body, without its `:` and `#`.
    Command(&'a [u8]),
}

/// What the lexer has thrown away, since start-up (wrapping counts).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LexerCounters {
    /// Bytes outside any command, and the bytes of abandoned commands.
    pub garbage_bytes: u32,
    /// Commands longer than [`COMMAND_CAPACITY`].
    pub overflows: u32,
    /// Commands not ended within [`COMMAND_TIMEOUT_US`].
    pub timeouts: u32,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    /// Between commands.
    Idle,
    /// Inside a command that began at this time.
    Command { since_us: u64 },
    /// Dropping the rest of an overlong command that began at this time.
    Overflow { since_us: u64 },
}

/// The lexer of one port.
#[derive(Clone, Debug)]
pub struct Lexer {
    body: Vec<u8, COMMAND_CAPACITY>,
    state: State,
    counters: LexerCounters,
}

impl Default for Lexer {
    fn default() -> Self {
        Self::new()
    }
}

impl Lexer {
    pub const fn new() -> Self {
        Lexer {
            body: Vec::new(),
            state: State::Idle,
            counters: LexerCounters {
                garbage_bytes: 0,
                overflows: 0,
                timeouts: 0,
            },
        }
    }

    pub fn counters(&self) -> LexerCounters {
        self.counters
    }

    /// Drops a command that began [`COMMAND_TIMEOUT_US`] or more before
    /// `now_us`. Called before each batch of bytes, so a stale half command
    /// never swallows the next one.
    pub fn expire(&mut self, now_us: u64) {
        let since_us = match self.state {
            State::Idle => return,
            State::Command { since_us } | State::Overflow { since_us } => since_us,
        };
        // A clock that runs backwards never times out a command (saturating).
        if now_us.saturating_sub(since_us) >= COMMAND_TIMEOUT_US {
            self.counters.timeouts = self.counters.timeouts.wrapping_add(1);
            self.state = State::Idle;
        }
    }

    /// Takes one byte; returns the token it completes, if any.
    pub fn push(&mut self, byte: u8, now_us: u64) -> Option<Token<'_>> {
        match self.state {
            State::Idle => match byte {
                ACK => return Some(Token::Ack),
                b':' => {
                    self.body.clear();
                    self.state = State::Command { since_us: now_us };
                }
                _ => self.garbage(1),
            },
            State::Command { since_us } => match byte {
                b'#' => {
                    self.state = State::Idle;
                    return Some(Token::Command(&self.body));
                }
                ACK => {
                    self.abandon();
                    return Some(Token::Ack);
                }
                0..=0x1f | 0x7f => {
                    self.abandon();
                    self.garbage(1);
                }
                _ => {
                    if self.body.push(byte).is_err() {
                        self.counters.overflows = self.counters.overflows.wrapping_add(1);
                        self.state = State::Overflow { since_us };
                    }
                }
            },
            State::Overflow { .. } => {
                if byte == b'#' {
                    self.state = State::Idle;
                }
            }
        }
        None
    }

    /// Gives up the command being received; its `:` and body are garbage.
    fn abandon(&mut self) {
        self.garbage(1 + self.body.len());
        self.state = State::Idle;
    }

    fn garbage(&mut self, bytes: usize) {
        // At most COMMAND_CAPACITY + 1 bytes at a time: the cast is exact.
        self.counters.garbage_bytes = self.counters.garbage_bytes.wrapping_add(bytes as u32);
    }
}
