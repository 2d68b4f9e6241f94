//! The measurement CSV of `aidnav filter`.
//!
//! - First line: a header. An optional column `time` (any unit, strictly
//!   increasing; default: the epoch index 0, 1, 2, …) and one column per
//!   measurement component, named as in the model file, in any order.
//! - One line per epoch; an empty cell means the component is missing at that
//!   epoch (a line with all cells empty is a pure prediction).
//! - Lines starting with `#` are comments. Numbers are decimal, `.` separated.
//!
//! Anything else — an unknown or missing column, a text in a number cell, a
//! non-finite value, a line with the wrong number of cells, time not strictly
//! increasing — is an error naming the file, the line and the column.

use std::path::Path;

use crate::error::{IoError, Result};

/// Default cap on the number of epochs read (documented in `--help`): about
/// 1.6 GB of cells at 20 components; raise it with `--max-epochs`.
pub const DEFAULT_MAX_EPOCHS: usize = 10_000_000;

/// Measurements read from a CSV file.
#[derive(Debug, Clone, PartialEq)]
pub struct MeasurementTable {
    /// Time tag per epoch.
    pub times: Vec<f64>,
    /// Per epoch, one optional value per model measurement component (model order).
    pub values: Vec<Vec<Option<f64>>>,
    /// Whether the file had a `time` column.
    pub has_time: bool,
}

impl MeasurementTable {
    /// Number of epochs.
    pub fn len(&self) -> usize {
        self.times.len()
    }

    /// Whether there are no epochs.
    pub fn is_empty(&self) -> bool {
        self.times.is_empty()
    }

    /// (time, values) per epoch, as the filter loop takes them.
    pub fn epochs(&self) -> impl Iterator<Item = (f64, &[Option<f64>])> {
        self.times
            .iter()
            .copied()
            .zip(self.values.iter().map(Vec::as_slice))
    }
}

/// Read a measurement CSV whose columns must be `names` (plus optional `time`).
pub fn read_measurements(
    path: &Path,
    names: &[String],
    max_epochs: usize,
) -> Result<MeasurementTable> {
    read_measurements_from(&crate::text::read_bytes(path)?, path, names, max_epochs)
}

/// [`read_measurements`] on the file's bytes; `origin` names it in
/// messages. A UTF-8 byte-order mark is stripped; invalid UTF-8 is an error
/// naming the line and byte.
pub fn read_measurements_from(
    bytes: &[u8],
    origin: &Path,
    names: &[String],
    max_epochs: usize,
) -> Result<MeasurementTable> {
    let text = crate::text::decode(bytes, origin)?;
    parse_measurements(text.as_bytes(), origin, names, max_epochs)
}

/// Parse measurement CSV from any reader; `origin` names it in errors
/// (prefer [`read_measurements_from`], which also strips a BOM and names the
/// line and byte of invalid UTF-8).
pub fn parse_measurements<R: std::io::Read>(
    reader: R,
    origin: &Path,
    names: &[String],
    max_epochs: usize,
) -> Result<MeasurementTable> {
    let data_err = |line: usize, column: &str, message: String| IoError::Data {
        path: origin.to_path_buf(),
        line,
        column: crate::text::excerpt(column),
        message,
    };
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(true)
        .comment(Some(b'#'))
        .flexible(true)
        .trim(csv::Trim::All)
        .from_reader(reader);
    let header = rdr
        .headers()
        .map_err(|e| data_err(1, "(header)", e.to_string()))?
        .clone();
    if header.is_empty() || (header.len() == 1 && header[0].is_empty()) {
        return Err(data_err(
            1,
            "(header)",
            "the file has no header line".into(),
        ));
    }
    let mut time_col = None;
    let mut slot = vec![usize::MAX; header.len()];
    for (c, h) in header.iter().enumerate() {
        if h == "time" {
            if time_col.is_some() {
                return Err(data_err(1, h, "appears twice".into()));
            }
            time_col = Some(c);
        } else if let Some(i) = names.iter().position(|n| n == h) {
            if slot.contains(&i) {
                return Err(data_err(1, h, "appears twice".into()));
            }
            slot[c] = i;
        } else {
            return Err(data_err(
                1,
                h,
                format!(
                    "unknown column; the model's measurements are {names:?} (plus an optional `time`)"
                ),
            ));
        }
    }
    if let Some(missing) = names
        .iter()
        .enumerate()
        .find(|(i, _)| !slot.contains(i))
        .map(|(_, n)| n)
    {
        return Err(data_err(
            1,
            missing,
            "column missing from the header".into(),
        ));
    }
    let mut table = MeasurementTable {
        times: Vec::new(),
        values: Vec::new(),
        has_time: time_col.is_some(),
    };
    let mut record = csv::StringRecord::new();
    loop {
        let more = rdr.read_record(&mut record).map_err(|e| {
            let line = e.position().map(|p| p.line() as usize).unwrap_or(0);
            data_err(line, "(row)", e.to_string())
        })?;
        if !more {
            break;
        }
        let line = record.position().map(|p| p.line() as usize).unwrap_or(0);
        if record.len() != header.len() {
            return Err(data_err(
                line,
                "(row)",
                format!("{} cells, the header has {}", record.len(), header.len()),
            ));
        }
        if table.len() >= max_epochs {
            return Err(IoError::Limit {
                path: origin.to_path_buf(),
                message: format!(
                    "more than {max_epochs} epochs; raise the limit with --max-epochs"
                ),
            });
        }
        let mut values = vec![None; names.len()];
        let mut time = table.len() as f64;
        for (c, cell) in record.iter().enumerate() {
            let col = &header[c];
            if Some(c) == time_col {
                time = parse_number(cell)
                    .map_err(|m| data_err(line, col, m))?
                    .ok_or_else(|| data_err(line, col, "empty time cell".into()))?;
                if let Some(&prev) = table.times.last()
                    && time <= prev
                {
                    return Err(data_err(
                        line,
                        col,
                        format!(
                            "time {} is not after the previous {}",
                            crate::text::num(time),
                            crate::text::num(prev)
                        ),
                    ));
                }
            } else {
                values[slot[c]] = parse_number(cell).map_err(|m| data_err(line, col, m))?;
            }
        }
        table.times.push(time);
        table.values.push(values);
    }
    Ok(table)
}

