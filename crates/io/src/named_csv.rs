//! What aidnav's named-column CSVs share (the generic GNSS, wheel-speed and
//! barometer CSVs): the header of known column names, the forms a quantity
//! may take (all of a form's columns or none, one form per quantity), the
//! time forms, the cells of a row as checked numbers, and the reading loop
//! (blank and `#` lines skipped, a truncated last line skipped with a
//! warning, strictly increasing time, at least one row).

use std::path::Path;

use aidnav_sensors::Timed;

use crate::error::{IoError, Result};
use crate::rtklib::{data_error, truncated_last_line};
use crate::text::{GPS_EPOCH_1970_S, WEEK_S, decode, excerpt, gps_minus_utc_s, num};

/// Latest GPST accepted, seconds since 1970 (2200-01-01): a larger value is
/// milliseconds or another epoch.
const MAX_GPST_S: f64 = 7_258_118_400.0;

/// The header row: its column names, each known and given once.
pub(crate) struct Header<'a> {
    /// The file.
    pub path: &'a Path,
    /// Its 1-based line.
    pub line: usize,
    /// The names, in file order.
    pub names: Vec<String>,
}

impl<'a> Header<'a> {
    /// The names of `header`; every one in `known`, none twice.
    pub fn parse(path: &'a Path, line: usize, header: &str, known: &[&str]) -> Result<Self> {
        let names: Vec<String> = header.split(',').map(|s| s.trim().to_string()).collect();
        let h = Self { path, line, names };
        for (i, n) in h.names.iter().enumerate() {
            if !known.contains(&n.as_str()) {
                return Err(h.error(
                    &excerpt(n),
                    format!(
                        "unknown column{} (column {}); the known columns are: {}",
                        if n.is_empty() {
                            " with an empty name (a trailing comma?)"
                        } else {
                            ""
                        },
                        i + 1,
                        known.join(", ")
                    ),
                ));
            }
            if h.names[..i].contains(n) {
                return Err(h.error(n, format!("named twice (column {})", i + 1)));
            }
        }
        Ok(h)
    }

    /// An error at the header's line.
    pub fn error(&self, column: &str, message: impl Into<String>) -> IoError {
        data_error(self.path, self.line, column, message)
    }

    /// The index of column `name`.
    pub fn find(&self, name: &str) -> Option<usize> {
        self.names.iter().position(|x| x == name)
    }

    /// The columns of a form: all present (Some), none (None), or an error
    /// naming the missing ones.
    pub fn group(&self, what: &str, cols: &[&str]) -> Result<Option<Vec<usize>>> {
        let found: Vec<Option<usize>> = cols.iter().map(|c| self.find(c)).collect();
        if found.iter().all(Option::is_none) {
            return Ok(None);
        }
        let missing: Vec<&str> = cols
            .iter()
            .zip(&found)
            .filter(|(_, f)| f.is_none())
            .map(|(c, _)| *c)
            .collect();
        if let Some(first) = missing.first() {
            return Err(self.error(
                first,
                format!(
                    "column missing: {what} needs {} (missing: {})",
                    cols.join(", "),
                    missing.join(", ")
                ),
            ));
        }
        Ok(Some(found.into_iter().flatten().collect()))
    }

    /// At most one of `forms` (name, columns when given) is given.
    pub fn one_of(&self, quantity: &str, forms: &[(&str, Option<&Vec<usize>>)]) -> Result<()> {
        let given: Vec<&str> = forms
            .iter()
            .filter(|(_, f)| f.is_some())
            .map(|(n, _)| *n)
            .collect();
        if given.len() > 1 {
            return Err(self.error(
                "(header)",
                format!(
                    "{quantity} given twice ({}): keep one form",
                    given.join(" and ")
                ),
            ));
        }
        Ok(())
    }

    /// The one of the columns `forms` (alternative forms of `quantity`)
    /// the header has: (form, column); an error when it has none or two.
    pub fn one_column(&self, quantity: &str, forms: &[&str]) -> Result<(usize, usize)> {
        let found: Vec<(usize, usize)> = forms
            .iter()
            .enumerate()
            .filter_map(|(k, n)| self.find(n).map(|c| (k, c)))
            .collect();
        match found.as_slice() {
            [] => Err(self.error(
                &format!("({quantity})"),
                format!("no {quantity} column: give one of {}", forms.join(", ")),
            )),
            [one] => Ok(*one),
            [a, b, ..] => Err(self.error(
                "(header)",
                format!(
                    "the {quantity} given twice ({} and {}): keep one form",
                    forms[a.0], forms[b.0]
                ),
            )),
        }
    }
}

