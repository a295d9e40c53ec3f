//! Splits the bytes of a command port into what they are: replies to the
//! queries the view sent, telemetry lines, and garbage.
//!
//! The port's rules (docs/port.md) make this possible without timing: a
//! reply is whole and never has a telemetry line inside it, a telemetry
//! line starts with `~T` (no reply does), most replies end with `#`, and a
//! switch (`:~T1#`) answers one byte `1` without `#`, so the view says for
//! each query what shape of reply it expects, in order.

use std::collections::VecDeque;

/// The longest line kept while waiting for its end: a reply is at most
/// 320 bytes; anything longer is garbled and dropped, which bounds memory.
pub const MAX_LINE: usize = 512;

/// The shape of the reply to a query.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Expect {
    /// Up to and with `#`.
    Hash,
    /// One byte (a switch's `1`).
    Byte,
}

/// What the port sent.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Item {
    /// The reply to the oldest query still waiting.
    Reply(String),
    /// A whole telemetry line, `~T ... #` (not yet checked inside).
    Telemetry(String),
    /// A line cut short or too long to be anything (for the page's notice).
    Garbled(String),
    /// Bytes nothing asked for.
    Garbage(usize),
}

#[derive(Default)]
pub struct Stream {
    buf: Vec<u8>,
    pending: VecDeque<Expect>,
}

fn find(hay: &[u8], needle: &[u8], from: usize) -> Option<usize> {
    hay.get(from..)?
        .windows(needle.len())
        .position(|w| w == needle)
        .map(|i| i + from)
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

impl Stream {
    /// A query was sent: its reply comes after those of the earlier ones.
    pub fn expect(&mut self, e: Expect) {
        self.pending.push_back(e);
    }

    /// Forget the replies still expected (a query timed out: its reply is
    /// lost, and would otherwise be taken for the next one's).
    pub fn forget_pending(&mut self) {
        self.pending.clear();
    }

    /// Bytes held while waiting for a line's end (at most [`MAX_LINE`]).
    pub fn held(&self) -> usize {
        self.buf.len()
    }

    /// Takes `bytes` and hands each complete item to `out`.
    pub fn push(&mut self, bytes: &[u8], out: &mut impl FnMut(Item)) {
        self.buf.extend_from_slice(bytes);
        while let Some(n) = self.next_item(out) {
            self.buf.drain(..n);
        }
        if self.buf.len() > MAX_LINE {
            out(Item::Garbled(text(&self.buf[..80])));
            self.buf.clear();
            // Whatever was awaited was in what is dropped.
            self.pending.pop_front();
        }
    }

    /// The next item at the start of the buffer: how many bytes it took,
    /// or `None` to wait for more.
    fn next_item(&mut self, out: &mut impl FnMut(Item)) -> Option<usize> {
        let b = self.buf.as_slice();
        match b {
            [] | [b'~'] => None,
            [b'~', b'T', ..] => {
                let hash = b.iter().position(|&c| c == b'#');
                // A new line before this one's end: this one was cut.
                let next = find(b, b"~T", 2).filter(|&j| hash.is_none_or(|h| j < h));
                if let Some(j) = next {
                    out(Item::Garbled(text(&b[..j])));
                    return Some(j);
                }
                let h = hash?;
                out(Item::Telemetry(text(&b[..=h])));
                Some(h + 1)
            }
            _ => match self.pending.front() {
                Some(Expect::Byte) => {
                    self.pending.pop_front();
                    out(Item::Reply(text(&b[..1])));
                    Some(1)
                }
                Some(Expect::Hash) => {
                    let hash = b.iter().position(|&c| c == b'#');
                    if let Some(j) = find(b, b"~T", 0).filter(|&j| hash.is_none_or(|h| j < h)) {
                        // Replies are whole: this one was cut.
                        self.pending.pop_front();
                        out(Item::Garbled(text(&b[..j])));
                        return Some(j);
                    }
                    let h = hash?;
                    self.pending.pop_front();
                    out(Item::Reply(text(&b[..h])));
                    Some(h + 1)
                }
                None => {
                    // Up to the next possible telemetry line.
                    let n = b
                        .iter()
                        .skip(1)
                        .position(|&c| c == b'~')
                        .map_or(b.len(), |i| i + 1);
                    out(Item::Garbage(n));
                    Some(n)
                }
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn items(s: &mut Stream, bytes: &[u8]) -> Vec<Item> {
        let mut v = Vec::new();
        s.push(bytes, &mut |i| v.push(i));
        v
    }

    #[test]
    fn tells_replies_telemetry_and_garbage_apart() {
        let mut s = Stream::default();
        s.expect(Expect::Hash);
        s.expect(Expect::Byte);
        // A reply split across reads, a line between replies, a switch's 1.
        assert_eq!(items(&mut s, b"mkgp-"), []);
        assert_eq!(
            items(&mut s, b"mount#~T t_ms=1#1xx"),
            [
                Item::Reply("mkgp-mount".into()),
                Item::Telemetry("~T t_ms=1#".into()),
                Item::Reply("1".into()),
                Item::Garbage(2),
            ]
        );
        // A line cut by the next one.
        assert_eq!(
            items(&mut s, b"~T t_ms=2 ge~T t_ms=3#"),
            [
                Item::Garbled("~T t_ms=2 ge".into()),
                Item::Telemetry("~T t_ms=3#".into())
            ]
        );
        // A line that never ends is dropped at MAX_LINE.
        let long = [b'~', b'T']
            .iter()
            .chain([b'x'; MAX_LINE].iter())
            .copied()
            .collect::<Vec<_>>();
        assert!(matches!(items(&mut s, &long)[..], [Item::Garbled(_)]));
        assert_eq!(s.held(), 0);
    }
}
