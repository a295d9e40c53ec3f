//! The command port: what a PC says to the mount over USB or a serial line,
//! sans-IO. LX200 as INDI's `indi_lx200generic` and the OnStep driver speak
//! it (the facts in docs/reference.md section 5), plus a namespace of our
//! own (`:~...#`); the command list with every reply is docs/port.md.
//!
//! - [`framer`]: bytes to `:...#` frames and the ACK byte, garbage counted.
//! - [`sexagesimal`], [`coords`], [`site`]: the numbers in commands and
//!   replies, range-checked, in integer units.
//! - [`command`]: a frame's body to a [`Command`], or a counted refusal.
//! - [`mount_port`]: the [`MountPort`] trait the firmware and the simulator
//!   implement, and the bounded values that cross it.
//! - [`interpreter`]: [`Interpreter::feed`], the entry point of a transport.
//! - [`own`]: our own commands; [`telemetry`]: the per-frame line;
//!   [`config_value`]: configuration values as text.
//! - [`reply`]: the bounded reply buffer and the [`ReplySink`] trait.
//!
//! RAM: an [`Interpreter`] per port (its framer's
//! [`framer::COMMAND_CAPACITY`] bytes and some state), and a
//! [`reply::REPLY_CAPACITY`]-byte reply on the stack while a command is
//! answered.

pub mod command;
pub mod config_value;
pub mod coords;
pub mod framer;
pub mod interpreter;
pub mod mount_port;
pub mod own;
pub mod reply;
pub mod sexagesimal;
pub mod site;
pub mod telemetry;

pub use command::Command;
pub use interpreter::{Interpreter, PortCounters};
pub use mount_port::MountPort;
pub use reply::ReplySink;

#[cfg(test)]
mod tests;
