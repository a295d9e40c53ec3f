//! The park record: the step counts of both axes when the mount was parked,
//! so that a mount not moved while powered off knows where its worm is.

/// Layout version of the park record; change it with the layout.
pub const PARK_FORMAT: u16 = 2;

/// Bytes of an encoded [`Park`]: two `i64`, little-endian, RA first, then
/// [`Park::carries_model`] as one byte, 0 or 1.
pub const PARK_RECORD_LEN: usize = 17;

/// The axes' step counts at park.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Park {
    pub ra_steps: i64,
    pub dec_steps: i64,
    /// The model stored beside the park was saved on the counts' clock,
    /// at the park: a start from the park may place it at the phase the
    /// counts give. Not if it could not be saved (its restored data still
    /// waiting for its phase, or the flash failing): the model stored then
    /// is an older one, on another start's clock, whose phase the next
    /// start must find again.
    pub carries_model: bool,
}

impl Park {
    /// The record's bytes.
    pub fn encode(&self) -> [u8; PARK_RECORD_LEN] {
        let mut out = [0; PARK_RECORD_LEN];
        let (ra, rest) = out.split_at_mut(8);
        let (dec, carries) = rest.split_at_mut(8);
        ra.copy_from_slice(&self.ra_steps.to_le_bytes());
        dec.copy_from_slice(&self.dec_steps.to_le_bytes());
        carries.fill(u8::from(self.carries_model));
        out
    }

    /// The park in `bytes`, or `None` if they are not [`PARK_RECORD_LEN`]
    /// long or the last byte is neither 0 nor 1.
    pub fn decode(bytes: &[u8]) -> Option<Park> {
        let (ra, rest) = bytes.split_first_chunk::<8>()?;
        let (dec, rest) = rest.split_first_chunk::<8>()?;
        let carries_model = match rest {
            [0] => false,
            [1] => true,
            _ => return None,
        };
        Some(Park {
            ra_steps: i64::from_le_bytes(*ra),
            dec_steps: i64::from_le_bytes(*dec),
            carries_model,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::SplitMix64;

    #[test]
    fn parks_round_trip_and_other_lengths_are_refused() {
        let mut rng = SplitMix64::new(5);
        for _ in 0..10_000 {
            let p = Park {
                ra_steps: rng.next_u64() as i64,
                dec_steps: rng.next_u64() as i64,
                carries_model: rng.below(2) == 1,
            };
            let bytes = p.encode();
            assert_eq!(Park::decode(&bytes), Some(p));
            let len = rng.below(40) as usize;
            let mut other = [0u8; 40];
            other.iter_mut().for_each(|b| *b = rng.next_u64() as u8);
            if len != PARK_RECORD_LEN {
                assert_eq!(Park::decode(&other[..len]), None, "{len} bytes");
            }
        }
        // The layout is fixed: RA first, little-endian, the flag last.
        let p = Park {
            ra_steps: 1,
            dec_steps: -1,
            carries_model: true,
        };
        let bytes = p.encode();
        assert_eq!(bytes[..9], [1, 0, 0, 0, 0, 0, 0, 0, 0xFF]);
        assert_eq!(bytes[16], 1);
        // A flag neither 0 nor 1 is no park of this layout.
        for flag in 2..=u8::MAX {
            let mut other = bytes;
            other[16] = flag;
            assert_eq!(Park::decode(&other), None, "{flag}");
        }
    }
}