/// One data row's cells and where they are.
pub(crate) struct Row<'a> {
    pub path: &'a Path,
    pub line: usize,
    pub cells: &'a [&'a str],
    pub names: &'a [String],
}

impl Row<'_> {
    fn name(&self, c: usize) -> &str {
        self.names.get(c).map_or("(column)", String::as_str)
    }

    /// An error at column `c` of this row.
    pub fn error(&self, c: usize, message: impl Into<String>) -> IoError {
        data_error(self.path, self.line, self.name(c), message)
    }

    /// The text of column `c` ("" beyond the row).
    pub fn cell(&self, c: usize) -> &str {
        self.cells.get(c).copied().unwrap_or("")
    }

    /// The finite number in column `c`.
    pub fn number(&self, c: usize) -> Result<f64> {
        let s = self.cell(c);
        if s.is_empty() {
            return Err(self.error(c, "empty: a value is needed"));
        }
        let v: f64 = s
            .parse()
            .map_err(|_| self.error(c, format!("`{}` is not a number", excerpt(s))))?;
        if !v.is_finite() {
            return Err(self.error(c, format!("`{}` is not finite", excerpt(s))));
        }
        Ok(v)
    }

    /// The number in column `c`, within `[lo, hi]`.
    pub fn bounded(&self, c: usize, lo: f64, hi: f64, unit: &str, why: &str) -> Result<f64> {
        let v = self.number(c)?;
        match crate::limits::outside(v, lo, hi, unit, why) {
            Some(m) => Err(self.error(c, m)),
            None => Ok(v),
        }
    }

    /// A σ in column `c`: > 0 and at most `max`.
    pub fn sigma(&self, c: usize, max: f64, unit: &str) -> Result<f64> {
        let v = self.number(c)?;
        if v <= 0.0 || v > max {
            return Err(self.error(
                c,
                format!(
                    "σ = {} {unit}: must be > 0 and ≤ {} {unit}",
                    num(v),
                    num(max)
                ),
            ));
        }
        Ok(v)
    }

    /// The σ in optional column `c`: None when there is no such column or
    /// its cell is empty.
    pub fn optional_sigma(&self, c: Option<usize>, max: f64, unit: &str) -> Result<Option<f64>> {
        match c {
            Some(c) if !self.cell(c).is_empty() => self.sigma(c, max, unit).map(Some),
            _ => Ok(None),
        }
    }
}

/// How the time is given.
#[derive(Debug, Clone, Copy)]
pub(crate) enum TimeForm {
    /// `time_s`: seconds as written, on the scale of the run's other files.
    Seconds(usize),
    /// `gpst_s`: GPST seconds since 1970.
    Gpst(usize),
    /// `gps_week`, `tow_s`.
    WeekTow(usize, usize),
    /// `utc`: ISO 8601.
    Utc(usize),
}

impl TimeForm {
    /// The time form of `h`: `gpst_s`, `gps_week` + `tow_s` or `utc`, and
    /// `time_s` too when `seconds` (the aiding CSVs).
    pub fn parse(h: &Header, seconds: bool) -> Result<Self> {
        let plain = if seconds {
            h.group("time in seconds", &["time_s"])?
        } else {
            None
        };
        let gpst = h.group("GPST time", &["gpst_s"])?;
        let week_tow = h.group("GPS week time", &["gps_week", "tow_s"])?;
        let utc = h.group("UTC time", &["utc"])?;
        let mut forms = Vec::with_capacity(4);
        if seconds {
            forms.push(("time_s", plain.as_ref()));
        }
        forms.extend([
            ("gpst_s", gpst.as_ref()),
            ("gps_week + tow_s", week_tow.as_ref()),
            ("utc", utc.as_ref()),
        ]);
        h.one_of("the time", &forms)?;
        let at = |v: &[usize], k: usize| v.get(k).copied().unwrap_or(0);
        Ok(match (&plain, &gpst, &week_tow, &utc) {
            (Some(s), _, _, _) => Self::Seconds(at(s, 0)),
            (_, Some(g), _, _) => Self::Gpst(at(g, 0)),
            (_, _, Some(w), _) => Self::WeekTow(at(w, 0), at(w, 1)),
            (_, _, _, Some(u)) => Self::Utc(at(u, 0)),
            _ => {
                return Err(h.error(
                    "(time)",
                    format!(
                        "no time column: give {}gpst_s, or gps_week and tow_s, or utc",
                        if seconds { "time_s, " } else { "" }
                    ),
                ));
            }
        })
    }

