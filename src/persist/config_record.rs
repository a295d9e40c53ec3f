//! The configuration record: every [`MountConfig`] field, in the order of
//! [`Field::ALL`], as a little-endian `u32` (a count as it is, a real number
//! as its `f32` bits). Decoding only rebuilds the struct; whether the values
//! make a mount is [`MountConfig::validate`]'s call, which the store makes
//! before it hands a loaded configuration out.

use crate::mount::config::{Field, MountConfig, Value};

/// Layout version of the configuration record. Change it whenever a field
/// is added, removed, reordered or changes its unit: a record of another
/// layout is then refused instead of misread.
pub const CONFIG_FORMAT: u16 = 2;

/// Bytes of an encoded configuration: one 32-bit word per field.
pub const CONFIG_RECORD_LEN: usize = 4 * Field::ALL.len();

/// The record's bytes.
pub fn encode(config: &MountConfig) -> [u8; CONFIG_RECORD_LEN] {
    let mut out = [0; CONFIG_RECORD_LEN];
    for (word, field) in out.as_chunks_mut::<4>().0.iter_mut().zip(Field::ALL) {
        let bits = match config.get(field) {
            Value::Count(v) => v,
            Value::Real(v) => v.to_bits(),
        };
        *word = bits.to_le_bytes();
    }
    out
}

/// The configuration in `bytes`, or `None` if they are not
/// [`CONFIG_RECORD_LEN`] long. Not validated.
pub fn decode(bytes: &[u8]) -> Option<MountConfig> {
    let (words, rest) = bytes.as_chunks::<4>();
    if !rest.is_empty() || words.len() != Field::ALL.len() {
        return None;
    }
    let mut words = words.iter().map(|w| u32::from_le_bytes(*w));
    let mut count = || words.next();
    // Fields in the order of `Field::ALL` (a struct expression evaluates
    // its fields in the order written); the round-trip test checks it.
    Some(MountConfig {
        ra_steps_per_worm_turn: count()?,
        worm_period_s: f32::from_bits(count()?),
        dec_steps_per_degree: f32::from_bits(count()?),
        guide_rate_sidereal: f32::from_bits(count()?),
        max_rate_sidereal: f32::from_bits(count()?),
        step_tick_hz: count()?,
        glitch_us: count()?,
        pulse_cap_us: count()?,
        guide_cadence_s: f32::from_bits(count()?),
        guider_aggressiveness: f32::from_bits(count()?),
        dither_threshold_us: count()?,
        silence_frames: count()?,
        least_pulse_share: f32::from_bits(count()?),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::SplitMix64;

    /// Every field's bits, as `encode` writes them.
    fn bits(c: &MountConfig) -> [u32; 13] {
        Field::ALL.map(|f| match c.get(f) {
            Value::Count(v) => v,
            Value::Real(v) => v.to_bits(),
        })
    }

    #[test]
    fn every_field_round_trips_bit_for_bit_in_field_order() {
        let mut rng = SplitMix64::new(7);
        let mut bytes = [0u8; CONFIG_RECORD_LEN];
        for _ in 0..10_000 {
            // Arbitrary words, NaNs and infinities included: decoding must
            // not care whether the values make sense.
            bytes.iter_mut().for_each(|b| *b = rng.next_u64() as u8);
            let c = decode(&bytes).unwrap();
            assert_eq!(encode(&c), bytes);
            // Word i is field Field::ALL[i].
            for (i, word) in bits(&c).iter().enumerate() {
                assert_eq!(word.to_le_bytes(), bytes[4 * i..4 * i + 4]);
            }
        }
        let d = MountConfig::default();
        assert_eq!(decode(&encode(&d)), Some(d));
    }

    #[test]
    fn other_lengths_are_refused() {
        let bytes = [0u8; CONFIG_RECORD_LEN + 4];
        for len in 0..bytes.len() {
            if len != CONFIG_RECORD_LEN {
                assert_eq!(decode(&bytes[..len]), None, "{len} bytes");
            }
        }
    }
}
