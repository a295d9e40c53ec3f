//! A configuration value as the port reads and writes it: a count in
//! decimal digits, a real number as `[-]digits[.digits]` (no exponent: the
//! fields are seconds, rates and ratios of a mount). A real is written
//! with the fewest significant digits (six to nine) that read back to the
//! same `f32`.

use super::reply::Reply;
use crate::mount::config::Value;

/// Digits a real number may have: beyond them an `f32` cannot tell.
const MAX_DIGITS: usize = 12;

/// `text` as a value of the kind `like` is; `None` if it is not one.
pub fn parse(text: &[u8], like: Value) -> Option<Value> {
    match like {
        Value::Count(_) => parse_count(text).map(Value::Count),
        Value::Real(_) => parse_real(text).map(Value::Real),
    }
}

fn parse_count(text: &[u8]) -> Option<u32> {
    if text.is_empty() || text.len() > 10 {
        return None;
    }
    let mut n: u32 = 0;
    for &b in text {
        let d = b.checked_sub(b'0').filter(|d| *d <= 9)?;
        n = n.checked_mul(10)?.checked_add(u32::from(d))?;
    }
    Some(n)
}

fn parse_real(text: &[u8]) -> Option<f32> {
    let (negative, rest) = match text {
        [b'-', rest @ ..] => (true, rest),
        [b'+', rest @ ..] => (false, rest),
        _ => (false, text),
    };
    let (whole, fraction) = match rest.iter().position(|&b| b == b'.') {
        Some(dot) => (rest.get(..dot)?, rest.get(dot + 1..)?),
        None => (rest, &[][..]),
    };
    if whole.is_empty() && fraction.is_empty() || whole.len() + fraction.len() > MAX_DIGITS {
        return None;
    }
    // At most 12 digits: exact in an i64, and in an f64 below 2^53.
    let mut mantissa: i64 = 0;
    for &b in whole.iter().chain(fraction) {
        let d = b.checked_sub(b'0').filter(|d| *d <= 9)?;
        mantissa = mantissa * 10 + i64::from(d);
    }
    let mut v = mantissa as f64;
    for _ in 0..fraction.len() {
        v /= 10.0;
    }
    Some(if negative { -v } else { v } as f32)
}

/// Writes `value`: a count as it is, a real with the fewest digits that
/// read back to it and no trailing zeros (`478.69`, `0.5`, `2`); a NaN, an
/// infinity or a value of 1e15 and more as `nan`, `inf`, `huge` (values
/// the port never accepts).
pub fn write(value: Value, reply: &mut Reply) {
    match value {
        Value::Count(n) => {
            reply.uint(n.into());
        }
        Value::Real(v) => write_real(v, reply),
    }
}

fn write_real(v: f32, reply: &mut Reply) {
    if v.is_nan() {
        reply.text(b"nan");
        return;
    }
    if v < 0.0 {
        reply.byte(b'-');
    }
    let a = f64::from(v).abs();
    if a.is_infinite() {
        reply.text(b"inf");
        return;
    }
    let magnitude = decimal_magnitude(a);
    if magnitude > 14 {
        // No mount has such a value (validate refuses it); say so plainly
        // rather than print an integer of thirty digits.
        reply.text(b"huge");
        return;
    }
    // The fewest significant digits that read back as `v`: 478.69, not
    // 478.690002. Nine always do for an f32.
    for digits in 6..=9 {
        let mut text = Reply::new();
        write_digits(a, magnitude, digits, &mut text);
        if digits == 9 || parse_real(text.as_bytes()) == Some(v.abs()) {
            reply.text(text.as_bytes());
            return;
        }
    }
}

/// The decimal exponent of finite `a` >= 0 (`floor(log10(a))`; 0 for 0),
/// at most 15: by whole powers of ten, exact up there, which libm's
/// `log10` and `pow` would pull into the firmware for this alone.
fn decimal_magnitude(a: f64) -> i32 {
    let (mut magnitude, mut power) = (0, 1.0);
    if a >= 1.0 {
        while magnitude < 15 && a >= 10.0 * power {
            power *= 10.0;
            magnitude += 1;
        }
    } else if a > 0.0 {
        // The smallest f32 is 1.4e-45.
        while magnitude > -46 && a * power < 1.0 {
            power *= 10.0;
            magnitude -= 1;
        }
    }
    magnitude
}

