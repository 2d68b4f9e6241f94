//! Text helpers shared by the readers: UTF-8 decoding that names the line
//! and byte of an invalid sequence, a UTF-8 byte-order mark stripped, lines
//! split at LF, CR LF or a lone CR, short excerpts of quoted content, and
//! numbers printed readably (scientific notation when large or tiny), plus
//! calendar helpers.

use std::path::Path;

use crate::error::{IoError, Result};

/// The UTF-8 byte-order mark (some editors write it; it is no content).
const BOM: &[u8] = b"\xEF\xBB\xBF";

/// Longest excerpt of file content quoted in a message, in characters.
pub const EXCERPT_CHARS: usize = 80;

/// The bytes as text, without a leading UTF-8 BOM; invalid UTF-8 is an error
/// naming the line and the byte offset (from the file's start) of the first
/// invalid sequence.
///
/// ```
/// use std::path::Path;
/// let t = aidnav_io::text::decode(b"\xEF\xBB\xBFa,b\n", Path::new("x.csv")).unwrap();
/// assert_eq!(t, "a,b\n");
/// let e = aidnav_io::text::decode(b"a\nb\xFF\n", Path::new("x.csv")).unwrap_err();
/// assert!(e.to_string().contains("x.csv:2:") && e.to_string().contains("byte 3"));
/// ```
pub fn decode<'a>(bytes: &'a [u8], origin: &Path) -> Result<&'a str> {
    let (skip, body) = match bytes.strip_prefix(BOM) {
        Some(rest) => (BOM.len(), rest),
        None => (0, bytes),
    };
    std::str::from_utf8(body).map_err(|e| {
        let at = e.valid_up_to();
        let line = 1 + body[..at].iter().filter(|&&b| b == b'\n').count();
        IoError::Data {
            path: origin.to_path_buf(),
            line,
            column: "(text)".into(),
            message: format!(
                "invalid UTF-8 at byte {} (byte 0x{:02X}): the file must be UTF-8 or ASCII text",
                skip + at,
                body[at]
            ),
        }
    })
}

/// Read a whole file as bytes, or a read error naming it.
pub fn read_bytes(path: &Path) -> Result<Vec<u8>> {
    std::fs::read(path).map_err(|reason| IoError::Read {
        path: path.to_path_buf(),
        reason,
    })
}

/// Lines ended by LF, CR LF or a lone CR (old Mac files), without their
/// terminators; a final terminator does not start an empty line.
///
/// ```
/// let l: Vec<&str> = aidnav_io::text::lines("a\rb\r\nc\nd").collect();
/// assert_eq!(l, ["a", "b", "c", "d"]);
/// ```
pub fn lines(text: &str) -> impl Iterator<Item = &str> {
    let mut rest = text;
    std::iter::from_fn(move || {
        if rest.is_empty() {
            return None;
        }
        // Both terminators are ASCII: a byte search finds them (a char
        // pattern of two was a tenth of reading an IMU log; memchr's SIMD
        // search is about ten times a byte loop).
        match memchr::memchr2(b'\n', b'\r', rest.as_bytes()) {
            Some(i) => {
                let line = &rest[..i];
                let skip = if rest[i..].starts_with("\r\n") { 2 } else { 1 };
                rest = &rest[i + skip..];
                Some(line)
            }
            None => {
                let line = rest;
                rest = "";
                Some(line)
            }
        }
    })
}

/// Powers of ten exactly representable as f64.
const EXACT_POWERS_OF_TEN: [f64; 16] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15,
];

