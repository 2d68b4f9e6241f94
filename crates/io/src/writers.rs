//! Result writers: CSV observers for filter runs and `summary.json`.
//!
//! Every file is written atomically: under a temporary name in the same
//! directory (`.NAME.tmp`), then renamed to its final name once complete, so
//! a failed write (a full disk) never leaves a truncated file under a final
//! name. [`begin_outputs`] removes a stale `summary.json` before a job
//! writes, and jobs write `summary.json` last: a directory whose
//! `summary.json` is missing holds a run that did not finish.

use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use aidnav_estimation::{EpochRecord, Observer, SmoothedEpoch, nalgebra::Dyn};
use serde::Serialize;

use crate::error::{IoError, Result};

fn write_err(path: &Path, e: impl std::fmt::Display) -> IoError {
    IoError::Write {
        path: path.to_path_buf(),
        message: e.to_string(),
    }
}

/// Create `dir` (and parents) if needed.
pub fn ensure_dir(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| write_err(dir, e))
}

/// Create `dir` and remove a `summary.json` left by an earlier run, so a run
/// that fails leaves no summary of another run beside its outputs.
pub fn begin_outputs(dir: &Path) -> Result<()> {
    ensure_dir(dir)?;
    remove_if_present(&dir.join("summary.json")).map(|_| ())
}

/// Remove the file at `path` if there is one; whether there was.
fn remove_if_present(path: &Path) -> Result<bool> {
    match std::fs::remove_file(path) {
        Ok(()) => Ok(true),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(false),
        Err(e) => Err(write_err(path, e)),
    }
}

/// Remove the files named in `optional` from `dir` unless this run wrote
/// them (they are in `written`), and return one note per file removed.
///
/// A job writes some files only when asked (`smoothed.csv` when smoothing,
/// `covariance.csv`, the tuning's charts...). Without this, a file an
/// earlier run left in a reused directory would sit beside this run's
/// outputs as if this run had written it: `smoothed.csv` of a smoothed run
/// beside the solution of one that did not smooth. Only the job's own
/// file names are touched, after its other files are written and before
/// `summary.json`.
pub fn remove_stale_outputs(
    dir: &Path,
    optional: &[&str],
    written: &[PathBuf],
) -> Result<Vec<String>> {
    let mut notes = Vec::new();
    for name in optional {
        let path = dir.join(name);
        if written.contains(&path) {
            continue;
        }
        if remove_if_present(&path)? {
            notes.push(format!(
                "{}: removed, left by an earlier run (this run does not write it)",
                path.display()
            ));
        }
    }
    Ok(notes)
}

/// A file being written under a temporary name beside its final one; removed
/// when dropped before [`commit`](Self::commit).
#[derive(Debug)]
pub struct Staged {
    path: PathBuf,
    tmp: PathBuf,
    committed: bool,
}

impl Staged {
    /// The temporary name of `path`: `.NAME.tmp` in the same directory.
    pub fn new(path: &Path) -> Self {
        let name = path
            .file_name()
            .map_or_else(|| "output".into(), |n| n.to_string_lossy().into_owned());
        Self {
            path: path.to_path_buf(),
            tmp: path.with_file_name(format!(".{name}.tmp")),
            committed: false,
        }
    }

    /// Where to write until [`commit`](Self::commit).
    pub fn tmp(&self) -> &Path {
        &self.tmp
    }

    /// The final name.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Rename the complete temporary file to its final name.
    pub fn commit(mut self) -> Result<PathBuf> {
        std::fs::rename(&self.tmp, &self.path).map_err(|e| write_err(&self.path, e))?;
        self.committed = true;
        Ok(self.path.clone())
    }
}

impl Drop for Staged {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}

/// Write `bytes` to `path` atomically (temporary name, then rename).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let staged = Staged::new(path);
    std::fs::write(staged.tmp(), bytes).map_err(|e| write_err(path, e))?;
    staged.commit().map(|_| ())
}

/// A CSV file being written under its temporary name.
struct StagedCsv {
    staged: Staged,
    writer: csv::Writer<BufWriter<File>>,
}

impl StagedCsv {
    fn create(path: &Path) -> Result<Self> {
        let staged = Staged::new(path);
        let f = File::create(staged.tmp()).map_err(|e| write_err(path, e))?;
        Ok(Self {
            staged,
            writer: csv::Writer::from_writer(BufWriter::new(f)),
        })
    }

