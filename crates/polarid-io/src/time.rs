//! Strict RFC 3339 timestamps (`2003-10-17T12:30:30-07:00`) to Unix seconds, for the
//! manifest's capture times (the sun's position, `polarid_core::sun`).
//!
//! Grammar (RFC 3339 §5.6, `date-time`): `YYYY-MM-DD`, then `T` (or `t`, or one space
//! as TOML and RFC 3339's note allow), then `hh:mm:ss`, optional fractional seconds
//! `.d+`, then the offset `Z` (or `z`) or `±hh:mm` (`-00:00` is taken as UTC). The
//! offset is required: a local time without one is ambiguous and refused. Every field
//! is checked: month 01–12, day within its month (leap years of the proleptic Gregorian
//! calendar), hour 00–23, minute 00–59, second 00–59, offset hours 00–23 and minutes
//! 00–59. A leap second (`:60`) is refused, since Unix time does not count leap seconds
//! (write `:59`; one second moves the sun by 0.004° at most). Fractional digits beyond
//! nanoseconds are truncated. Nothing else is accepted: no surrounding spaces, no
//! week or ordinal dates, no `24:00`.
//!
//! A small parser of our own rather than `jiff` or `time`: measured, `jiff` 1.0 with
//! only `std` takes about 34 s of wall time (10 s of CPU) to compile in release on this
//! machine for one function that this module does in a couple of hundred lines.

use thiserror::Error;

/// An RFC 3339 text that cannot be used: the text and what is wrong with it.
#[non_exhaustive]
#[derive(Debug, Error, Clone, PartialEq, Eq)]
#[error("invalid RFC 3339 time {value:?}: {reason}")]
pub struct TimeError {
    /// The text as given.
    pub value: String,
    /// What is wrong, naming the field and its value.
    pub reason: String,
}

/// An instant read from an RFC 3339 text.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Timestamp {
    /// Whole seconds since 1970-01-01T00:00:00Z (leap seconds not counted), rounded down.
    pub unix_seconds: i64,
    /// Nanoseconds after `unix_seconds`, in [0, 10⁹).
    pub nanosecond: u32,
    /// The text's offset from UTC, minutes (east positive; 0 for `Z`).
    pub offset_minutes: i32,
}

impl Timestamp {
    /// Seconds since 1970-01-01T00:00:00Z as `f64` (exact to about 0.1 µs today).
    pub fn unix_seconds_f64(&self) -> f64 {
        self.unix_seconds as f64 + f64::from(self.nanosecond) * 1e-9
    }
}

/// Parse an RFC 3339 date-time with offset into Unix seconds (UTC).
///
/// `"2003-10-17T12:30:30-07:00"` → `1066419030.0`.
///
/// # Errors
/// [`TimeError`] with the text and the field at fault (see the module documentation).
pub fn parse_rfc3339(text: &str) -> Result<f64, TimeError> {
    parse_rfc3339_timestamp(text).map(|t| t.unix_seconds_f64())
}

/// Parse an RFC 3339 date-time with offset, keeping whole seconds, nanoseconds and the
/// offset apart.
///
/// # Errors
/// [`TimeError`] with the text and the field at fault (see the module documentation).
pub fn parse_rfc3339_timestamp(text: &str) -> Result<Timestamp, TimeError> {
    let fail = |reason: String| TimeError {
        value: text.to_string(),
        reason,
    };
    let b = text.as_bytes();
    let mut p = Cursor { s: text, b, i: 0 };

    let year = p.digits(4, "year").map_err(&fail)?;
    p.expect_byte(b'-', "'-' after the year").map_err(&fail)?;
    let month = p.digits(2, "month").map_err(&fail)?;
    p.expect_byte(b'-', "'-' after the month").map_err(&fail)?;
    let day = p.digits(2, "day").map_err(&fail)?;
    match p.next() {
        Some(b'T' | b't' | b' ') => {}
        Some(_) => {
            return Err(fail(format!(
                "expected 'T' between date and time, found {:?}",
                p.char_at(p.i - 1)
            )));
        }
        None => {
            return Err(fail(
                "a date alone is not a time: add 'T', hh:mm:ss and an offset".to_string(),
            ));
        }
    }
    let hour = p.digits(2, "hour").map_err(&fail)?;
    p.expect_byte(b':', "':' after the hour").map_err(&fail)?;
    let minute = p.digits(2, "minute").map_err(&fail)?;
    p.expect_byte(b':', "':' after the minute").map_err(&fail)?;
    let second = p.digits(2, "second").map_err(&fail)?;
    let nanosecond = p.fraction().map_err(&fail)?;
    let offset_minutes = p.offset().map_err(&fail)?;
    if p.i != b.len() {
        return Err(fail(format!(
            "unexpected {:?} after the offset",
            String::from_utf8_lossy(&b[p.i..])
        )));
    }

    check_ranges([year, month, day], [hour, minute, second]).map_err(fail)?;

    let days = days_from_civil(year as i64, month as i64, day as i64);
    let local = days * 86_400 + (hour * 3600 + minute * 60 + second) as i64;
    Ok(Timestamp {
        unix_seconds: local - i64::from(offset_minutes) * 60,
        nanosecond,
        offset_minutes,
    })
}

