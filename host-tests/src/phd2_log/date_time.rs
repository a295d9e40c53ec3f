//! The date and time of `Guiding Begins at 2017-03-10 20:22:52`: where a
//! section starts on the night's clock. PHD2 writes the computer's local
//! time to the second; the `Time` column of the section's rows counts from
//! there.

/// Seconds since 1970-01-01 00:00:00 of `YYYY-MM-DD HH:MM:SS` (the
/// calendar's own time zone), or `None` if `text` is not one.
pub fn seconds(text: &str) -> Option<i64> {
    let mut parts = text.split_whitespace();
    let (date, time) = (parts.next()?, parts.next()?);
    if parts.next().is_some() {
        return None;
    }
    let [y, mo, d] = fields::<3>(date, '-')?;
    let [h, mi, s] = fields::<3>(time, ':')?;
    let days_in_month = match mo {
        1 | 3 | 5 | 7 | 8 | 10 | 12 => 31,
        4 | 6 | 9 | 11 => 30,
        2 if y % 4 == 0 && (y % 100 != 0 || y % 400 == 0) => 29,
        2 => 28,
        _ => return None,
    };
    let valid =
        (1..=9999).contains(&y) && (1..=days_in_month).contains(&d) && h < 24 && mi < 60 && s < 61;
    valid.then(|| days_from_epoch(y, mo, d) * 86_400 + h * 3600 + mi * 60 + s)
}

/// `N` unsigned decimal numbers separated by `sep`.
fn fields<const N: usize>(text: &str, sep: char) -> Option<[i64; N]> {
    let mut out = [0; N];
    let mut it = text.split(sep);
    for slot in &mut out {
        let f = it.next()?;
        if f.is_empty() || f.len() > 4 || !f.bytes().all(|b| b.is_ascii_digit()) {
            return None;
        }
        *slot = f.parse().ok()?;
    }
    it.next().is_none().then_some(out)
}

/// `seconds` since 1970 as `YYYY-MM-DD HH:MM:SS` (what `Guiding Begins at`
/// writes).
pub fn format(seconds: i64) -> String {
    let (days, in_day) = (seconds.div_euclid(86_400), seconds.rem_euclid(86_400));
    let (y, m, d) = date_of(days);
    format!(
        "{y:04}-{m:02}-{d:02} {:02}:{:02}:{:02}",
        in_day / 3600,
        in_day % 3600 / 60,
        in_day % 60
    )
}

/// The date `days` after 1970-01-01: [`days_from_epoch`] undone, era,
/// year of the era (from March), day of that year.
fn date_of(days: i64) -> (i64, i64, i64) {
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let day_of_era = z - era * 146_097;
    let year_of_era =
        (day_of_era - day_of_era / 1460 + day_of_era / 36_524 - day_of_era / 146_096) / 365;
    let day_of_year = day_of_era - (365 * year_of_era + year_of_era / 4 - year_of_era / 100);
    let month_from_march = (5 * day_of_year + 2) / 153;
    let day = day_of_year - (153 * month_from_march + 2) / 5 + 1;
    let month = if month_from_march < 10 {
        month_from_march + 3
    } else {
        month_from_march - 9
    };
    let year = year_of_era + era * 400 + i64::from(month <= 2);
    (year, month, day)
}

/// Days from 1970-01-01 to the given date of the proleptic Gregorian
/// calendar: whole 400-year eras (146,097 days each) from 0000-03-01, then
/// the day within the era, counting years from March so that the leap day
/// comes last.
fn days_from_epoch(year: i64, month: i64, day: i64) -> i64 {
    let y = if month <= 2 { year - 1 } else { year };
    let era = y.div_euclid(400);
    let year_of_era = y - era * 400;
    let month_from_march = (month + 9) % 12;
    let day_of_year = (153 * month_from_march + 2) / 5 + day - 1;
    let day_of_era = year_of_era * 365 + year_of_era / 4 - year_of_era / 100 + day_of_year;
    era * 146_097 + day_of_era - 719_468
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_dates() {
        assert_eq!(seconds("1970-01-01 00:00:00"), Some(0));
        assert_eq!(seconds("2000-03-01 00:00:00"), Some(951_868_800));
        assert_eq!(seconds("2017-03-10 20:22:52"), Some(1_489_177_372));
        // Across midnight and a leap day.
        assert_eq!(
            seconds("2024-03-01 00:00:10").unwrap() - seconds("2024-02-28 23:59:50").unwrap(),
            86_400 + 20
        );
    }

    #[test]
    fn format_undoes_seconds() {
        for s in [
            0,
            951_868_800,
            1_489_177_372,
            1_709_251_210,
            -86_400,
            253_402_300_799,
        ] {
            assert_eq!(seconds(&format(s)), Some(s), "{s}");
        }
        assert_eq!(format(1_489_177_372), "2017-03-10 20:22:52");
    }

    #[test]
    fn not_dates() {
        for bad in [
            "",
            "2017-03-10",
            "2017-13-10 20:22:52",
            "2017-02-29 20:22:52",
            "2017-03-10 24:00:00",
            "2017-03-10 20:22",
            "2017-03-10 20:22:52 extra",
            "2017/03/10 20:22:52",
            "2017-03-10 20:22:-1",
            "99999-03-10 20:22:52",
        ] {
            assert_eq!(seconds(bad), None, "{bad}");
        }
    }
}
