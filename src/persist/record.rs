//! The envelope every stored record is written in: its format version
//! (`u16`, little-endian) and then the body, whose layout that version
//! names. A reader that finds a version it does not know refuses the record
//! (another firmware's layout) instead of misreading it.

use sequential_storage::map::{SerializationError, Value};

/// Bytes before the body: the format version.
pub const ENVELOPE_LEN: usize = 2;

/// A record as it is stored: format version and body.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Envelope<'a> {
    pub format: u16,
    pub body: &'a [u8],
}

impl<'a> Envelope<'a> {
    /// The envelope in `bytes`, or `None` if they are too short to hold one.
    pub fn parse(bytes: &'a [u8]) -> Option<Self> {
        let (format, body) = bytes.split_first_chunk::<ENVELOPE_LEN>()?;
        Some(Envelope {
            format: u16::from_le_bytes(*format),
            body,
        })
    }
}

impl<'a> Value<'a> for Envelope<'a> {
    fn serialize_into(&self, buffer: &mut [u8]) -> Result<usize, SerializationError> {
        let len = ENVELOPE_LEN + self.body.len();
        let out = buffer
            .get_mut(..len)
            .ok_or(SerializationError::BufferTooSmall)?;
        let (format, body) = out
            .split_first_chunk_mut::<ENVELOPE_LEN>()
            .ok_or(SerializationError::BufferTooSmall)?;
        *format = self.format.to_le_bytes();
        body.copy_from_slice(self.body);
        Ok(len)
    }

    fn deserialize_from(buffer: &'a [u8]) -> Result<(Self, usize), SerializationError> {
        let envelope = Envelope::parse(buffer).ok_or(SerializationError::InvalidFormat)?;
        Ok((envelope, buffer.len()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::SplitMix64;

    #[test]
    fn envelopes_round_trip_and_short_bytes_are_refused() {
        let mut rng = SplitMix64::new(3);
        let mut body = [0u8; 64];
        let mut buf = [0u8; 66];
        for _ in 0..1_000 {
            let len = rng.below(65) as usize;
            body.iter_mut().for_each(|b| *b = rng.next_u64() as u8);
            let e = Envelope {
                format: rng.next_u64() as u16,
                body: &body[..len],
            };
            let n = e.serialize_into(&mut buf).unwrap();
            assert_eq!(n, ENVELOPE_LEN + len);
            assert_eq!(Envelope::deserialize_from(&buf[..n]).unwrap(), (e, n));
            // One byte short of room: refused, not cut.
            assert_eq!(
                e.serialize_into(&mut buf[..n - 1]),
                Err(SerializationError::BufferTooSmall)
            );
        }
        for short in [&[][..], &[7u8][..]] {
            assert_eq!(Envelope::parse(short), None);
            assert_eq!(
                Envelope::deserialize_from(short),
                Err(SerializationError::InvalidFormat)
            );
        }
    }
}