    /// The column reported for a time error.
    pub fn column(&self) -> usize {
        match *self {
            Self::Seconds(c) | Self::Gpst(c) | Self::Utc(c) | Self::WeekTow(c, _) => c,
        }
    }

    /// A time of this form for a message.
    pub fn show(&self, time_s: f64) -> String {
        match self {
            Self::Seconds(_) => format!("{} s", num(time_s)),
            _ => format!("{} GPST", crate::text::date_time(time_s)),
        }
    }

    /// The row's time: GPST seconds since 1970 (`time_s`: as written).
    pub fn time(&self, row: &Row) -> Result<f64> {
        match *self {
            Self::Seconds(c) => row.number(c),
            Self::Gpst(c) => row.bounded(
                c,
                GPS_EPOCH_1970_S,
                MAX_GPST_S,
                "s",
                "GPST seconds since 1970 from 1980-01-06 (GPS time began) to 2200; seconds of week go in tow_s with gps_week",
            ),
            Self::WeekTow(w, t) => {
                let week = row.bounded(w, 0.0, 9999.0, "", "GPS weeks since 1980-01-06")?;
                if week.fract() != 0.0 {
                    return Err(row.error(w, format!("{} is not a whole week", num(week))));
                }
                let tow = row.number(t)?;
                if !(0.0..WEEK_S).contains(&tow) {
                    return Err(row.error(
                        t,
                        format!("{} s is outside a week's [0, 604800) s", num(tow)),
                    ));
                }
                Ok(GPS_EPOCH_1970_S + week * WEEK_S + tow)
            }
            Self::Utc(c) => {
                let s = row.cell(c);
                let (utc_s, days) =
                    crate::generic_gnss::parse_iso8601(s).map_err(|m| row.error(c, m))?;
                Ok(utc_s + gps_minus_utc_s(days))
            }
        }
    }
}

/// Read a named-column CSV: the header resolved by `layout` (which also
/// gives its time form), each data row turned into a record by `record`;
/// the records and the warnings (a truncated last line).
pub(crate) fn read_table<L, T: Timed>(
    bytes: &[u8],
    path: &Path,
    known: &[&str],
    layout: impl FnOnce(&Header) -> Result<(L, TimeForm)>,
    mut record: impl FnMut(&L, &Row, f64) -> Result<T>,
) -> Result<(Vec<T>, Vec<String>)> {
    let text = decode(bytes, path)?;
    let mut lines = crate::text::lines(text)
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
    let Some((header_line, header)) = lines.next() else {
        return Err(data_error(
            path,
            0,
            "(header)",
            format!(
                "no header row: the first line must name the columns ({})",
                known.join(", ")
            ),
        ));
    };
    let header = Header::parse(path, header_line, header, known)?;
    let (layout, time_form) = layout(&header)?;
    let width = header.names.len();
    let rows: Vec<(usize, &str)> = lines.collect();
    let mut out: Vec<T> = Vec::with_capacity(rows.len());
    let mut warnings = Vec::new();
    for (k, &(line, row)) in rows.iter().enumerate() {
        let cells: Vec<&str> = row.split(',').map(str::trim).collect();
        let n = cells.len();
        if n != width {
            if k + 1 == rows.len() && n < width {
                let what = format_args!("{n} of {width} cells");
                warnings.push(truncated_last_line(path, line, what));
                continue;
            }
            let message = format!("{n} cells, the header (line {header_line}) has {width}");
            return Err(data_error(path, line, "(line)", message));
        }
        let row = Row {
            path,
            line,
            cells: &cells,
            names: &header.names,
        };
        let time_s = time_form.time(&row)?;
        let item = record(&layout, &row, time_s)?;
        if let Some(prev) = out.last()
            && item.time_s() <= prev.time_s()
        {
            return Err(row.error(
                time_form.column(),
                format!(
                    "time {} does not increase (previous row {})",
                    time_form.show(item.time_s()),
                    time_form.show(prev.time_s())
                ),
            ));
        }
        out.push(item);
    }
    if out.is_empty() {
        return Err(data_error(
            path,
            header_line,
            "(file)",
            "no data rows after the header",
        ));
    }
    Ok((out, warnings))
}
