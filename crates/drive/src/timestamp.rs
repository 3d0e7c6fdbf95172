//! KITTI raw timestamps: `2011-09-26 13:10:59.442711794`, one per line in `timestamps.txt`.
//!
//! They become seconds since the Unix epoch, reading the clock as UTC: KITTI does not say which
//! zone its clock was in, and nothing here needs more than differences between times of one
//! drive, which the zone does not change. The date is converted with our own days-from-civil
//! (proleptic Gregorian) rather than a date-time crate, because this is the only date arithmetic
//! the project needs.
//!
//! Precision: the text is parsed exactly into integer seconds and nanoseconds ([`UnixTime`]);
//! only then is it turned into `f64`, whose resolution at 1.3·10⁹ s is about 0.24 µs — far below
//! the millisecond offsets between scans and OXTS packets that matter here.

use crate::error::ReadError;
use crate::text::{line_error, read_text};
use std::path::Path;

/// A parsed timestamp: whole seconds since 1970-01-01 00:00:00 (clock read as UTC) and the
/// nanoseconds after them, both exact.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct UnixTime {
    /// Whole seconds since the Unix epoch (negative before 1970).
    pub seconds: i64,
    /// Nanoseconds after `seconds`, in `0..1_000_000_000`.
    pub nanos: u32,
}

impl UnixTime {
    /// The time as `f64` seconds since the epoch (about 0.24 µs resolution for dates near 2011).
    pub fn as_seconds(self) -> f64 {
        self.seconds as f64 + f64::from(self.nanos) * 1e-9
    }
}

/// Why a string is not a KITTI timestamp.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("`{text}` is not a timestamp `YYYY-MM-DD hh:mm:ss.fffffffff`: {reason}")]
pub struct TimestampError {
    /// The offending text (cut to 64 characters).
    pub text: String,
    /// What is wrong with it.
    pub reason: &'static str,
}

/// Days from 1970-01-01 to the given proleptic Gregorian date (negative before), after Howard
/// Hinnant's `days_from_civil`. `month` is 1–12 and `day` 1–31; the caller checks the day fits
/// the month.
pub fn days_from_civil(year: i64, month: u32, day: u32) -> i64 {
    let y = if month <= 2 { year - 1 } else { year };
    let era = y.div_euclid(400);
    let yoe = y - era * 400; // [0, 399]
    let m = i64::from(month);
    let doy = (153 * (if m > 2 { m - 3 } else { m + 9 }) + 2) / 5 + i64::from(day) - 1; // [0, 365]
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy; // [0, 146096]
    era * 146_097 + doe - 719_468
}

/// Days in a month of the proleptic Gregorian calendar.
fn days_in_month(year: i64, month: u32) -> u32 {
    match month {
        1 | 3 | 5 | 7 | 8 | 10 | 12 => 31,
        4 | 6 | 9 | 11 => 30,
        _ if (year % 4 == 0 && year % 100 != 0) || year % 400 == 0 => 29,
        _ => 28,
    }
}

/// Parses an unsigned decimal field of exactly `len` ASCII digits (no sign, no spaces).
fn digits(text: &str, len: usize) -> Option<u32> {
    if text.len() != len || !text.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    text.parse().ok()
}

/// Parses `YYYY-MM-DD hh:mm:ss[.f…]` (1 to 9 fraction digits) exactly.
///
/// # Errors
///
/// [`TimestampError`] naming the text and the part that is wrong (format, month, day, hour,
/// minute, second, fraction).
pub fn parse_unix_time(text: &str) -> Result<UnixTime, TimestampError> {
    let fail = |reason| TimestampError {
        text: text.chars().take(64).collect(),
        reason,
    };
    let mut words = text.split_whitespace();
    let (Some(date), Some(time), None) = (words.next(), words.next(), words.next()) else {
        return Err(fail("expected a date and a time separated by a space"));
    };
    let mut d = date.split('-');
    let (Some(y), Some(mo), Some(dd), None) = (d.next(), d.next(), d.next(), d.next()) else {
        return Err(fail("the date is not YYYY-MM-DD"));
    };
    let (Some(year), Some(month), Some(day)) = (digits(y, 4), digits(mo, 2), digits(dd, 2)) else {
        return Err(fail("the date is not YYYY-MM-DD"));
    };
    let year = i64::from(year);
    if !(1..=12).contains(&month) {
        return Err(fail("month outside 01..12"));
    }
    if day == 0 || day > days_in_month(year, month) {
        return Err(fail("day outside the month"));
    }
    let (clock, fraction) = match time.split_once('.') {
        Some((clock, fraction)) => (clock, Some(fraction)),
        None => (time, None),
    };
    let mut c = clock.split(':');
    let (Some(h), Some(mi), Some(s), None) = (c.next(), c.next(), c.next(), c.next()) else {
        return Err(fail("the time is not hh:mm:ss"));
    };
    let (Some(hour), Some(minute), Some(second)) = (digits(h, 2), digits(mi, 2), digits(s, 2))
    else {
        return Err(fail("the time is not hh:mm:ss"));
    };
    if hour > 23 {
        return Err(fail("hour outside 00..23"));
    }
    if minute > 59 {
        return Err(fail("minute outside 00..59"));
    }
    if second > 59 {
        return Err(fail("second outside 00..59"));
    }
    let nanos = match fraction {
        None => 0,
        Some(f) => {
            if f.is_empty() || f.len() > 9 || !f.bytes().all(|b| b.is_ascii_digit()) {
                return Err(fail("the fraction of a second needs 1 to 9 digits"));
            }
            let mut nanos = 0u32;
            for b in f.bytes().chain(std::iter::repeat(b'0')).take(9) {
                nanos = nanos * 10 + u32::from(b - b'0');
            }
            nanos
        }
    };
    let seconds = days_from_civil(year, month, day) * 86_400
        + i64::from(hour) * 3600
        + i64::from(minute) * 60
        + i64::from(second);
    Ok(UnixTime { seconds, nanos })
}

