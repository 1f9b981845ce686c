//! Date-and-time cells, as dataframe tools and data loggers write a time column:
//! `2026-11-29 06:00:00.125`, `2026-11-29T06:00:00.125Z`, `2026/11/29 06:00:00,125+01:00`.
//! Each is read as seconds since 1970-01-01 00:00 UTC, as a Parquet timestamp is. A time
//! without a zone is taken as UTC: what a recording needs is the time between its rows.

/// Seconds since 1970-01-01 UTC of `YYYY-MM-DD` (or `/`), `T` or a space, `hh:mm`,
/// optional `:ss` with a fraction after `.` or `,`, and an optional zone (`Z`, `±hh`,
/// `±hh:mm`, `±hhmm`); `None` for anything else, or a date or time out of range.
pub(super) fn parse_date_time(cell: &str) -> Option<f64> {
    let mut s = Cursor(cell.trim().as_bytes());
    let year = s.digits(4)?;
    let sep = s.one_of(b"-/")?;
    let month = s.digits(2)?;
    s.expect(sep)?;
    let day = s.digits(2)?;
    s.one_of(b"T ")?;
    let hour = s.digits(2)?;
    s.expect(b':')?;
    let minute = s.digits(2)?;
    let (mut second, mut fraction) = (0, 0.0);
    if s.peek() == Some(b':') {
        s.expect(b':')?;
        second = s.digits(2)?;
        if matches!(s.peek(), Some(b'.' | b',')) {
            s.0 = &s.0[1..];
            fraction = s.fraction()?;
        }
    }
    let offset_s = s.zone()?;
    let in_range = (1..=12).contains(&month)
        && (1..=days_in_month(year, month)).contains(&day)
        && hour < 24
        && minute < 60
        && second < 61;
    if !s.0.is_empty() || !in_range {
        return None;
    }
    let whole = days_from_civil(year, month, day) * 86_400 + hour * 3600 + minute * 60 + second - offset_s;
    Some(whole as f64 + fraction)
}

/// The bytes of a cell still to read.
struct Cursor<'a>(&'a [u8]);

impl Cursor<'_> {
    fn peek(&self) -> Option<u8> {
        self.0.first().copied()
    }

    /// The next byte, if it is one of `set`.
    fn one_of(&mut self, set: &[u8]) -> Option<u8> {
        let b = self.peek().filter(|b| set.contains(b))?;
        self.0 = &self.0[1..];
        Some(b)
    }

    fn expect(&mut self, b: u8) -> Option<()> {
        self.one_of(&[b]).map(|_| ())
    }

    /// Exactly `n` decimal digits.
    fn digits(&mut self, n: usize) -> Option<i64> {
        let d = self.0.get(..n).filter(|d| d.iter().all(u8::is_ascii_digit))?;
        self.0 = &self.0[n..];
        Some(d.iter().fold(0, |v, &c| 10 * v + i64::from(c - b'0')))
    }

    /// One or more digits after the decimal mark, as a fraction of a second.
    fn fraction(&mut self) -> Option<f64> {
        let n = self.0.iter().take_while(|c| c.is_ascii_digit()).count();
        if n == 0 {
            return None;
        }
        // Digits past the nanosecond change nothing an f64 of seconds since 1970 holds.
        let kept = n.min(9);
        let value = self.0[..kept].iter().fold(0u64, |v, &c| 10 * v + u64::from(c - b'0'));
        self.0 = &self.0[n..];
        Some(value as f64 / 10f64.powi(kept as i32))
    }

    /// The zone's offset east of UTC, s (0 without one).
    fn zone(&mut self) -> Option<i64> {
        let sign = match self.peek() {
            None => return Some(0),
            Some(b'Z' | b'z') => {
                self.0 = &self.0[1..];
                return Some(0);
            }
            Some(b'+') => 1,
            Some(b'-') => -1,
            Some(_) => return None,
        };
        self.0 = &self.0[1..];
        let hours = self.digits(2)?;
        if self.peek() == Some(b':') {
            self.0 = &self.0[1..];
        }
        let minutes = if self.0.is_empty() { 0 } else { self.digits(2)? };
        (hours < 24 && minutes < 60).then_some(sign * (hours * 3600 + minutes * 60))
    }
}

fn days_in_month(year: i64, month: i64) -> i64 {
    let leap = (year % 4 == 0 && year % 100 != 0) || year % 400 == 0;
    match month {
        2 if leap => 29,
        2 => 28,
        4 | 6 | 9 | 11 => 30,
        _ => 31,
    }
}

/// Days from 1970-01-01 to a date of the proleptic Gregorian calendar: counted in
/// 400-year eras of 146 097 days, each year starting on 1 March so that the leap day
/// comes last.
fn days_from_civil(year: i64, month: i64, day: i64) -> i64 {
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
    fn dates_and_times_are_seconds_since_1970_utc() {
        assert_eq!(parse_date_time("1970-01-01 00:00:00"), Some(0.0));
        assert_eq!(parse_date_time("1970-01-02T00:00Z"), Some(86_400.0));
        // 2026-11-29T06:00:00Z, as `date -d 2026-11-29T06:00:00Z +%s` gives it.
        assert_eq!(parse_date_time(" 2026-11-29 06:00:00.125 "), Some(1_795_932_000.125));
        assert_eq!(parse_date_time("2026/11/29 07:00:00,125+01:00"), Some(1_795_932_000.125));
        assert_eq!(parse_date_time("2026-11-29T01:30:00-0430"), Some(1_795_932_000.0));
        assert_eq!(parse_date_time("2000-02-29 00:00:00"), Some(951_782_400.0));
        assert_eq!(parse_date_time("1969-12-31 23:59:59.5"), Some(-0.5));
        // Pandas writes microseconds, some loggers nanoseconds.
        let t = parse_date_time("2026-11-29 06:00:00.000001").unwrap();
        assert!((t - 1_795_932_000.000_001).abs() < 1e-6);
        assert_eq!(
            parse_date_time("2026-11-29 06:00:00.123456789123"),
            parse_date_time("2026-11-29 06:00:00.123456789")
        );
    }

    #[test]
    fn what_is_not_a_date_and_time_is_none() {
        for cell in [
            "",
            "1.5",
            "RUN",
            "2026-11-29",
            "06:00:00",
            "2026-13-01 00:00",
            "2026-02-29 00:00",
            "2026-11-31 00:00",
            "2026-11-29 24:00",
            "2026-11-29 06:60",
            "2026-11-29 06:00:00.",
            "2026-11/29 06:00",
            "2026-11-29 06:00 UTC",
            "2026-11-29 06:00+25:00",
            "26-11-29 06:00",
        ] {
            assert_eq!(parse_date_time(cell), None, "{cell}");
        }
    }

    #[test]
    fn days_count_as_the_calendar_does() {
        // Day by day from 1600 to 2400: each date one day after the one before.
        let mut expected = days_from_civil(1600, 1, 1);
        for year in 1600..2400 {
            for month in 1..=12 {
                for day in 1..=days_in_month(year, month) {
                    assert_eq!(days_from_civil(year, month, day), expected, "{year}-{month}-{day}");
                    expected += 1;
                }
            }
        }
        assert_eq!(days_from_civil(1970, 1, 1), 0);
    }
}
