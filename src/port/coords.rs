//! Right ascension and declination as LX200 writes them, in whole seconds
//! of time and arcseconds (no floats: a second of time and an arcsecond
//! are the finest either precision shows).

use super::reply::Reply;
use super::sexagesimal::scan;

/// Right ascension in seconds of time, `0..86_400`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Ra(u32);

/// Declination in arcseconds, `-324_000..=324_000` (±90°).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Dec(i32);

/// Where the mount points, or where a client says it points.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Equatorial {
    pub ra: Ra,
    pub dec: Dec,
}

/// The two forms LX200 writes coordinates in; `:U#` toggles between them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Precision {
    /// `HH:MM.T` and `sDD*MM`.
    Low,
    /// `HH:MM:SS` and `sDD*MM:SS`.
    High,
}

impl Precision {
    pub fn toggled(self) -> Self {
        match self {
            Precision::Low => Precision::High,
            Precision::High => Precision::Low,
        }
    }
}

const DAY_S: u32 = 86_400;
const QUARTER_TURN_ARCSEC: i32 = 324_000;

impl Ra {
    /// `None` outside `0..86_400`.
    pub fn from_seconds(s: u32) -> Option<Self> {
        (s < DAY_S).then_some(Ra(s))
    }

    /// Any number of seconds, wrapped into a day (for the mount, whose RA
    /// comes from a step counter that may run past 24 h either way).
    pub fn wrapping_from_seconds(s: i64) -> Self {
        // rem_euclid of a positive modulus is in 0..86_400: the cast is exact.
        Ra(s.rem_euclid(i64::from(DAY_S)) as u32)
    }

    pub fn seconds(self) -> u32 {
        self.0
    }

    /// `HH:MM:SS` or `HH:MM.T`, with or without seconds' tenths.
    pub fn parse(arg: &[u8]) -> Option<Self> {
        let f = scan(arg)?;
        if f.signed {
            return None;
        }
        let hours = f.whole(0, 23)?;
        let seconds = match f.count {
            // HH:MM.T: minutes with tenths (6 s each).
            2 => hours * 3600 + f.tenths_below(1, 600)? * 6,
            3 => hours * 3600 + f.whole(1, 59)? * 60 + f.tenths_below(2, 600)? / 10,
            _ => return None,
        };
        Ra::from_seconds(seconds)
    }

    pub fn write(self, precision: Precision, out: &mut Reply) {
        let (h, m, s) = (self.0 / 3600, self.0 / 60 % 60, self.0 % 60);
        out.padded(h.into(), 2).byte(b':').padded(m.into(), 2);
        match precision {
            Precision::High => out.byte(b':').padded(s.into(), 2),
            Precision::Low => out.byte(b'.').padded((s / 6).into(), 1),
        };
    }
}

impl Dec {
    /// `None` beyond ±90°.
    pub fn from_arcsec(a: i32) -> Option<Self> {
        (-QUARTER_TURN_ARCSEC..=QUARTER_TURN_ARCSEC)
            .contains(&a)
            .then_some(Dec(a))
    }

    pub fn arcsec(self) -> i32 {
        self.0
    }

    /// `sDD*MM:SS` or `sDD*MM`; the sign may be left out for the north.
    pub fn parse(arg: &[u8]) -> Option<Self> {
        let f = scan(arg)?;
        let degrees = f.whole(0, 90)?;
        let minutes = f.whole(1, 59)?;
        let seconds = match f.count {
            2 => 0,
            3 => f.tenths_below(2, 600)? / 10,
            _ => return None,
        };
        // At most 90 * 3600 + 59 * 60 + 59, well inside i32.
        let magnitude = (degrees * 3600 + minutes * 60 + seconds) as i32;
        Dec::from_arcsec(if f.negative { -magnitude } else { magnitude })
    }

    pub fn write(self, precision: Precision, out: &mut Reply) {
        let a = self.0.unsigned_abs();
        let (d, m, s) = (a / 3600, a / 60 % 60, a % 60);
        out.sign(self.0 < 0).padded(d.into(), 2).byte(b'*');
        out.padded(m.into(), 2);
        if precision == Precision::High {
            out.byte(b':').padded(s.into(), 2);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::port::reply::show;

    #[test]
    fn ra_both_precisions() {
        let ra = Ra::parse(b"06:30:45").unwrap();
        assert_eq!(ra.seconds(), 6 * 3600 + 30 * 60 + 45);
        assert_eq!(show(|r| ra.write(Precision::High, r)), "06:30:45");
        assert_eq!(show(|r| ra.write(Precision::Low, r)), "06:30.7");
        assert_eq!(
            Ra::parse(b"06:30.7").unwrap().seconds(),
            6 * 3600 + 30 * 60 + 42
        );
        assert_eq!(Ra::parse(b" 23 59 59.9").unwrap().seconds(), DAY_S - 1);
        for bad in [
            &b"24:00:00"[..],
            b"12:60:00",
            b"12:00:60",
            b"+12:00:00",
            b"12",
            b"12:59.99x",
        ] {
            assert_eq!(Ra::parse(bad), None, "{:?}", core::str::from_utf8(bad));
        }
        assert_eq!(Ra::wrapping_from_seconds(-1).seconds(), DAY_S - 1);
    }

    #[test]
    fn dec_both_precisions() {
        let dec = Dec::parse(b"-05*07:09").unwrap();
        assert_eq!(dec.arcsec(), -(5 * 3600 + 7 * 60 + 9));
        assert_eq!(show(|r| dec.write(Precision::High, r)), "-05*07:09");
        assert_eq!(show(|r| dec.write(Precision::Low, r)), "-05*07");
        assert_eq!(Dec::parse(b"+90\xdf00").unwrap().arcsec(), 324_000);
        assert_eq!(Dec::parse(b"10*00'00\"").unwrap().arcsec(), 36_000);
        for bad in [&b"+90*00:01"[..], b"+91*00", b"45*60", b"45", b"4O*00"] {
            assert_eq!(Dec::parse(bad), None, "{:?}", core::str::from_utf8(bad));
        }
    }
}