/// Format whole Unix seconds as RFC 3339 in UTC, `YYYY-MM-DDThh:mm:ssZ` (years 0000 to
/// 9999; `None` outside them).
pub fn format_rfc3339_utc(unix_seconds: i64) -> Option<String> {
    let days = unix_seconds.div_euclid(86_400);
    let secs = unix_seconds.rem_euclid(86_400);
    let (y, m, d) = civil_from_days(days);
    if !(0..=9999).contains(&y) {
        return None;
    }
    Some(format!(
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}Z",
        secs / 3600,
        secs / 60 % 60,
        secs % 60
    ))
}

/// The date and time fields must be in range (no leap second).
fn check_ranges(
    [year, month, day]: [u32; 3],
    [hour, minute, second]: [u32; 3],
) -> Result<(), String> {
    if !(1..=12).contains(&month) {
        return Err(format!("month {month:02} is out of range (01 to 12)"));
    }
    let dim = days_in_month(year, month);
    if !(1..=dim).contains(&day) {
        return Err(format!(
            "day {day:02} is out of range for {year:04}-{month:02} (01 to {dim:02})"
        ));
    }
    if hour > 23 {
        return Err(format!("hour {hour:02} is out of range (00 to 23)"));
    }
    if minute > 59 {
        return Err(format!("minute {minute:02} is out of range (00 to 59)"));
    }
    if second == 60 {
        return Err("second 60 (a leap second) cannot be a Unix time: use 59".to_string());
    }
    if second > 59 {
        return Err(format!("second {second:02} is out of range (00 to 59)"));
    }
    Ok(())
}

/// Byte cursor over the text.
struct Cursor<'a> {
    s: &'a str,
    b: &'a [u8],
    i: usize,
}

impl Cursor<'_> {
    /// The (whole, possibly non-ASCII) character starting at byte `i`.
    fn char_at(&self, i: usize) -> char {
        self.s
            .get(i..)
            .and_then(|t| t.chars().next())
            .unwrap_or(char::REPLACEMENT_CHARACTER)
    }

    fn peek(&self) -> Option<u8> {
        self.b.get(self.i).copied()
    }

    fn next(&mut self) -> Option<u8> {
        let c = self.peek();
        if c.is_some() {
            self.i += 1;
        }
        c
    }

    /// Exactly `n` ASCII digits.
    fn digits(&mut self, n: usize, what: &str) -> Result<u32, String> {
        let mut v = 0u32;
        for k in 0..n {
            match self.peek() {
                Some(c @ b'0'..=b'9') => {
                    v = v * 10 + u32::from(c - b'0');
                    self.i += 1;
                }
                Some(_) => {
                    return Err(format!(
                        "{what} must be {n} digits, found {:?} at digit {}",
                        self.char_at(self.i),
                        k + 1
                    ));
                }
                None => return Err(format!("{what} must be {n} digits, the text ends")),
            }
        }
        Ok(v)
    }

    fn expect_byte(&mut self, c: u8, what: &str) -> Result<(), String> {
        match self.next() {
            Some(x) if x == c => Ok(()),
            Some(_) => Err(format!(
                "expected {what}, found {:?}",
                self.char_at(self.i - 1)
            )),
            None => Err(format!("expected {what}, the text ends")),
        }
    }

    /// The optional fraction of the seconds (`.` and digits), in nanoseconds (digits
    /// after the ninth are ignored).
    fn fraction(&mut self) -> Result<u32, String> {
        let mut nanosecond: u32 = 0;
        if self.peek() == Some(b'.') {
            self.i += 1;
            let start = self.i;
            while let Some(c @ b'0'..=b'9') = self.peek() {
                let k = self.i - start;
                if k < 9 {
                    nanosecond += u32::from(c - b'0') * 10u32.pow(8 - k as u32);
                }
                self.i += 1;
            }
            if self.i == start {
                return Err("expected digits after the decimal point of the seconds".to_string());
            }
        }
        Ok(nanosecond)
    }

    /// The offset, `Z` or `±hh:mm`, in minutes.
    fn offset(&mut self) -> Result<i32, String> {
        match self.next() {
            Some(b'Z' | b'z') => Ok(0),
            Some(sign @ (b'+' | b'-')) => {
                let oh = self.digits(2, "offset hour")?;
                self.expect_byte(b':', "':' in the offset (±hh:mm)")?;
                let om = self.digits(2, "offset minute")?;
                if oh > 23 {
                    return Err(format!("offset hour {oh:02} is out of range (00 to 23)"));
                }
                if om > 59 {
                    return Err(format!("offset minute {om:02} is out of range (00 to 59)"));
                }
                let m = (oh * 60 + om) as i32;
                Ok(if sign == b'-' { -m } else { m })
            }
            Some(_) => Err(format!(
                "expected an offset 'Z' or ±hh:mm, found {:?}",
                self.char_at(self.i - 1)
            )),
            None => {
                Err("missing offset: a local time is ambiguous, end with 'Z' or ±hh:mm".to_string())
            }
        }
    }
}