    fn write_record<I, T>(&mut self, record: I) -> Result<()>
    where
        I: IntoIterator<Item = T>,
        T: AsRef<[u8]>,
    {
        self.writer
            .write_record(record)
            .map_err(|e| write_err(self.staged.path(), e))
    }

    /// Flush, sync and rename to the final name.
    fn commit(self) -> Result<PathBuf> {
        let path = self.staged.path().to_path_buf();
        let file = self
            .writer
            .into_inner()
            .map_err(|e| write_err(&path, e.error()))?
            .into_inner()
            .map_err(|e| write_err(&path, e.error()))?;
        file.sync_all().map_err(|e| write_err(&path, e))?;
        self.staged.commit()
    }
}

/// Writes a filter run as it happens:
/// `estimates.csv` (epoch, time, each state, each σ),
/// `innovations.csv` (epoch, time, each innovation and its σ, NIS, dof, outcome)
/// and, when asked, `covariance.csv` (upper triangle of P per epoch).
/// Errors are kept and returned by [`finish`](Self::finish): an observer cannot fail mid-run.
/// Non-finite values found while writing are counted per column and
/// reported by [`warnings`](Self::warnings): ±inf anywhere, and NaN where a
/// value is never missing (states, σ, covariance). (NaN innovations and NIS
/// of a missing measurement are written as empty cells without a warning.)
/// The files get their final names only in [`finish`](Self::finish).
pub struct FilterCsvWriter {
    estimates: StagedCsv,
    innovations: StagedCsv,
    covariance: Option<StagedCsv>,
    states: Vec<String>,
    measurements: Vec<String>,
    error: Option<IoError>,
    row: Vec<String>,
    non_finite: NonFinite,
}

/// Non-finite values per (file, column): count and first epoch.
#[derive(Debug, Default)]
struct NonFinite(Vec<(String, String, usize, usize)>);

impl NonFinite {
    fn note(&mut self, file: &str, column: &str, epoch: usize) {
        match self
            .0
            .iter_mut()
            .find(|(f, c, _, _)| f == file && c == column)
        {
            Some(entry) => entry.2 += 1,
            None => self.0.push((file.into(), column.into(), 1, epoch)),
        }
    }

    fn warnings(&self) -> Vec<String> {
        self.0
            .iter()
            .map(|(file, column, count, first)| {
                format!(
                    "{file}: column `{column}`: {count} non-finite value{} (first at epoch {first})",
                    if *count == 1 { "" } else { "s" }
                )
            })
            .collect()
    }
}

impl FilterCsvWriter {
    /// Open the files in `dir`; names label the columns.
    pub fn create(
        dir: &Path,
        states: &[String],
        measurements: &[String],
        full_covariance: bool,
    ) -> Result<Self> {
        ensure_dir(dir)?;
        Ok(Self {
            estimates: StagedCsv::create(&dir.join("estimates.csv"))?,
            innovations: StagedCsv::create(&dir.join("innovations.csv"))?,
            covariance: if full_covariance {
                Some(StagedCsv::create(&dir.join("covariance.csv"))?)
            } else {
                None
            },
            states: states.to_vec(),
            measurements: measurements.to_vec(),
            error: None,
            row: Vec::new(),
            non_finite: NonFinite::default(),
        })
    }

    fn keep(&mut self, r: Result<()>) {
        if let Err(e) = r
            && self.error.is_none()
        {
            self.error = Some(e);
        }
    }

    /// One warning per column that received non-finite values, naming the
    /// file, the column, the count and the first epoch.
    pub fn warnings(&self) -> Vec<String> {
        self.non_finite.warnings()
    }

    /// Report the first error of the run, if any; else flush the files and
    /// give them their final names. On error no file keeps a final name.
    pub fn finish(mut self) -> Result<()> {
        if let Some(e) = self.error.take() {
            return Err(e);
        }
        let mut done: Vec<PathBuf> = Vec::new();
        let files = [
            Some(self.estimates),
            Some(self.innovations),
            self.covariance,
        ];
        for f in files.into_iter().flatten() {
            match f.commit() {
                Ok(p) => done.push(p),
                Err(e) => {
                    for p in &done {
                        let _ = std::fs::remove_file(p);
                    }
                    return Err(e);
                }
            }
        }
        Ok(())
    }
}

fn fmt(v: f64) -> String {
    if v.is_nan() {
        String::new()
    } else {
        format!("{v}")
    }
}

/// Append `v` as [`fmt`] writes it (`{}`, NaN as nothing) to `text`,
/// without allocating: [`push_display`].
fn push_number(text: &mut Vec<u8>, v: f64) {
    if !v.is_nan() {
        push_display(text, v);
    }
}