fn parse_number(cell: &str) -> std::result::Result<Option<f64>, String> {
    if cell.is_empty() {
        return Ok(None);
    }
    match cell.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(Some(v)),
        Ok(v) => Err(format!(
            "non-finite value {v}; leave the cell empty for a missing value"
        )),
        Err(_) => Err(format!(
            "\"{}\" is not a number",
            crate::text::excerpt(cell)
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<MeasurementTable> {
        let names = vec!["a".to_string(), "b".to_string()];
        parse_measurements(text.as_bytes(), Path::new("z.csv"), &names, 100)
    }

    #[test]
    fn reads_columns_in_any_order_with_missing_cells() {
        let t = parse("time,b,a\n# comment\n0.0,1,2\n0.5,,3\n1.0,,\n").unwrap();
        assert_eq!(t.times, vec![0.0, 0.5, 1.0]);
        assert_eq!(t.values[0], vec![Some(2.0), Some(1.0)]);
        assert_eq!(t.values[1], vec![Some(3.0), None]);
        assert_eq!(t.values[2], vec![None, None]);
    }

    #[test]
    fn time_defaults_to_the_epoch_index() {
        let t = parse("a,b\n1,2\n3,4\n").unwrap();
        assert!(!t.has_time);
        assert_eq!(t.times, vec![0.0, 1.0]);
    }

    #[test]
    fn errors_name_line_and_column() {
        let e = parse("time,a,b\n0,1,2\n1,x,2\n").unwrap_err().to_string();
        assert_eq!(e, "z.csv:3: column `a`: \"x\" is not a number");
        let e = parse("time,a,c\n").unwrap_err().to_string();
        assert!(e.starts_with("z.csv:1: column `c`: unknown column"), "{e}");
        let e = parse("time,a\n").unwrap_err().to_string();
        assert!(e.starts_with("z.csv:1: column `b`: column missing"), "{e}");
        let e = parse("time,a,b\n1,1,2\n1,1,2\n").unwrap_err().to_string();
        assert!(
            e.starts_with("z.csv:3: column `time`: time 1 is not after"),
            "{e}"
        );
        let e = parse("time,a,b\n1,1\n").unwrap_err().to_string();
        assert!(
            e.starts_with("z.csv:2: column `(row)`: 2 cells, the header has 3"),
            "{e}"
        );
        let e = parse("time,a,b\n1,inf,2\n").unwrap_err().to_string();
        assert!(e.contains("non-finite"), "{e}");
    }

    #[test]
    fn the_epoch_cap_is_an_error_not_a_truncation() {
        let mut text = String::from("a,b\n");
        for _ in 0..101 {
            text.push_str("1,2\n");
        }
        let e = parse(&text).unwrap_err().to_string();
        assert!(e.contains("more than 100 epochs"), "{e}");
    }

    #[test]
    fn bom_invalid_utf8_long_cells_and_large_numbers() {
        let names = vec!["a".to_string(), "b".to_string()];
        let from = |b: &[u8]| read_measurements_from(b, Path::new("z.csv"), &names, 100);
        // A BOM used to make the first column `\u{FEFF}time` unknown.
        let t = from("\u{FEFF}time,a,b\n0,1,2\n".as_bytes()).unwrap();
        assert!(t.has_time);
        let e = from(b"time,a,b\n0,1,\xFF\n").unwrap_err().to_string();
        assert!(
            e.starts_with("z.csv:2: column `(text)`: invalid UTF-8 at byte 13"),
            "{e}"
        );
        let e = from(format!("time,a,b\n0,1,{}\n", "x".repeat(10_000)).as_bytes())
            .unwrap_err()
            .to_string();
        assert!(e.len() < 200 && e.contains('…'), "{e}");
        let huge = format!("1{}", "0".repeat(308));
        let e = from(format!("time,a,b\n{huge},1,2\n0,1,2\n").as_bytes())
            .unwrap_err()
            .to_string();
        assert!(e.contains("time 0 is not after the previous 1e308"), "{e}");
    }
}