/// `s.parse::<f64>()` (the same value, bit for bit, and the same failures),
/// with a short path for the plain decimals logs are made of: an optional
/// sign, at most 15 digits and at most one point. Their digits form an
/// integer m < 10¹⁵ < 2⁵³ and the divisor 10^(digits after the point) is
/// exact, so m / 10ᵏ is one correctly rounded division — the correctly
/// rounded value of the decimal, which is what `parse` returns (Clinger's
/// fast path). Anything else (exponents, more digits, `inf`, stray bytes)
/// goes to `parse`.
///
/// ```
/// use aidnav_io::text::parse_f64;
/// assert_eq!(parse_f64("-0.671"), Some(-0.671));
/// assert_eq!(parse_f64("-0").map(f64::is_sign_negative), Some(true));
/// assert_eq!(parse_f64("1.5e3"), Some(1500.0));
/// assert_eq!(parse_f64("1,5"), None);
/// ```
pub fn parse_f64(s: &str) -> Option<f64> {
    parse_plain_decimal(s.as_bytes()).or_else(|| s.parse().ok())
}

/// The fast path of [`parse_f64`]: the value of a plain decimal (an
/// optional sign, 1 to 15 digits, at most one point, nothing else — no
/// space), exactly as `str::parse::<f64>` gives it; None for any other
/// text (which `parse` may still read, or refuse).
#[inline]
pub fn parse_plain_decimal(bytes: &[u8]) -> Option<f64> {
    plain_decimal_prefix(bytes).and_then(|(v, end)| (end == bytes.len()).then_some(v))
}

/// The plain decimal that starts `bytes` (as [`parse_plain_decimal`]
/// reads it, up to the first byte that is neither a digit nor its first
/// point) and the number of bytes it spans; None when that prefix is no
/// plain decimal (no digit, more than 15). One pass: the IMU reader
/// continues from the end it returns.
#[inline(always)]
pub(crate) fn plain_decimal_prefix(bytes: &[u8]) -> Option<(f64, usize)> {
    let negative = bytes.first() == Some(&b'-');
    let mut i = usize::from(negative || bytes.first() == Some(&b'+'));
    let start = i;
    let mut mantissa: u64 = 0;
    let mut point = None;
    while let Some(&b) = bytes.get(i) {
        let digit = b.wrapping_sub(b'0');
        if digit < 10 {
            // Wraps only past 19 digits, refused below.
            mantissa = mantissa.wrapping_mul(10).wrapping_add(u64::from(digit));
        } else if b == b'.' && point.is_none() {
            point = Some(i);
        } else {
            break;
        }
        i += 1;
    }
    let digits = i - start - usize::from(point.is_some());
    if digits == 0 || digits > 15 {
        return None;
    }
    // At most 15 digits: m < 10¹⁵ < 2⁵³ and 10^(after the point) exact.
    let after_point = point.map_or(0, |p| i - p - 1);
    let v = mantissa as f64 / EXACT_POWERS_OF_TEN[after_point];
    Some((if negative { -v } else { v }, i))
}

/// At most [`EXCERPT_CHARS`] characters of `s`, control characters escaped,
/// `…` marking a cut.
///
/// ```
/// let long = "x".repeat(1000);
/// let e = aidnav_io::text::excerpt(&long);
/// assert!(e.chars().count() <= 81 && e.ends_with('…'));
/// assert_eq!(aidnav_io::text::excerpt("a\tb"), "a\\tb");
/// ```
pub fn excerpt(s: &str) -> String {
    let mut out = String::new();
    for (n, c) in s.chars().enumerate() {
        if n >= EXCERPT_CHARS {
            out.push('…');
            break;
        }
        if c.is_control() || c == '\u{FEFF}' {
            out.extend(c.escape_default());
        } else {
            out.push(c);
        }
    }
    out
}

