//! The park record: the step counts of both axes when the mount was parked,
//! so that a mount not moved while powered off knows where its worm is.

/// Layout version of the park record; change it with the layout.
pub const PARK_FORMAT: u16 = 1;

/// Bytes of an encoded [`Park`]: two `i64`, little-endian, RA first.
pub const PARK_RECORD_LEN: usize = 16;

/// The axes' step counts at park.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Park {
    pub ra_steps: i64,
    pub dec_steps: i64,
}

impl Park {
    /// The record's bytes.
    pub fn encode(&self) -> [u8; PARK_RECORD_LEN] {
        let mut out = [0; PARK_RECORD_LEN];
        let (ra, dec) = out.split_at_mut(PARK_RECORD_LEN / 2);
        ra.copy_from_slice(&self.ra_steps.to_le_bytes());
        dec.copy_from_slice(&self.dec_steps.to_le_bytes());
        out
    }

    /// The park in `bytes`, or `None` if they are not [`PARK_RECORD_LEN`]
    /// long.
    pub fn decode(bytes: &[u8]) -> Option<Park> {
        let (ra, dec) = bytes.split_first_chunk::<8>()?;
        let dec: &[u8; 8] = dec.try_into().ok()?;
        Some(Park {
            ra_steps: i64::from_le_bytes(*ra),
            dec_steps: i64::from_le_bytes(*dec),
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
        // The layout is fixed: RA first, little-endian.
        let p = Park {
            ra_steps: 1,
            dec_steps: -1,
        };
        assert_eq!(p.encode()[..9], [1, 0, 0, 0, 0, 0, 0, 0, 0xFF]);
    }
}
