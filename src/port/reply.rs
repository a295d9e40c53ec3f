//! Replies: a bounded buffer the interpreter formats into, and the sink the
//! transport takes them from.

use heapless::Vec;

/// The longest reply. LX200 replies are under 60 bytes; a telemetry line
/// with three stages takes up to 300; our counter lists are cut to fit (with
/// `more=`, docs/port.md). RAM: this many bytes on the stack while a
/// command is answered, none kept.
pub const REPLY_CAPACITY: usize = 320;

/// Room [`Reply::key_value`] leaves for the end of a list: ` more=99#`.
pub const LIST_END_ROOM: usize = 9;

/// Where replies go: the transport (USB, UART) or a test's buffer. Each
/// call is one whole reply; a transport that cannot take it all (its
/// buffer full: a client that stopped reading) drops it whole and returns
/// `false`, and the interpreter counts it (`replies_dropped`).
pub trait ReplySink {
    fn send(&mut self, reply: &[u8]) -> bool;
}

/// A reply being formatted. Writes past the capacity are dropped and
/// remembered ([`Reply::overflowed`]); callers that can run long check
/// [`Reply::room`] first, so a full reply is a bug the tests catch, not a
/// panic.
#[derive(Clone, Debug, Default)]
pub struct Reply {
    bytes: Vec<u8, REPLY_CAPACITY>,
    overflowed: bool,
}

impl Reply {
    pub fn new() -> Self {
        Self::default()
    }

    pub fn as_bytes(&self) -> &[u8] {
        &self.bytes
    }

    pub fn is_empty(&self) -> bool {
        self.bytes.is_empty()
    }

    pub fn overflowed(&self) -> bool {
        self.overflowed
    }

    /// Bytes still free.
    pub fn room(&self) -> usize {
        REPLY_CAPACITY - self.bytes.len()
    }

    #[inline(never)]
    pub fn text(&mut self, s: &[u8]) -> &mut Self {
        if self.bytes.extend_from_slice(s).is_err() {
            self.overflowed = true;
        }
        self
    }

    pub fn byte(&mut self, b: u8) -> &mut Self {
        if self.bytes.push(b).is_err() {
            self.overflowed = true;
        }
        self
    }

    /// `n` in decimal, at least `width` digits (zero-padded).
    #[inline(never)]
    pub fn padded(&mut self, n: u64, width: usize) -> &mut Self {
        let mut digits = [b'0'; 20];
        let mut len = 0;
        let mut rest = n;
        for slot in digits.iter_mut().rev() {
            *slot = b'0' + (rest % 10) as u8;
            rest /= 10;
            len += 1;
            if rest == 0 && len >= width {
                break;
            }
        }
        let start = digits.len() - len;
        self.text(digits.get(start..).unwrap_or(&[]))
    }

    /// `n` in decimal.
    pub fn uint(&mut self, n: u64) -> &mut Self {
        self.padded(n, 1)
    }

    /// `n` in decimal, with `-` if negative.
    pub fn int(&mut self, n: i64) -> &mut Self {
        if n < 0 {
            self.byte(b'-');
        }
        self.uint(n.unsigned_abs())
    }

    /// ` key=value` (no space before the first): one field of a reply of our
    /// own. `false`, and nothing written, if it would leave less than
    /// [`LIST_END_ROOM`] bytes, so a list always has room for its end.
    #[inline(never)]
    pub fn key_value(&mut self, key: &[u8], value: i64) -> bool {
        let space = usize::from(!self.bytes.is_empty());
        if space + key.len() + 1 + int_len(value) + LIST_END_ROOM > self.room() {
            return false;
        }
        if space == 1 {
            self.byte(b' ');
        }
        self.text(key).byte(b'=').int(value);
        true
    }

    /// `+` or `-`, as LX200 writes the sign of a declination or latitude.
    pub fn sign(&mut self, negative: bool) -> &mut Self {
        self.byte(if negative { b'-' } else { b'+' })
    }
}

/// The number of bytes [`Reply::int`] writes for `n`.
#[inline(never)]
pub fn int_len(n: i64) -> usize {
    let mut len = usize::from(n < 0) + 1;
    let mut rest = n.unsigned_abs() / 10;
    while rest > 0 {
        len += 1;
        rest /= 10;
    }
    len
}

/// What `write` puts into a fresh reply, as text (for the unit tests of
/// the types that write themselves into replies).
#[cfg(test)]
pub(crate) fn show(write: impl Fn(&mut Reply)) -> std::string::String {
    let mut r = Reply::new();
    write(&mut r);
    std::string::String::from_utf8(r.as_bytes().to_vec()).unwrap()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers() {
        let mut r = Reply::new();
        r.padded(7, 2)
            .byte(b' ')
            .uint(0)
            .byte(b' ')
            .int(-120)
            .byte(b' ');
        r.int(i64::MIN).byte(b' ').uint(u64::MAX);
        assert_eq!(
            r.as_bytes(),
            b"07 0 -120 -9223372036854775808 18446744073709551615"
        );
        for n in [0, 9, 10, -1, -10, 12345, i64::MIN, i64::MAX] {
            let mut r = Reply::new();
            r.int(n);
            assert_eq!(r.as_bytes().len(), int_len(n), "{n}");
        }
    }

    #[test]
    fn full_reply_is_cut_not_a_panic() {
        let mut r = Reply::new();
        for _ in 0..REPLY_CAPACITY + 5 {
            r.byte(b'x');
        }
        assert!(r.overflowed());
        assert_eq!(r.room(), 0);
    }
}
