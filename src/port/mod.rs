//! The command port: what a PC says to the mount over USB or a serial line,
//! sans-IO. LX200 as INDI's `indi_lx200generic` and the OnStep driver speak
//! it (the facts in docs/reference.md section 5), plus a namespace of our
//! own (`:~...#`); the command list with every reply is docs/port.md.
//!
//! - [`lexer`]: bytes to `:...#` commands and the ACK byte, garbage counted.
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
//! RAM: an [`Interpreter`] per port (its lexer's
//! [`lexer::COMMAND_CAPACITY`] bytes and some state), and a
//! [`reply::REPLY_CAPACITY`]-byte reply on the stack while a command is
//! answered.

pub mod command;
pub mod config_value;
pub mod coords;
pub mod interpreter;
pub mod lexer;
pub mod mount_port;
pub mod own;
pub mod reply;
pub mod sexagesimal;
pub mod site;
pub mod telemetry;

pub use command::Command;
pub use interpreter::Interpreter;
pub use mount_port::MountPort;
pub use reply::ReplySink;

#[cfg(test)]
mod tests;

// Here, not in `interpreter` which counts them: `own` lists them too.
crate::counters! {
    /// What the port received and refused, since start-up (wrapping counts).
    pub struct PortCounters {
        /// Commands understood and carried out.
        commands,
        /// ACK bytes answered.
        acks,
        /// Bytes outside any command, and of commands abandoned at a control
        /// byte.
        garbage_bytes,
        /// Commands longer than the lexer's buffer.
        overflows,
        /// Commands not ended in time.
        timeouts,
        /// Complete commands we do not know.
        unknown,
        /// Known commands with a malformed or out-of-range value.
        bad_values,
        /// Replies cut because they did not fit (none should be: a bug).
        replies_cut,
        /// Replies and telemetry lines the transport had no room for.
        replies_dropped,
        /// Saves asked (`:~W#`, `:~KW#`) whose outcome did not come within
        /// [`interpreter::STORE_REPLY_TIMEOUT_US`]: answered `0`.
        store_timeouts,
    }
}