/// Append `v` (not NaN) exactly as `format!("{v}")` writes it: the
/// shortest digits that read back as `v`, laid out as `Display` lays them
/// out — plain decimal, never an exponent (`1e-7` is `0.0000001`, `1e300` a
/// 1 and 300 zeros), no trailing `.0`, `-0` for −0.0, `inf`/`-inf`.
///
/// The digits are zmij's (a Schubfach-family shortest printer, faster than
/// Ryū, which was about three times faster than `core::fmt`'s Grisu/Dragon;
/// float formatting was a tenth of `aidnav process`'s CPU).
/// Both give the shortest digit string that reads back as `v`, the one
/// nearest to `v`; they may differ only when two such strings are equally
/// near (Ryū takes the even last digit, `core::fmt` rounds the tie up, e.g.
/// 1234560000000000.25: `.2` and `.3`). Such a tie needs `v`'s exact
/// decimal expansion to be one digit longer than its shortest form, so at
/// most 18 significant digits, ending in 5 — a value with a short binary
/// fraction; those go to `core::fmt`.
/// `display_layout_equals_the_standard_library` checks the equality on
/// edge cases, on short binary fractions at every magnitude and on a
/// million random values.
pub fn push_display(text: &mut Vec<u8>, v: f64) {
    if !v.is_finite() {
        text.extend_from_slice(if v > 0.0 { b"inf" } else { b"-inf" });
        return;
    }
    let exact_digits = short_exact_decimal(v);
    let mut buffer = zmij::Buffer::new();
    let written = buffer.format_finite(v).as_bytes();
    if exact_digits.is_none() && !written.contains(&b'e') {
        // zmij's plain form (`-ddd.ddd`, `0.000ddd`, `ddd.0`) is Display's
        // but for the `.0` of an integer.
        text.extend_from_slice(written.strip_suffix(b".0").unwrap_or(written));
        return;
    }
    let (negative, written) = match written.split_first() {
        Some((b'-', rest)) => (true, rest),
        _ => (false, written),
    };
    // zmij writes `d.ddd`, `0.000ddd` or `d.ddde±xx`: the digits, where the
    // decimal point sits among them, and a power of ten.
    let (mantissa, exponent) = match written.iter().position(|&b| b == b'e') {
        Some(e) => (&written[..e], parse_exponent(&written[e + 1..])),
        None => (written, 0),
    };
    let mut digits = [0u8; 32];
    let mut count = 0;
    let mut before_point = mantissa.len();
    for (i, &b) in mantissa.iter().enumerate() {
        if b == b'.' {
            before_point = i;
        } else {
            digits[count] = b;
            count += 1;
        }
    }
    let leading = digits[..count].iter().take_while(|&&d| d == b'0').count();
    let mut significant = &digits[leading..count];
    while let [rest @ .., b'0'] = significant {
        significant = rest;
    }
    if exact_digits.is_some_and(|n| n != significant.len()) {
        // Shorter than the exact expansion: a tie is possible, and
        // `core::fmt` breaks it its own way. (As long as it, the shortest
        // digits are the exact expansion, whichever printer finds them.)
        use std::io::Write as _;
        // Writing into a Vec cannot fail.
        let _ = write!(text, "{v}");
        return;
    }
    // The decimal point lies `point` digits into `significant`.
    let point = before_point as i64 - leading as i64 + exponent;
    if negative {
        text.push(b'-');
    }
    let len = significant.len() as i64;
    if significant.is_empty() {
        text.push(b'0');
    } else if point <= 0 {
        text.extend_from_slice(b"0.");
        text.resize(text.len() + (-point) as usize, b'0');
        text.extend_from_slice(significant);
    } else if point < len {
        let (int, frac) = significant.split_at(point as usize);
        text.extend_from_slice(int);
        text.push(b'.');
        text.extend_from_slice(frac);
    } else {
        text.extend_from_slice(significant);
        text.resize(text.len() + (point - len) as usize, b'0');
    }
}

