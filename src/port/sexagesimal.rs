//! Reading the numbers of a command argument: `HH:MM:SS`, `HH:MM.T`,
//! `sDD*MM:SS`, `MM/DD/YY`, `sHH.H`.
//!
//! Tolerant of separators as INDI's own parser is: any run of punctuation,
//! spaces or bytes of 0x80 and above (Meade's degree sign 0xDF, UTF-8's
//! `°`) separates two fields. Unlike INDI's parser, letters are refused
//! rather than skipped, so `12:3a:00` is an error and not 12:03:00.

/// At most three fields, each at most [`MAX_FIELD_DIGITS`] digits before an
/// optional decimal point (and as many after it); one decimal is kept
/// (tenths), more are read and dropped. The digit limit refuses huge numbers
/// before they can overflow anything.
pub const MAX_FIELDS: usize = 3;
pub const MAX_FIELD_DIGITS: usize = 3;

/// The numbers of an argument.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Fields {
    /// A leading `-`.
    pub negative: bool,
    /// A leading `+` or `-`.
    pub signed: bool,
    /// Each field in tenths (`12` is 120, `4.5` is 45).
    pub tenths: [u32; MAX_FIELDS],
    /// Whether each field had a decimal point.
    pub fraction: [bool; MAX_FIELDS],
    pub count: usize,
}

impl Fields {
    /// Field `i` as a whole number, if it is one and at most `max`.
    pub fn whole(&self, i: usize, max: u32) -> Option<u32> {
        let tenths = *self.tenths.get(i)?;
        let fraction = *self.fraction.get(i)?;
        (i < self.count && !fraction && tenths / 10 <= max).then_some(tenths / 10)
    }

    /// Field `i` in tenths, if it is below `max_tenths`.
    pub fn tenths_below(&self, i: usize, max_tenths: u32) -> Option<u32> {
        let tenths = *self.tenths.get(i)?;
        (i < self.count && tenths < max_tenths).then_some(tenths)
    }
}

fn is_separator(b: u8) -> bool {
    matches!(
        b,
        b' ' | b':' | b'*' | b'\'' | b'"' | b'/' | b',' | 0x80..=0xff
    )
}

/// Reads `arg` into fields; `None` for anything but separators, digits, one
/// decimal point per field and a leading sign.
pub fn scan(arg: &[u8]) -> Option<Fields> {
    let mut fields = Fields {
        negative: false,
        signed: false,
        tenths: [0; MAX_FIELDS],
        fraction: [false; MAX_FIELDS],
        count: 0,
    };
    let mut rest = arg;
    while let [b' ', tail @ ..] = rest {
        rest = tail;
    }
    if let [sign @ (b'+' | b'-'), tail @ ..] = rest {
        fields.signed = true;
        fields.negative = *sign == b'-';
        rest = tail;
    }
    loop {
        while let [b, tail @ ..] = rest {
            if !is_separator(*b) {
                break;
            }
            rest = tail;
        }
        if rest.is_empty() {
            break;
        }
        let (value, fraction, tail) = field(rest)?;
        let slot = fields.tenths.get_mut(fields.count)?;
        *slot = value;
        if let Some(f) = fields.fraction.get_mut(fields.count) {
            *f = fraction;
        }
        fields.count += 1;
        rest = tail;
    }
    (fields.count > 0).then_some(fields)
}

/// One field at the start of `s`: its value in tenths, whether it had a
/// decimal point, and what follows it.
fn field(s: &[u8]) -> Option<(u32, bool, &[u8])> {
    let mut value: u32 = 0;
    let mut digits = 0;
    let mut rest = s;
    while let [d @ b'0'..=b'9', tail @ ..] = rest {
        digits += 1;
        if digits > MAX_FIELD_DIGITS {
            return None;
        }
        value = value * 10 + u32::from(d - b'0');
        rest = tail;
    }
    if digits == 0 {
        return None;
    }
    value *= 10;
    let mut fraction = false;
    if let [b'.', tail @ ..] = rest {
        fraction = true;
        rest = tail;
        let mut decimals = 0;
        while let [d @ b'0'..=b'9', tail @ ..] = rest {
            if decimals == 0 {
                value += u32::from(d - b'0');
            }
            decimals += 1;
            if decimals > MAX_FIELD_DIGITS {
                return None;
            }
            rest = tail;
        }
        if decimals == 0 {
            return None;
        }
    }
    // A field ends at a separator or at the end, never at a letter.
    match rest {
        [] => Some((value, fraction, rest)),
        [b, ..] if is_separator(*b) => Some((value, fraction, rest)),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn separators_signs_and_tenths() {
        let f = scan(b" -45\xdf30:15").unwrap();
        assert!(f.negative && f.signed);
        assert_eq!((f.count, f.tenths), (3, [450, 300, 150]));
        let f = scan(b"12:34.5").unwrap();
        assert_eq!(
            (f.count, f.tenths, f.fraction),
            (2, [120, 345, 0], [false, true, false])
        );
        assert_eq!(f.whole(1, 59), None);
        assert_eq!(f.tenths_below(1, 600), Some(345));
    }

    #[test]
    fn refusals() {
        for bad in [
            &b""[..],
            b"   ",
            b"12:3a:00",
            b"1234:00:00",
            b"1:2:3:4",
            b"12.:00",
            b"--1",
            b"1.2345",
        ] {
            assert_eq!(scan(bad), None, "{:?}", core::str::from_utf8(bad));
        }
    }
}