/// `a` (finite, >= 0, below 1e15, of decimal `magnitude`) with `digits`
/// significant digits, no trailing zeros after the point.
fn write_digits(a: f64, magnitude: i32, digits: i32, out: &mut Reply) {
    // The decimals that leaves after the point: none for large values, at
    // most 12 (below 1e-3 fewer digits remain; no field is that small).
    let decimals = (digits - 1 - magnitude).clamp(0, 12) as u32;
    // At least 1: no division by zero (and 10^12 fits a u64 anyway).
    let unit = 10u64.pow(decimals).max(1);
    // Below 1e15 (no decimals) or 1e9 x 10 (with them): exact in a u64.
    let scaled = libm::round(a * unit as f64) as u64;
    out.uint(scaled / unit);
    let mut fraction = scaled % unit;
    let mut width = decimals as usize;
    while width > 0 && fraction.is_multiple_of(10) {
        fraction /= 10;
        width -= 1;
    }
    if width > 0 {
        out.byte(b'.').padded(fraction, width);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::SplitMix64;

    fn shown(value: Value) -> std::string::String {
        let mut r = Reply::new();
        write(value, &mut r);
        std::string::String::from_utf8(r.as_bytes().to_vec()).unwrap()
    }

    #[test]
    fn counts_and_reals_read_and_write() {
        let real = Value::Real(0.0);
        let count = Value::Count(0);
        assert_eq!(parse(b"4294967295", count), Some(Value::Count(u32::MAX)));
        assert_eq!(parse(b"4294967296", count), None);
        assert_eq!(parse(b"12a", count), None);
        assert_eq!(parse(b"", count), None);
        assert_eq!(parse(b"-1", count), None);
        assert_eq!(parse(b"478.69", real), Some(Value::Real(478.69)));
        assert_eq!(parse(b"-0.5", real), Some(Value::Real(-0.5)));
        assert_eq!(parse(b".5", real), Some(Value::Real(0.5)));
        assert_eq!(parse(b"2.", real), Some(Value::Real(2.0)));
        for bad in [
            &b"."[..],
            b"",
            b"1e3",
            b"1.2.3",
            b"--1",
            b"1,5",
            b"1234567890123",
        ] {
            assert_eq!(parse(bad, real), None, "{bad:?}");
        }
        assert_eq!(shown(Value::Real(478.69)), "478.69");
        assert_eq!(shown(Value::Real(0.5)), "0.5");
        assert_eq!(shown(Value::Real(2.0)), "2");
        assert_eq!(shown(Value::Real(-0.7)), "-0.7");
        assert_eq!(shown(Value::Real(0.0)), "0");
        assert_eq!(shown(Value::Real(86164.09)), "86164.09");
        assert_eq!(shown(Value::Real(f32::NAN)), "nan");
        assert_eq!(shown(Value::Real(f32::NEG_INFINITY)), "-inf");
        assert_eq!(shown(Value::Real(3e20)), "huge");
        assert_eq!(shown(Value::Real(123_456_789.0)), "123456792");
        assert_eq!(shown(Value::Count(50_000)), "50000");
    }

    /// What is written reads back to the same `f32`, over the range of
    /// the fields (1e-3 to 1e7) and beyond, to 1e9.
    #[test]
    fn reals_round_trip() {
        let mut rng = SplitMix64::new(7);
        for _ in 0..200_000 {
            let exponent = rng.f64_in(-3.0, 9.0);
            let v = libm::pow(10.0, exponent) as f32;
            let text = shown(Value::Real(v));
            assert_eq!(
                parse(text.as_bytes(), Value::Real(0.0)),
                Some(Value::Real(v)),
                "{v:e} -> {text}"
            );
        }
    }

    /// The decimal exponent by powers of ten is `log10`'s, over every
    /// magnitude an `f32` has, at the powers of ten and just below them.
    #[test]
    fn the_decimal_magnitude_is_that_of_log10() {
        let mut rng = SplitMix64::new(9);
        for _ in 0..200_000 {
            let v = libm::pow(10.0, rng.f64_in(-45.0, 14.9)) as f32;
            let a = f64::from(v);
            if a > 0.0 {
                assert_eq!(
                    decimal_magnitude(a),
                    libm::floor(libm::log10(a)) as i32,
                    "{v:e}"
                );
            }
        }
        for k in -30..=14 {
            let power = format!("1e{k}").parse::<f32>().unwrap();
            for v in [power, f32::from_bits(power.to_bits() - 1)] {
                let a = f64::from(v);
                assert_eq!(
                    decimal_magnitude(a),
                    libm::floor(libm::log10(a)) as i32,
                    "{v:e}"
                );
            }
        }
        assert_eq!(decimal_magnitude(0.0), 0);
        assert_eq!(decimal_magnitude(1e20), 15);
    }

    /// Random bytes never panic and never give a non-finite real.
    #[test]
    fn random_text_is_refused_or_finite() {
        let mut rng = SplitMix64::new(8);
        for _ in 0..200_000 {
            let len = rng.below(16) as usize;
            let text: std::vec::Vec<u8> = (0..len)
                .map(|_| b"0123456789.-+e x"[rng.below(16) as usize])
                .collect();
            if let Some(Value::Real(v)) = parse(&text, Value::Real(0.0)) {
                assert!(v.is_finite(), "{text:?}");
            }
        }
    }
}