/// The number of significant digits of finite `v`'s exact decimal
/// expansion when `v` has a fractional part and that expansion has at most
/// 18 significant digits (where the shortest round-trip digits may have a
/// tie, see [`push_display`]); None otherwise. An integer cannot tie: its
/// rounding interval is narrower than the unit of any digit it could drop
/// and still read back. With `v = m 2^(−f)` (m odd, f > 0) the expansion is
/// the digits of `m 5^f` (odd: no trailing zero), more than 18 for f > 32
/// (5³³ > 10²³).
fn short_exact_decimal(v: f64) -> Option<usize> {
    let bits = v.to_bits();
    let biased = ((bits >> 52) & 0x7FF) as i64;
    let fraction = bits & ((1 << 52) - 1);
    let (mut m, mut e) = if biased == 0 {
        (fraction, -1074)
    } else {
        (fraction | (1 << 52), biased - 1075)
    };
    if m == 0 {
        return None;
    }
    let zeros = m.trailing_zeros();
    m >>= zeros;
    e += i64::from(zeros);
    if !(-32..0).contains(&e) {
        return None;
    }
    // m < 2⁵³ and 5³² < 2⁷⁵: the product fits in 128 bits.
    let exact = u128::from(m) * POWERS_OF_FIVE[(-e) as usize];
    let digits = exact.ilog10() as usize + 1;
    (digits <= 18).then_some(digits)
}

/// 5ᵏ for k = 0 … 32 ([`short_exact_decimal`]'s exact expansions).
const POWERS_OF_FIVE: [u128; 33] = {
    let mut p = [1_u128; 33];
    let mut k = 1;
    while k < 33 {
        p[k] = p[k - 1] * 5;
        k += 1;
    }
    p
};

/// The decimal exponent written after `e` (an optional sign, digits).
fn parse_exponent(bytes: &[u8]) -> i64 {
    let (sign, digits) = match bytes.split_first() {
        Some((b'-', rest)) => (-1, rest),
        Some((b'+', rest)) => (1, rest),
        _ => (1, bytes),
    };
    sign * digits
        .iter()
        .fold(0_i64, |e, &d| e * 10 + i64::from(d - b'0'))
}

/// Note `v` if it is non-finite (`missing_ok`: NaN is a missing value, not
/// noted).
fn note_non_finite(
    v: f64,
    non_finite: &mut NonFinite,
    file: &str,
    column: &str,
    epoch: usize,
    missing_ok: bool,
) {
    if v.is_infinite() || (v.is_nan() && !missing_ok) {
        non_finite.note(file, column, epoch);
    }
}

/// A number as a cell, noting a non-finite value (`missing_ok`: NaN is a
/// missing value, not noted).
fn cell(
    v: f64,
    non_finite: &mut NonFinite,
    file: &str,
    column: &str,
    epoch: usize,
    missing_ok: bool,
) -> String {
    note_non_finite(v, non_finite, file, column, epoch, missing_ok);
    fmt(v)
}

impl Observer for FilterCsvWriter {
    fn observe_init(&mut self, _states: usize, _measurements: usize) {
        let mut h = vec!["epoch".to_string(), "time".to_string()];
        h.extend(self.states.iter().cloned());
        h.extend(self.states.iter().map(|s| format!("sigma_{s}")));
        let r = self.estimates.write_record(&h);
        self.keep(r);
        let mut h = vec!["epoch".to_string(), "time".to_string()];
        h.extend(self.measurements.iter().map(|s| format!("innovation_{s}")));
        h.extend(
            self.measurements
                .iter()
                .map(|s| format!("sigma_innovation_{s}")),
        );
        h.extend(["nis", "dof", "outcome"].map(String::from));
        let r = self.innovations.write_record(&h);
        self.keep(r);
        if self.covariance.is_some() {
            let mut h = vec!["epoch".to_string(), "time".to_string()];
            for i in 0..self.states.len() {
                for j in i..self.states.len() {
                    h.push(format!("P_{}_{}", self.states[i], self.states[j]));
                }
            }
            if let Some(w) = &mut self.covariance {
                let r = w.write_record(&h);
                self.keep(r);
            }
        }
    }