/// Parses a KITTI timestamp into `f64` seconds since the Unix epoch (see [`parse_unix_time`]).
///
/// # Errors
///
/// [`TimestampError`].
pub fn parse_timestamp(text: &str) -> Result<f64, TimestampError> {
    parse_unix_time(text).map(UnixTime::as_seconds)
}

/// Reads a KITTI `timestamps.txt`: one timestamp per line, in frame order, as `f64` seconds.
///
/// Blank lines at the end are accepted (the files end with a newline, some with more); a blank
/// line before the last timestamp is an error, because it would shift every later frame's time by
/// one.
///
/// # Errors
///
/// [`ReadError`] naming the file and, for a bad timestamp or an interior blank line, the line.
pub fn read_timestamps(path: &Path) -> Result<Vec<f64>, ReadError> {
    let text = read_text(path)?;
    let mut times = Vec::new();
    let mut blank_line: Option<usize> = None;
    for (i, line) in text.lines().enumerate() {
        let line_number = i + 1;
        let line = line.trim();
        if line.is_empty() {
            blank_line.get_or_insert(line_number);
            continue;
        }
        if let Some(blank) = blank_line {
            return Err(line_error(
                path,
                blank,
                "blank line before the last timestamp (one timestamp per frame, no gaps)",
            ));
        }
        let t = parse_timestamp(line).map_err(|e| line_error(path, line_number, e.to_string()))?;
        times.push(t);
    }
    Ok(times)
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn days_from_civil_known_dates() {
        assert_eq!(days_from_civil(1970, 1, 1), 0);
        assert_eq!(days_from_civil(1969, 12, 31), -1);
        assert_eq!(days_from_civil(2000, 3, 1), 11_017);
        // 2011-09-26: 41 years incl. 10 leap days since 1970 = 14975 days to 2011-01-01,
        // plus 268 days (Jan..Aug = 243, + 25).
        assert_eq!(days_from_civil(2011, 9, 26), 14_975 + 268);
        assert_eq!(days_from_civil(2011, 1, 1), 14_975);
    }

    #[test]
    fn parses_a_kitti_timestamp_exactly() {
        let t = parse_unix_time("2011-09-26 13:10:59.442711794").unwrap();
        // date -u -d '2011-09-26 13:10:59' +%s = 1317042659
        assert_eq!(
            t,
            UnixTime {
                seconds: 1_317_042_659,
                nanos: 442_711_794
            }
        );
        assert!((t.as_seconds() - 1_317_042_659.0 - 0.442_711_794).abs() < 1e-6);
        let short = parse_unix_time("2011-09-26 13:10:59.5").unwrap();
        assert_eq!(short.nanos, 500_000_000);
        assert_eq!(parse_unix_time("2000-02-29 00:00:00").unwrap().nanos, 0);
        // Two KITTI times 103.564923 ms apart keep that difference to well under a microsecond.
        let a = parse_timestamp("2011-09-26 13:10:59.442711794").unwrap();
        let b = parse_timestamp("2011-09-26 13:10:59.546276717").unwrap();
        assert!((b - a - 0.103_564_923).abs() < 1e-6);
    }

    #[test]
    fn refuses_malformed_timestamps() {
        for (text, reason) in [
            ("2011-09-26", "expected a date"),
            ("2011-09-26 13:10:59 extra", "expected a date"),
            ("2011/09/26 13:10:59", "date"),
            ("2011-13-26 13:10:59", "month"),
            ("2011-02-29 13:10:59", "day"),
            ("2011-09-26 24:00:00", "hour"),
            ("2011-09-26 13:60:00", "minute"),
            ("2011-09-26 13:10:60", "second"),
            ("2011-09-26 13:10:59.", "fraction"),
            ("2011-09-26 13:10:59.1234567890", "fraction"),
            ("2011-09-26 13:10:+9.5", "time"),
            ("2011-09-26 13:10:59.-5", "fraction"),
        ] {
            let err = parse_unix_time(text).unwrap_err();
            assert!(err.reason.contains(reason), "{text}: {err}");
        }
    }

    #[test]
    fn reads_a_timestamps_file_with_trailing_blank_lines() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("timestamps.txt");
        std::fs::write(
            &path,
            "2011-09-26 13:10:59.000000000\n2011-09-26 13:10:59.100000000\n\n\n",
        )
        .unwrap();
        let times = read_timestamps(&path).unwrap();
        assert_eq!(times.len(), 2);
        assert!((times[1] - times[0] - 0.1).abs() < 1e-6);

        std::fs::write(&path, "2011-09-26 13:10:59.0\n\n2011-09-26 13:10:59.1\n").unwrap();
        let err = read_timestamps(&path).unwrap_err();
        assert!(matches!(err, ReadError::Line { line: 2, .. }), "{err}");
        std::fs::write(&path, "2011-09-26 13:10:59.0\n2011-09-26 25:10:59.1\n").unwrap();
        let err = read_timestamps(&path).unwrap_err().to_string();
        assert!(
            err.contains("timestamps.txt:2:") && err.contains("hour"),
            "{err}"
        );
        let missing = dir.path().join("none.txt");
        assert!(matches!(
            read_timestamps(&missing),
            Err(ReadError::Io { .. })
        ));
    }
}
