//! TOML configuration files with errors a user can act on.
//!
//! Structs use `#[serde(deny_unknown_fields)]` so a misspelt key is an error,
//! and implement [`Validate`] for ranges serde cannot express. Both kinds of
//! error come back as [`IoError::Config`] with the file, the 1-based line and
//! the dotted key, e.g.
//! `scenario.toml:4: runs: 0 is out of range: allowed 1 ≤ runs ≤ 1000000`.

use std::fmt::Display;
use std::path::Path;

use serde::de::DeserializeOwned;

use crate::error::{IoError, Result};

/// A value out of its allowed range, found by [`Validate`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Invalid {
    /// Dotted key (`filter.policy.k`).
    pub key: String,
    /// The offending value, as text.
    pub value: String,
    /// The allowed range or set, as text.
    pub allowed: String,
}

impl Invalid {
    /// A new range violation.
    pub fn new(key: impl Into<String>, value: impl Display, allowed: impl Into<String>) -> Self {
        Self {
            key: key.into(),
            value: value.to_string(),
            allowed: allowed.into(),
        }
    }

    /// Prefix the key with a table name (`prefix.key`).
    pub fn within(mut self, prefix: &str) -> Self {
        self.key = format!("{prefix}.{}", self.key);
        self
    }
}

/// Range checks beyond what the types say.
pub trait Validate {
    /// `Ok` when every field is in its allowed range.
    fn validate(&self) -> std::result::Result<(), Invalid>;
}

/// Error unless `lo ≤ value ≤ hi` (and finite).
pub fn in_range(key: &str, value: f64, lo: f64, hi: f64) -> std::result::Result<(), Invalid> {
    if value.is_finite() && value >= lo && value <= hi {
        Ok(())
    } else {
        Err(Invalid::new(key, value, format!("{lo} ≤ {key} ≤ {hi}")))
    }
}

/// Error unless `value > 0` (and finite).
pub fn positive(key: &str, value: f64) -> std::result::Result<(), Invalid> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(Invalid::new(key, value, format!("{key} > 0 and finite")))
    }
}

/// [`positive`] for every (key, value) of a table; the error's key is
/// prefixed with the table's dotted name (e.g. `"model.imu"`).
pub fn all_positive(table: &str, pairs: &[(&str, f64)]) -> std::result::Result<(), Invalid> {
    for &(key, value) in pairs {
        positive(key, value).map_err(|e| e.within(table))?;
    }
    Ok(())
}

/// [`in_range`] for each `(key, value, lo, hi)` of a table, the key named
/// within `table` (top-level keys when `table` is empty).
pub fn all_in_range(
    table: &str,
    checks: &[(&str, f64, f64, f64)],
) -> std::result::Result<(), Invalid> {
    for &(key, value, lo, hi) in checks {
        in_range(key, value, lo, hi).map_err(
            |e| {
                if table.is_empty() { e } else { e.within(table) }
            },
        )?;
    }
    Ok(())
}

/// Error unless `value ≥ 0` (and finite).
pub fn non_negative(key: &str, value: f64) -> std::result::Result<(), Invalid> {
    if value.is_finite() && value >= 0.0 {
        Ok(())
    } else {
        Err(Invalid::new(key, value, format!("{key} ≥ 0 and finite")))
    }
}

/// Error unless `0 < value < 1`.
pub fn probability(key: &str, value: f64) -> std::result::Result<(), Invalid> {
    if value > 0.0 && value < 1.0 {
        Ok(())
    } else {
        Err(Invalid::new(key, value, format!("0 < {key} < 1")))
    }
}

/// Error unless `lo ≤ value ≤ hi` for integers.
pub fn count_in_range(
    key: &str,
    value: usize,
    lo: usize,
    hi: usize,
) -> std::result::Result<(), Invalid> {
    if (lo..=hi).contains(&value) {
        Ok(())
    } else {
        Err(Invalid::new(key, value, format!("{lo} ≤ {key} ≤ {hi}")))
    }
}

/// Read, parse and validate a TOML file. Returns the value and the file's text
/// (to echo it into `summary.json`).
pub fn load_toml<T: DeserializeOwned + Validate>(path: &Path) -> Result<(T, String)> {
    let text = std::fs::read_to_string(path).map_err(|reason| IoError::Read {
        path: path.to_path_buf(),
        reason,
    })?;
    let value = parse_toml(&text, path)?;
    Ok((value, text))
}

/// Parse and validate TOML text; `origin` names it in errors.
pub fn parse_toml<T: DeserializeOwned + Validate>(text: &str, origin: &Path) -> Result<T> {
    let value: T = toml::from_str(text).map_err(|e| {
        let (line, key) = match e.span() {
            Some(span) => locate_span(text, span.start),
            None => (0, String::from("(document)")),
        };
        let mut message = e.message().trim().to_string();
        if message.contains("did not match any variant") {
            message.push_str(" (see the file format in the documentation of this file type)");
        }
        IoError::Config {
            path: origin.to_path_buf(),
            line,
            key,
            message,
        }
    })?;
    value.validate().map_err(|inv| IoError::Config {
        path: origin.to_path_buf(),
        line: find_key_line(text, &inv.key).unwrap_or(0),
        message: format!("{} is out of range: allowed {}", inv.value, inv.allowed),
        key: inv.key,
    })?;
    Ok(value)
}