    fn observe_epoch(&mut self, rec: &EpochRecord) {
        let k = rec.epoch;
        let nf = &mut self.non_finite;
        let row = &mut self.row;
        row.clear();
        row.push(k.to_string());
        row.push(format!("{}", rec.time));
        for (v, name) in rec.state.iter().zip(&self.states) {
            row.push(cell(*v, nf, "estimates.csv", name, k, false));
        }
        for (v, name) in rec.sigma.iter().zip(&self.states) {
            row.push(cell(
                *v,
                nf,
                "estimates.csv",
                &format!("sigma_{name}"),
                k,
                false,
            ));
        }
        let r1 = self.estimates.write_record(&*row);
        row.clear();
        row.push(k.to_string());
        row.push(format!("{}", rec.time));
        for (v, name) in rec.innovation.iter().zip(&self.measurements) {
            let column = format!("innovation_{name}");
            row.push(cell(*v, nf, "innovations.csv", &column, k, true));
        }
        for (v, name) in rec.innovation_sigma.iter().zip(&self.measurements) {
            let column = format!("sigma_innovation_{name}");
            row.push(cell(*v, nf, "innovations.csv", &column, k, true));
        }
        row.push(cell(rec.nis, nf, "innovations.csv", "nis", k, true));
        row.push(rec.dof.to_string());
        row.push(rec.outcome.as_str().to_string());
        let r2 = self.innovations.write_record(&*row);
        let mut r3 = Ok(());
        if let (Some(w), Some(cov)) = (&mut self.covariance, &rec.covariance) {
            row.clear();
            row.push(k.to_string());
            row.push(format!("{}", rec.time));
            for i in 0..cov.nrows() {
                for j in i..cov.ncols() {
                    let column = format!("P_{}_{}", self.states[i], self.states[j]);
                    row.push(cell(cov[(i, j)], nf, "covariance.csv", &column, k, false));
                }
            }
            r3 = w.write_record(&*row);
        }
        self.keep(r1);
        self.keep(r2);
        self.keep(r3);
    }
}

/// Write `smoothed.csv`: epoch, time, smoothed states and their σ.
pub fn write_smoothed(
    dir: &Path,
    states: &[String],
    times: &[f64],
    smoothed: &[SmoothedEpoch<Dyn>],
) -> Result<PathBuf> {
    let mut w = StagedCsv::create(&dir.join("smoothed.csv"))?;
    let mut h = vec!["epoch".to_string(), "time".to_string()];
    h.extend(states.iter().cloned());
    h.extend(states.iter().map(|s| format!("sigma_{s}")));
    w.write_record(&h)?;
    for (k, (t, s)) in times.iter().zip(smoothed).enumerate() {
        let mut row = vec![k.to_string(), format!("{t}")];
        row.extend(s.x.iter().map(|&v| fmt(v)));
        row.extend(s.p.diagonal().iter().map(|&v| fmt(v.max(0.0).sqrt())));
        w.write_record(&row)?;
    }
    w.commit()
}

/// Write a CSV with a header and numeric rows (NaN written as an empty cell),
/// atomically.
pub fn write_table(
    path: &Path,
    header: &[&str],
    rows: impl IntoIterator<Item = Vec<f64>>,
) -> Result<()> {
    write_table_noting_infinities(path, header, rows).map(|_| ())
}

/// [`write_table`], returning one warning per column that received ±inf
/// (naming the file, the column, the count and the first data row).
pub fn write_table_noting_infinities(
    path: &Path,
    header: &[&str],
    rows: impl IntoIterator<Item = Vec<f64>>,
) -> Result<Vec<String>> {
    write_rows(path, header, rows)
}

/// Bytes of formatted rows [`write_rows`] collects before one write to
/// the file: few system calls, and a bounded buffer however long the table
/// (256 KiB: each writer thread's buffer is fresh memory, and 1 MiB cost
/// the drive about 180 more page faults, 0.7 ms).
const TABLE_CHUNK_BYTES: usize = 1 << 18;

/// [`write_table_noting_infinities`] for rows of any slice type (e.g.
/// arrays: no allocation per row).
///
/// The same bytes as the `csv` crate writes (the header goes through it):
/// a data row's cells are numbers as [`push_display`] writes them, or
/// empty, which never need quotes, so a row is its cells joined by commas,
/// formatted straight into one buffer that is written in chunks of
/// 256 KiB; a row of no bytes is `""`, as the `csv` crate writes it.
pub fn write_rows<R: AsRef<[f64]>>(
    path: &Path,
    header: &[&str],
    rows: impl IntoIterator<Item = R>,
) -> Result<Vec<String>> {
    let name = path
        .file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    use std::io::Write as _;
    let mut non_finite = NonFinite::default();
    let staged = Staged::new(path);
    let mut file = File::create(staged.tmp()).map_err(|e| write_err(path, e))?;
    let mut text: Vec<u8> = Vec::with_capacity(TABLE_CHUNK_BYTES + (1 << 14));
    {
        let mut header_writer = csv::Writer::from_writer(&mut text);
        header_writer
            .write_record(header)
            .and_then(|()| header_writer.flush().map_err(csv::Error::from))
            .map_err(|e| write_err(path, e))?;
    }
    for (k, row) in rows.into_iter().enumerate() {
        let row = row.as_ref();
        check_row_length(path, row, header)?;
        let row_start = text.len();
        for (c, (&v, column)) in row.iter().zip(header).enumerate() {
            if c > 0 {
                text.push(b',');
            }
            note_non_finite(v, &mut non_finite, &name, column, k + 1, true);
            push_number(&mut text, v);
        }
        if text.len() == row_start {
            // A record of no bytes (no column, or one empty cell): the csv
            // crate writes it as `""`, so that it is not a blank line.
            text.extend_from_slice(b"\"\"");
        }
        text.push(b'\n');
        if text.len() >= TABLE_CHUNK_BYTES {
            file.write_all(&text).map_err(|e| write_err(path, e))?;
            text.clear();
        }
    }
    file.write_all(&text).map_err(|e| write_err(path, e))?;
    file.sync_all().map_err(|e| write_err(path, e))?;
    drop(file);
    staged.commit()?;
    Ok(non_finite
        .warnings()
        .into_iter()
        .map(|m| m.replace("(first at epoch", "(first at data row"))
        .collect())
}