fn is_leap(year: u32) -> bool {
    year.is_multiple_of(4) && (!year.is_multiple_of(100) || year.is_multiple_of(400))
}

fn days_in_month(year: u32, month: u32) -> u32 {
    match month {
        2 if is_leap(year) => 29,
        2 => 28,
        4 | 6 | 9 | 11 => 30,
        _ => 31,
    }
}

/// Days since 1970-01-01 of a proleptic Gregorian date (H. Hinnant's algorithm).
fn days_from_civil(y: i64, m: i64, d: i64) -> i64 {
    let y = if m <= 2 { y - 1 } else { y };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let mp = (m + 9) % 12;
    let doy = (153 * mp + 2) / 5 + d - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    era * 146_097 + doe - 719_468
}

/// Inverse of [`days_from_civil`].
fn civil_from_days(z: i64) -> (i64, i64, i64) {
    let z = z + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    (y, m, d)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn err(text: &str) -> String {
        let e = parse_rfc3339(text).unwrap_err();
        assert_eq!(e.value, text);
        let msg = e.to_string();
        assert!(msg.contains(text), "{msg}");
        e.reason
    }

    #[test]
    fn spa_reference_time_with_offset() {
        assert_eq!(
            parse_rfc3339("2003-10-17T12:30:30-07:00").unwrap(),
            1_066_419_030.0
        );
        assert_eq!(
            parse_rfc3339("2003-10-17T19:30:30Z").unwrap(),
            1_066_419_030.0
        );
        assert_eq!(
            parse_rfc3339("2003-10-18T02:30:30+07:00").unwrap(),
            1_066_419_030.0
        );
        assert_eq!(
            parse_rfc3339("2003-10-17t19:30:30z").unwrap(),
            1_066_419_030.0
        );
        assert_eq!(
            parse_rfc3339("2003-10-17 19:30:30-00:00").unwrap(),
            1_066_419_030.0
        );
        let t = parse_rfc3339_timestamp("2003-10-17T12:30:30-07:00").unwrap();
        assert_eq!(t.offset_minutes, -420);
        assert_eq!(t.nanosecond, 0);
    }

    #[test]
    fn epochs_and_odd_offsets() {
        assert_eq!(parse_rfc3339("1970-01-01T00:00:00Z").unwrap(), 0.0);
        assert_eq!(parse_rfc3339("1969-12-31T23:59:59Z").unwrap(), -1.0);
        assert_eq!(
            parse_rfc3339("2000-01-01T00:00:00Z").unwrap(),
            946_684_800.0
        );
        // India +05:30, Chatham +12:45, Marquesas −09:30.
        assert_eq!(
            parse_rfc3339("2000-01-01T05:30:00+05:30").unwrap(),
            946_684_800.0
        );
        assert_eq!(
            parse_rfc3339("2000-01-01T12:45:00+12:45").unwrap(),
            946_684_800.0
        );
        assert_eq!(
            parse_rfc3339("1999-12-31T14:30:00-09:30").unwrap(),
            946_684_800.0
        );
        assert_eq!(
            parse_rfc3339("2000-01-01T23:59:00+23:59").unwrap(),
            946_684_800.0
        );
        // Leap days.
        assert_eq!(
            parse_rfc3339("2000-02-29T00:00:00Z").unwrap(),
            951_782_400.0
        );
        assert!(parse_rfc3339("2024-02-29T12:00:00Z").is_ok());
        assert!(parse_rfc3339("0000-01-01T00:00:00Z").is_ok());
        assert!(parse_rfc3339("9999-12-31T23:59:59Z").is_ok());
    }

    #[test]
    fn fractional_seconds() {
        let t = parse_rfc3339_timestamp("2003-10-17T19:30:30.25Z").unwrap();
        assert_eq!((t.unix_seconds, t.nanosecond), (1_066_419_030, 250_000_000));
        assert_eq!(t.unix_seconds_f64(), 1_066_419_030.25);
        let t = parse_rfc3339_timestamp("2003-10-17T19:30:30.123456789999Z").unwrap();
        assert_eq!(t.nanosecond, 123_456_789);
        let t = parse_rfc3339_timestamp("1969-12-31T23:59:59.5Z").unwrap();
        assert_eq!((t.unix_seconds, t.nanosecond), (-1, 500_000_000));
        assert_eq!(t.unix_seconds_f64(), -0.5);
        assert!(err("2003-10-17T19:30:30.Z").contains("digits after the decimal point"));
    }

    #[test]
    fn invalid_dates_name_the_value() {
        let r = err("2003-02-30T12:00:00Z");
        assert!(
            r.contains("day 30") && r.contains("2003-02") && r.contains("28"),
            "{r}"
        );
        let r = err("2003-02-29T12:00:00Z");
        assert!(r.contains("day 29"), "{r}");
        let r = err("1900-02-29T12:00:00Z");
        assert!(r.contains("day 29") && r.contains("1900-02"), "{r}");
        assert!(err("2003-04-31T00:00:00Z").contains("day 31"));
        assert!(err("2003-01-00T00:00:00Z").contains("day 00"));
        assert!(err("2003-13-01T00:00:00Z").contains("month 13"));
        assert!(err("2003-00-01T00:00:00Z").contains("month 00"));
    }

    #[test]
    fn out_of_range_fields_name_the_value() {
        assert!(err("2003-10-17T24:00:00Z").contains("hour 24"));
        assert!(err("2003-10-17T12:60:00Z").contains("minute 60"));
        assert!(err("2003-10-17T12:30:61Z").contains("second 61"));
        assert!(err("2003-10-17T23:59:60Z").contains("leap second"));
        assert!(err("2003-10-17T12:30:30+24:00").contains("offset hour 24"));
        assert!(err("2003-10-17T12:30:30-07:60").contains("offset minute 60"));
    }

    #[test]
    fn malformed_texts_are_refused() {
        assert!(err("2003-10-17T12:30:30").contains("missing offset"));
        assert!(err("2003-10-17").contains("a date alone"));
        assert!(err("2003-10-17T12:30").contains("':' after the minute"));
        assert!(err("03-10-17T12:30:30Z").contains("year must be 4 digits"));
        assert!(err("2003-1-17T12:30:30Z").contains("month must be 2 digits"));
        assert!(err("2003/10/17T12:30:30Z").contains("'-' after the year"));
        assert!(err("2003-10-17X12:30:30Z").contains("expected 'T'"));
        assert!(err("2003-10-17T12:30:30-0700").contains("':' in the offset"));
        assert!(err("2003-10-17T12:30:30-07").contains("':' in the offset"));
        assert!(err("2003-10-17T12:30:30UTC").contains("expected an offset"));
        assert!(err("2003-10-17T12:30:30Z ").contains("after the offset"));
        assert!(err(" 2003-10-17T12:30:30Z").contains("year"));
        assert!(err("").contains("the text ends"));
        assert!(err("2003-10-17T12:30:30+07:00[America/Denver]").contains("after the offset"));
        let r = err("２００３-10-17T12:30:30Z");
        assert!(r.contains("year") && r.contains("'２'"), "{r}");
        let r = err("2003-10-17T12:30:30−07:00");
        assert!(r.contains("'−'"), "{r}");
        let r = err("2003-10-17é12:30:30Z");
        assert!(r.contains("'é'"), "{r}");
        assert!(err("+2003-10-17T12:30:30Z").contains("year"));
    }

    #[test]
    fn formatting_round_trips() {
        for s in [
            "1970-01-01T00:00:00Z",
            "2003-10-17T19:30:30Z",
            "2000-02-29T23:59:59Z",
            "1969-12-31T23:59:59Z",
            "0000-03-01T00:00:00Z",
            "9999-12-31T23:59:59Z",
        ] {
            let t = parse_rfc3339_timestamp(s).unwrap();
            assert_eq!(format_rfc3339_utc(t.unix_seconds).as_deref(), Some(s));
        }
        assert_eq!(format_rfc3339_utc(i64::MIN / 2), None);
        // Every day of 1600..2400 round-trips through the calendar conversions.
        let start = days_from_civil(1600, 1, 1);
        let end = days_from_civil(2400, 1, 1);
        for z in start..end {
            let (y, m, d) = civil_from_days(z);
            assert_eq!(days_from_civil(y, m, d), z);
            assert!(d >= 1 && d as u32 <= days_in_month(y as u32, m as u32));
        }
    }
}