/// 1-based line of a byte offset and the dotted key written on that line
/// (or the table header above it when the line holds no `key =`).
fn locate_span(text: &str, offset: usize) -> (usize, String) {
    let offset = offset.min(text.len());
    let line_no = text[..offset].matches('\n').count() + 1;
    let mut table = String::new();
    let mut key_here = None;
    for (i, raw) in text.lines().enumerate() {
        let line = strip_comment(raw).trim();
        if i + 1 > line_no {
            break;
        }
        if let Some(h) = table_header(line) {
            table = h;
        } else if i + 1 == line_no {
            key_here = line.split_once('=').map(|(k, _)| unquote(k.trim()));
        }
    }
    let key = match (key_here, table.is_empty()) {
        (Some(k), true) => k,
        (Some(k), false) => format!("{table}.{k}"),
        (None, false) => table,
        (None, true) => String::from("(document)"),
    };
    (line_no, key)
}

/// The 1-based line where dotted `key` is assigned, by scanning tables and
/// `key =` lines (handles `[a]` + `b = …`, `a.b = …` and `a = { b = … }`).
pub fn find_key_line(text: &str, key: &str) -> Option<usize> {
    let mut table = String::new();
    let mut fallback = None;
    for (i, raw) in text.lines().enumerate() {
        let line = strip_comment(raw).trim();
        if let Some(h) = table_header(line) {
            table = h;
            if table == key {
                return Some(i + 1);
            }
            continue;
        }
        let Some((k, rest)) = line.split_once('=') else {
            continue;
        };
        let k = unquote(k.trim());
        let full = if table.is_empty() {
            k.clone()
        } else {
            format!("{table}.{k}")
        };
        if full == key {
            return Some(i + 1);
        }
        // Inline table: `policy = { kind = "huber", k = 0 }` holds `policy.k`.
        if key.starts_with(&format!("{full}.")) && rest.trim_start().starts_with('{') {
            fallback = fallback.or(Some(i + 1));
        }
        // The first segments match: remember the nearest enclosing assignment.
        if key.starts_with(&format!("{full}.")) || key.starts_with(&format!("{full}[")) {
            fallback = fallback.or(Some(i + 1));
        }
    }
    fallback
}

fn strip_comment(line: &str) -> &str {
    // Good enough for keys: a '#' inside a string on a key line is rare and
    // only affects the reported line, never the parse.
    match line.find('#') {
        Some(i) => &line[..i],
        None => line,
    }
}

fn table_header(line: &str) -> Option<String> {
    let l = line.trim();
    if l.starts_with("[[") && l.ends_with("]]") {
        Some(l[2..l.len() - 2].trim().to_string())
    } else if l.starts_with('[') && l.ends_with(']') && !l.contains('=') {
        Some(l[1..l.len() - 1].trim().to_string())
    } else {
        None
    }
}

fn unquote(k: &str) -> String {
    k.split('.')
        .map(|p| p.trim().trim_matches('"').trim_matches('\''))
        .collect::<Vec<_>>()
        .join(".")
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::Deserialize;

    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Inner {
        k: f64,
    }

    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Doc {
        runs: usize,
        inner: Inner,
    }

    impl Validate for Doc {
        fn validate(&self) -> std::result::Result<(), Invalid> {
            count_in_range("runs", self.runs, 1, 1000)?;
            positive("k", self.inner.k).map_err(|e| e.within("inner"))
        }
    }

    fn err(text: &str) -> String {
        parse_toml::<Doc>(text, Path::new("s.toml"))
            .unwrap_err()
            .to_string()
    }

    #[test]
    fn unknown_key_names_file_line_and_key() {
        let e = err("runs = 3\n\n[inner]\nk = 1.0\nkk = 2\n");
        assert!(
            e.starts_with("s.toml:5: inner.kk: unknown field `kk`"),
            "{e}"
        );
    }

    #[test]
    fn wrong_type_names_the_key() {
        let e = err("runs = \"many\"\n[inner]\nk = 1.0\n");
        assert!(e.starts_with("s.toml:1: runs: "), "{e}");
        assert!(e.contains("string"), "{e}");
    }

    #[test]
    fn out_of_range_names_the_allowed_range() {
        let e = err("runs = 0\n[inner]\nk = 1.0\n");
        assert_eq!(
            e,
            "s.toml:1: runs: 0 is out of range: allowed 1 ≤ runs ≤ 1000"
        );
        let e = err("runs = 2\n[inner]\n# comment\nk = -1.5\n");
        assert_eq!(
            e,
            "s.toml:4: inner.k: -1.5 is out of range: allowed k > 0 and finite"
        );
    }

    #[test]
    fn missing_key_is_reported() {
        let e = err("runs = 2\n");
        assert!(e.contains("missing field `inner`"), "{e}");
    }
}