/// A row must have one value per column.
fn check_row_length(path: &Path, row: &[f64], header: &[&str]) -> Result<()> {
    if row.len() != header.len() {
        return Err(write_err(
            path,
            format!("row of {} values for {} columns", row.len(), header.len()),
        ));
    }
    Ok(())
}

/// `summary.json`: the tool, its version, the command, the seed, the full
/// scenario echoed back, and the results as further top-level keys.
#[derive(Debug, Clone, Serialize)]
pub struct Summary {
    /// Always `"aidnav"`.
    pub tool: &'static str,
    /// Version of aidnav that wrote it.
    pub aidnav_version: String,
    /// The subcommand, e.g. `"filter"` or `"reproduce consistency"`.
    pub command: String,
    /// Master seed (null when the command draws no random numbers).
    pub seed: Option<u64>,
    /// The full scenario or model, as parsed (defaults filled in).
    pub scenario: serde_json::Value,
    /// Result keys, flattened to the top level.
    #[serde(flatten)]
    pub results: serde_json::Map<String, serde_json::Value>,
}

impl Summary {
    /// A summary for `command` of aidnav `version`.
    pub fn new(
        command: impl Into<String>,
        version: impl Into<String>,
        seed: Option<u64>,
        scenario: &impl Serialize,
    ) -> Self {
        Self {
            tool: "aidnav",
            aidnav_version: version.into(),
            command: command.into(),
            seed,
            scenario: serde_json::to_value(scenario).unwrap_or(serde_json::Value::Null),
            results: serde_json::Map::new(),
        }
    }

    /// Add a result under `key`.
    pub fn insert(&mut self, key: &str, value: impl Serialize) {
        let v = serde_json::to_value(value).unwrap_or(serde_json::Value::Null);
        self.results.insert(key.to_string(), v);
    }