/// A number for a message: plain when moderate, scientific notation when
/// large or tiny (a 309-digit value prints as `1e308`).
///
/// ```
/// use aidnav_io::text::num;
/// assert_eq!(num(1.5), "1.5");
/// assert_eq!(num(1e308), "1e308");
/// assert_eq!(num(-2.5e-9), "-2.5e-9");
/// assert_eq!(num(0.0), "0");
/// ```
pub fn num(v: f64) -> String {
    let a = v.abs();
    if v.is_finite() && a != 0.0 && !(1e-4..1e9).contains(&a) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

/// Days in a month of the proleptic Gregorian calendar (0 for a month
/// outside 1–12).
pub fn days_in_month(year: i64, month: i64) -> i64 {
    match month {
        1 | 3 | 5 | 7 | 8 | 10 | 12 => 31,
        4 | 6 | 9 | 11 => 30,
        2 if (year % 4 == 0 && year % 100 != 0) || year % 400 == 0 => 29,
        2 => 28,
        _ => 0,
    }
}

/// Whether `year-month-day` is a calendar date (no 30 February, no 31 April).
///
/// ```
/// use aidnav_io::text::is_date;
/// assert!(is_date(2024, 2, 29) && !is_date(2025, 2, 29) && !is_date(2025, 4, 31));
/// ```
pub fn is_date(year: i64, month: i64, day: i64) -> bool {
    day >= 1 && day <= days_in_month(year, month)
}

/// Days from 1970-01-01 to a proleptic Gregorian date (Howard Hinnant's
/// algorithm).
pub fn days_from_civil(y: i64, m: i64, d: i64) -> i64 {
    let y = if m <= 2 { y - 1 } else { y };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let mp = (m + 9) % 12;
    let doy = (153 * mp + 2) / 5 + d - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    era * 146_097 + doe - 719_468
}

/// The date of a day count since 1970-01-01 (inverse of [`days_from_civil`]).
pub fn civil_from_days(z: i64) -> (i64, i64, i64) {
    let z = z + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let y = yoe + era * 400;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    (if m <= 2 { y + 1 } else { y }, m, d)
}

/// GPS week 0 began 1980-01-06 00:00:00 GPST: this many seconds after
/// 1970-01-01 on the GPST-since-1970 scale of every reader.
pub const GPS_EPOCH_1970_S: f64 = 315_964_800.0;

/// Seconds in a GPS week.
pub const WEEK_S: f64 = 604_800.0;

/// GPS − UTC \[s\] from each date on (IERS Bulletin C; 18 s since 2017-01-01,
/// no leap second announced up to the time of writing).
const LEAP_SECONDS: [((i64, i64, i64), f64); 18] = [
    ((1981, 7, 1), 1.0),
    ((1982, 7, 1), 2.0),
    ((1983, 7, 1), 3.0),
    ((1985, 7, 1), 4.0),
    ((1988, 1, 1), 5.0),
    ((1990, 1, 1), 6.0),
    ((1991, 1, 1), 7.0),
    ((1992, 7, 1), 8.0),
    ((1993, 7, 1), 9.0),
    ((1994, 7, 1), 10.0),
    ((1996, 1, 1), 11.0),
    ((1997, 7, 1), 12.0),
    ((1999, 1, 1), 13.0),
    ((2006, 1, 1), 14.0),
    ((2009, 1, 1), 15.0),
    ((2012, 7, 1), 16.0),
    ((2015, 7, 1), 17.0),
    ((2017, 1, 1), 18.0),
];

/// GPS − UTC \[s\] on the UTC day `days` since 1970-01-01 (0 before 1981-07-01,
/// the value of the last table entry after it): GPST = UTC + this.
///
/// ```
/// use aidnav_io::text::{days_from_civil, gps_minus_utc_s};
/// assert_eq!(gps_minus_utc_s(days_from_civil(2016, 12, 31)), 17.0);
/// assert_eq!(gps_minus_utc_s(days_from_civil(2025, 8, 28)), 18.0);
/// ```
pub fn gps_minus_utc_s(days: i64) -> f64 {
    LEAP_SECONDS
        .iter()
        .rev()
        .find(|((y, m, d), _)| days >= days_from_civil(*y, *m, *d))
        .map_or(0.0, |&(_, s)| s)
}

/// Seconds since 1970-01-01 as `YYYY-MM-DD hh:mm:ss.sss` (the scale is kept:
/// GPST in, GPST out); values too large for a date are printed as seconds.
///
/// ```
/// assert_eq!(aidnav_io::text::date_time(86_400.5), "1970-01-02 00:00:00.500");
/// ```
pub fn date_time(seconds: f64) -> String {
    if !seconds.is_finite() || seconds.abs() > 1e13 {
        return format!("{} s", num(seconds));
    }
    let ms = (seconds * 1000.0).round() as i64;
    let days = ms.div_euclid(86_400_000);
    let rest = ms.rem_euclid(86_400_000);
    let (y, m, d) = civil_from_days(days);
    format!(
        "{y:04}-{m:02}-{d:02} {:02}:{:02}:{:02}.{:03}",
        rest / 3_600_000,
        rest / 60_000 % 60,
        rest / 1000 % 60,
        rest % 1000
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn civil_round_trips() {
        for z in [-800_000, -1, 0, 1, 20_000, 59, 60, 11_016, 2_932_896] {
            let (y, m, d) = civil_from_days(z);
            assert!(is_date(y, m, d));
            assert_eq!(days_from_civil(y, m, d), z);
        }
    }

    #[test]
    fn invalid_utf8_names_line_and_byte_after_a_bom() {
        let e = decode(b"\xEF\xBB\xBFab\ncd\n\xC3(", Path::new("f"))
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("f:3: column `(text)`: invalid UTF-8 at byte 9"),
            "{e}"
        );
    }

    /// The short path against `str::parse`, bit for bit, on decimals of
    /// every length and sign, and on what it hands over.
    #[test]
    fn parse_f64_equals_std_parse() {
        let mut next = crate::xorshift(0x9E37_79B9_7F4A_7C15);
        let mut cases: Vec<String> = [
            "0",
            "-0",
            "+0",
            "0.",
            ".5",
            "-.5",
            "1.",
            ".",
            "-",
            "+",
            "",
            "1e3",
            "1.5E-7",
            "inf",
            "-inf",
            "NaN",
            "1.2.3",
            " 1",
            "1 ",
            "--1",
            "0x10",
            "123456789012345",
            "1234567890123456",
            "0.000000000000001",
            "0.0000000000000001",
            "9007199254740993",
            "000000000000001",
            "0000000000000001",
            "-000.000000000001",
            "+.",
            "-.",
            "-0.",
            "1..",
            ".1.",
            "5e",
            "1_0",
            "\u{0661}",
            "1\u{a0}",
            "999999999999999",
            "9999999999999999",
            "99999999999999.9",
            "0.999999999999999",
            "4.9e-324",
            "2.2250738585072011e-308",
            "1.7976931348623157e308",
            "1e309",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        for _ in 0..20_000 {
            let r = next();
            let digits = 1 + (r % 17) as usize;
            let mut s = String::new();
            match (r >> 8) % 3 {
                0 => s.push('-'),
                1 => s.push('+'),
                _ => {}
            }
            let point = ((r >> 16) % (digits as u64 + 2)) as usize;
            for d in 0..digits {
                if d == point {
                    s.push('.');
                }
                s.push(char::from(b'0' + ((next() % 10) as u8)));
            }
            cases.push(s);
        }
        for s in &cases {
            let ours = parse_f64(s).map(f64::to_bits);
            let std = s.parse::<f64>().ok().map(f64::to_bits);
            assert_eq!(ours, std, "`{s}`");
            // The fast path answers only for what `parse` reads, with its
            // bits, and answers for every plain decimal of ≤ 15 digits.
            let plain = parse_plain_decimal(s.as_bytes()).map(f64::to_bits);
            if plain.is_some() {
                assert_eq!(plain, std, "`{s}`");
            }
            let body = s.strip_prefix(['-', '+']).unwrap_or(s);
            let digits = body.bytes().filter(u8::is_ascii_digit).count();
            let is_plain = (1..=15).contains(&digits)
                && body.bytes().all(|b| b.is_ascii_digit() || b == b'.')
                && body.bytes().filter(|&b| b == b'.').count() <= 1;
            assert_eq!(plain.is_some(), is_plain, "`{s}`");
        }
    }

    #[test]
    fn cr_only_text_has_lines() {
        assert_eq!(lines("a\r\rb\r").collect::<Vec<_>>(), ["a", "", "b"]);
        assert_eq!(lines("").count(), 0);
    }
}
