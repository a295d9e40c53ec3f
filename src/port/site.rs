//! The site and clock a client sets at connect (`:St :Sg :SG :SL :SC`) and
//! reads back (`:Gt :Gg :GG :GL :GC`). The mount uses none of them (it has
//! no goto and no horizon): each port keeps what its client told it, so the
//! client reads back what it set, and the clock runs from `now_us`.

use super::reply::Reply;
use super::sexagesimal::scan;

/// Latitude in arcminutes, ±90°, north positive.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Latitude(i32);

/// Longitude in arcminutes, ±360°, kept in the client's own convention
/// (Meade counts west positive, others east).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Longitude(i32);

/// Hours added to local time to get UTC (Meade's sign), in tenths, ±14 h.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct UtcOffset(i32);

/// Local time of day in seconds, `0..86_400`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TimeOfDay(u32);

/// A calendar date, years 2000-2099 as LX200's two digits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Date {
    month: u8,
    day: u8,
    year: u8,
}

/// Signed degrees and minutes (`sDD*MM`, seconds read and dropped) in
/// arcminutes, at most `max_degrees`.
fn degrees_minutes(arg: &[u8], max_degrees: u32) -> Option<i32> {
    let f = scan(arg)?;
    if !(2..=3).contains(&f.count) {
        return None;
    }
    let arcmin = f.whole(0, max_degrees)? * 60 + f.whole(1, 59)?;
    if f.count == 3 {
        f.tenths_below(2, 600)?;
    }
    if arcmin > max_degrees * 60 {
        return None;
    }
    // At most 360 * 60: the cast is exact.
    Some(if f.negative {
        -(arcmin as i32)
    } else {
        arcmin as i32
    })
}

fn write_degrees_minutes(arcmin: i32, degree_digits: usize, out: &mut Reply) {
    let a = arcmin.unsigned_abs();
    out.sign(arcmin < 0).padded((a / 60).into(), degree_digits);
    out.byte(b'*').padded((a % 60).into(), 2);
}

impl Latitude {
    pub fn parse(arg: &[u8]) -> Option<Self> {
        degrees_minutes(arg, 90).map(Latitude)
    }

    /// `sDD*MM`.
    pub fn write(self, out: &mut Reply) {
        write_degrees_minutes(self.0, 2, out);
    }
}

impl Longitude {
    pub fn parse(arg: &[u8]) -> Option<Self> {
        degrees_minutes(arg, 360).map(Longitude)
    }

    /// `sDDD*MM`.
    pub fn write(self, out: &mut Reply) {
        write_degrees_minutes(self.0, 3, out);
    }
}

impl UtcOffset {
    /// `sHH` or `sHH.H`.
    pub fn parse(arg: &[u8]) -> Option<Self> {
        let f = scan(arg)?;
        let tenths = f.tenths_below(0, 141)?;
        if f.count != 1 {
            return None;
        }
        // At most 140: the cast is exact.
        Some(UtcOffset(if f.negative {
            -(tenths as i32)
        } else {
            tenths as i32
        }))
    }

    /// `sHH`, or `sHH.H` for a fractional offset.
    pub fn write(self, out: &mut Reply) {
        let t = self.0.unsigned_abs();
        out.sign(self.0 < 0).padded((t / 10).into(), 2);
        if !t.is_multiple_of(10) {
            out.byte(b'.').padded((t % 10).into(), 1);
        }
    }
}

impl TimeOfDay {
    /// `HH:MM:SS`.
    pub fn parse(arg: &[u8]) -> Option<Self> {
        let f = scan(arg)?;
        if f.signed || f.count != 3 {
            return None;
        }
        let s = f.whole(0, 23)? * 3600 + f.whole(1, 59)? * 60 + f.tenths_below(2, 600)? / 10;
        Some(TimeOfDay(s))
    }

    pub fn write(self, out: &mut Reply) {
        let s = self.0;
        out.padded((s / 3600).into(), 2).byte(b':');
        out.padded((s / 60 % 60).into(), 2).byte(b':');
        out.padded((s % 60).into(), 2);
    }
}

impl Default for Date {
    fn default() -> Self {
        Date {
            month: 1,
            day: 1,
            year: 0,
        }
    }
}

impl Date {
    /// `MM/DD/YY`, a day that exists.
    pub fn parse(arg: &[u8]) -> Option<Self> {
        let f = scan(arg)?;
        if f.signed || f.count != 3 {
            return None;
        }
        let (month, day, year) = (f.whole(0, 12)?, f.whole(1, 31)?, f.whole(2, 99)?);
        let leap = year.is_multiple_of(4); // 2000-2099: every fourth year.
        let days = match month {
            1 | 3 | 5 | 7 | 8 | 10 | 12 => 31,
            4 | 6 | 9 | 11 => 30,
            2 if leap => 29,
            2 => 28,
            _ => return None,
        };
        // Each is at most 99: the casts are exact.
        (day >= 1 && day <= days).then_some(Date {
            month: month as u8,
            day: day as u8,
            year: year as u8,
        })
    }

    /// `MM/DD/YY`.
    pub fn write(self, out: &mut Reply) {
        out.padded(self.month.into(), 2).byte(b'/');
        out.padded(self.day.into(), 2).byte(b'/');
        out.padded(self.year.into(), 2);
    }
}

/// What one client told its port. The date does not advance at midnight:
/// clients set it at connect, and the mount has no use for it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Site {
    pub latitude: Latitude,
    pub longitude: Longitude,
    pub utc_offset: UtcOffset,
    pub date: Date,
    /// The time of day a client set, and when.
    time_set: TimeOfDay,
    time_set_at_us: u64,
}

impl Site {
    pub fn set_time(&mut self, time: TimeOfDay, now_us: u64) {
        self.time_set = time;
        self.time_set_at_us = now_us;
    }

    /// The time set, advanced by the time since.
    pub fn time(&self, now_us: u64) -> TimeOfDay {
        let elapsed_s = now_us.saturating_sub(self.time_set_at_us) / 1_000_000;
        let s = (u64::from(self.time_set.0) + elapsed_s) % 86_400;
        // Below 86_400: the cast is exact.
        TimeOfDay(s as u32)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::port::reply::show;

    #[test]
    fn round_trips() {
        let lat = Latitude::parse(b"-33*52").unwrap();
        assert_eq!(show(|r| lat.write(r)), "-33*52");
        let lon = Longitude::parse(b"151*12").unwrap();
        assert_eq!(show(|r| lon.write(r)), "+151*12");
        let utc = UtcOffset::parse(b"-05.5").unwrap();
        assert_eq!(show(|r| utc.write(r)), "-05.5");
        assert_eq!(show(|r| UtcOffset::parse(b"+02").unwrap().write(r)), "+02");
        let date = Date::parse(b"02/29/28").unwrap();
        assert_eq!(show(|r| date.write(r)), "02/29/28");
        let mut site = Site::default();
        site.set_time(TimeOfDay::parse(b"23:59:58").unwrap(), 5_000_000);
        assert_eq!(show(|r| site.time(8_000_000).write(r)), "00:00:01");
    }

    #[test]
    fn refusals() {
        assert_eq!(Latitude::parse(b"+90*01"), None);
        assert_eq!(Longitude::parse(b"361*00"), None);
        assert_eq!(UtcOffset::parse(b"+14.1"), None);
        assert_eq!(TimeOfDay::parse(b"24:00:00"), None);
        assert_eq!(Date::parse(b"02/29/27"), None);
        assert_eq!(Date::parse(b"13/01/27"), None);
        assert_eq!(Date::parse(b"00/01/27"), None);
    }
}