    /// Write `dir/summary.json` (pretty-printed).
    pub fn write(&self, dir: &Path) -> Result<PathBuf> {
        ensure_dir(dir)?;
        let path = dir.join("summary.json");
        let text = serde_json::to_string_pretty(self).map_err(|e| write_err(&path, e))?;
        write_atomic(&path, (text + "\n").as_bytes())?;
        Ok(path)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn a_failed_table_write_leaves_no_file_under_a_final_name() {
        let dir = tempfile::tempdir().unwrap();
        // The final name is taken by a directory: the rename fails.
        std::fs::create_dir(dir.path().join("t.csv")).unwrap();
        let e = write_table(&dir.path().join("t.csv"), &["a"], vec![vec![1.0]]).unwrap_err();
        assert!(e.to_string().contains("t.csv: cannot write"), "{e}");
        assert_eq!(names(dir.path()), vec!["t.csv"]);
        assert!(dir.path().join("t.csv").is_dir());
        // A row of the wrong length half-way: nothing under the final name.
        let e = write_table(
            &dir.path().join("u.csv"),
            &["a"],
            vec![vec![1.0], vec![1.0, 2.0]],
        );
        assert!(e.is_err());
        assert_eq!(names(dir.path()), vec!["t.csv"]);
        // A good write gets its final name and leaves no temporary file.
        write_table(&dir.path().join("u.csv"), &["a"], vec![vec![1.0]]).unwrap();
        assert_eq!(names(dir.path()), vec!["t.csv", "u.csv"]);
    }

    /// Of the optional names, the files this run did not write are removed
    /// (one note each, in the given order); the ones it wrote, the missing
    /// ones and every other file stay.
    #[test]
    fn stale_optional_outputs_are_removed_and_noted() {
        let dir = tempfile::tempdir().unwrap();
        for name in ["a.csv", "b.svg", "kept.csv", "other.txt"] {
            std::fs::write(dir.path().join(name), name).unwrap();
        }
        let written = [dir.path().join("kept.csv")];
        let optional = ["b.svg", "missing.csv", "kept.csv", "a.csv"];
        let notes = remove_stale_outputs(dir.path(), &optional, &written).unwrap();
        assert_eq!(names(dir.path()), vec!["kept.csv", "other.txt"]);
        assert_eq!(notes.len(), 2, "{notes:?}");
        assert!(notes[0].contains("b.svg: removed"), "{notes:?}");
        assert!(notes[1].contains("a.csv: removed"), "{notes:?}");
        // Nothing left to remove: no notes.
        assert!(
            remove_stale_outputs(dir.path(), &optional, &written)
                .unwrap()
                .is_empty()
        );
    }

    /// The table writer's bytes are the `csv` crate's for the same cells:
    /// headers that need quotes, NaN (empty) and infinite cells, one and
    /// two columns, and a table longer than the writer's chunk.
    #[test]
    fn tables_are_written_as_the_csv_crate_writes_them() {
        let dir = tempfile::tempdir().unwrap();
        let reference = |header: &[&str], rows: &[Vec<f64>]| {
            let mut w = csv::Writer::from_writer(Vec::new());
            w.write_record(header).unwrap();
            for row in rows {
                w.write_record(row.iter().map(|&v| fmt(v))).unwrap();
            }
            w.into_inner().unwrap()
        };
        let mut next = crate::xorshift(0x9E37_79B9_7F4A_7C15);
        let headers: [&[&str]; 5] = [
            &["a"],
            &["time [s]", "x, \"quoted\""],
            &["δ (Cramér–Rao)", "", "line\nbreak", "d"],
            &["a", "b", "c", "d", "e", "f", "g", "h"],
            &[],
        ];
        for (h, header) in headers.iter().enumerate() {
            let rows: Vec<Vec<f64>> = (0..if h == 3 { 30_000 } else { 50 })
                .map(|_| {
                    (0..header.len())
                        .map(|_| match next() % 7 {
                            0 => f64::NAN,
                            1 => f64::INFINITY,
                            2 => -0.0,
                            3 => (next() % 1000) as f64,
                            _ => f64::from_bits(next()),
                        })
                        .collect()
                })
                .collect();
            let path = dir.path().join(format!("t{h}.csv"));
            write_table(&path, header, rows.clone()).unwrap();
            let written = std::fs::read(&path).unwrap();
            assert!(h != 3 || written.len() > TABLE_CHUNK_BYTES);
            assert!(written == reference(header, &rows), "table {h}");
        }
        assert_eq!(
            names(dir.path()),
            ["t0.csv", "t1.csv", "t2.csv", "t3.csv", "t4.csv"]
        );
    }

    #[test]
    fn infinities_in_a_table_are_named() {
        let dir = tempfile::tempdir().unwrap();
        let w = write_table_noting_infinities(
            &dir.path().join("t.csv"),
            &["a", "b"],
            vec![
                vec![1.0, f64::NAN],
                vec![f64::INFINITY, 2.0],
                vec![f64::NEG_INFINITY, 2.0],
            ],
        )
        .unwrap();
        assert_eq!(
            w,
            vec!["t.csv: column `a`: 2 non-finite values (first at data row 2)".to_string()]
        );
    }

    #[test]
    fn table_cells_are_written_as_display_writes_them() {
        let dir = tempfile::tempdir().unwrap();
        let values = [1.0, -0.0, 1e-7, 123_456.789, -2.5e300, f64::NAN, 0.1 + 0.2];
        let path = dir.path().join("t.csv");
        let header: Vec<String> = (0..values.len()).map(|c| format!("c{c}")).collect();
        let header: Vec<&str> = header.iter().map(String::as_str).collect();
        write_table(&path, &header, vec![values.to_vec(), values.to_vec()]).unwrap();
        let row = values
            .iter()
            .map(|v| {
                if v.is_nan() {
                    String::new()
                } else {
                    format!("{v}")
                }
            })
            .collect::<Vec<_>>()
            .join(",");
        assert_eq!(
            row,
            "1,-0,0.0000001,123456.789,-25".to_string()
                + &"0".repeat(299)
                + ",,0.30000000000000004"
        );
        assert_eq!(
            std::fs::read_to_string(&path).unwrap(),
            format!("{}\n{row}\n{row}\n", header.join(","))
        );
    }

    /// [`push_display`] against `format!("{v}")`, byte for byte: edge
    /// cases (zeros, subnormals, the extremes, integers, powers of ten and
    /// their neighbours across the range where zmij switches to an exponent,
    /// 1e±16 and beyond), short decimals as logs hold them, and a million
    /// random bit patterns over every exponent.
    #[test]
    fn display_layout_equals_the_standard_library() {
        let check = |v: f64| {
            if v.is_nan() {
                return;
            }
            let mut text = Vec::new();
            push_display(&mut text, v);
            assert_eq!(
                std::str::from_utf8(&text).unwrap(),
                format!("{v}"),
                "bits {:#018x}",
                v.to_bits()
            );
        };
        let mut edge = vec![
            0.0,
            -0.0,
            1.0,
            -1.0,
            0.1,
            0.5,
            0.3,
            0.1 + 0.2,
            5e-324,
            -5e-324,
            f64::MIN_POSITIVE,
            f64::MIN_POSITIVE - 5e-324,
            f64::MAX,
            f64::MIN,
            f64::EPSILON,
            f64::INFINITY,
            f64::NEG_INFINITY,
            9_007_199_254_740_992.0,
            9_007_199_254_740_993.0,
            123_456.789,
            1.752003261729e9,
            std::f64::consts::PI,
            // Ties between two shortest digit strings (`core::fmt` rounds
            // up), and exact short expansions that are the shortest digits.
            1_234_560_000_000_000.2,
            1_234_560_000_000_000.3,
            2_251_799_813_685_248.5,
            1_125_899_906_842_624.2,
            562_949_953_421_312.1,
            1_752_003_258.5,
            0.25,
            0.000_030_517_578_125,
        ];
        for e in -325..=308 {
            let p: f64 = format!("1e{e}").parse().unwrap();
            for v in [p, p * 1.5, p * 9.999, p * 123.456] {
                let bits = v.to_bits();
                edge.extend([
                    v,
                    f64::from_bits(bits.wrapping_add(1)),
                    f64::from_bits(bits.wrapping_sub(1)),
                ]);
            }
        }
        for k in 0..=2000 {
            edge.push(f64::from(k));
            edge.push(f64::from(k) * 1e15);
            edge.push(f64::from(k) / 1000.0);
            edge.push(-f64::from(k) / 7.0);
        }
        for v in edge {
            check(v);
            check(-v);
        }
        // SplitMix64: random bit patterns (every exponent, subnormals too)
        // and random short decimals.
        let mut state = 0x9E37_79B9_7F4A_7C15_u64;
        let mut next = move || {
            state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = state;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^ (z >> 31)
        };
        for _ in 0..1_000_000 {
            check(f64::from_bits(next()));
        }
        // Around the magnitudes of the ties (2⁴⁹ … 2⁵¹), and the ends of
        // the range sent to `core::fmt`: values with few binary digits
        // after the point.
        for _ in 0..300_000 {
            let r = next();
            let binary_exponent = 40 + (r % 20) as i32;
            let fraction_bits = (r >> 8) % 6;
            let m = (r >> 16) & ((1 << 20) - 1);
            let v = 2f64.powi(binary_exponent) + (m as f64) / f64::from(1 << fraction_bits);
            check(v);
            check(-v);
        }
        // Short binary fractions m 2^(−f) at every magnitude (the ties'
        // home): m of 1 to 53 bits, f up to 40.
        for _ in 0..300_000 {
            let r = next();
            let bits = 1 + (r % 53) as u32;
            let m = (next() >> (64 - bits)) | 1;
            let f = ((r >> 8) % 41) as i32;
            check(m as f64 * 2f64.powi(-f));
        }
        for _ in 0..200_000 {
            let r = next();
            let v = (r % 10_000_000) as f64 / 10f64.powi((r >> 40) as i32 % 12);
            check(v);
        }
        // Full-precision values over the magnitudes the printer writes
        // without an exponent (1e-7 … 1e17), as tables hold them.
        for _ in 0..300_000 {
            let r = next();
            let unit = (r >> 11) as f64 / (1u64 << 53) as f64;
            check(10f64.powf(-7.0 + 24.0 * unit));
        }
    }

    #[test]
    fn begin_outputs_removes_a_stale_summary() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("summary.json"), "{}").unwrap();
        begin_outputs(dir.path()).unwrap();
        assert!(names(dir.path()).is_empty());
    }
}
