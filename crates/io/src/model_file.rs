//! The linear-model file of `aidnav filter`.
//!
//! ```toml
//! # x_k = Φ x_{k−1} + w,  z_k = H x_k + v,  w ~ N(0, Q), v ~ N(0, R), x_0 ~ N(x0, P0)
//! states = ["position", "velocity"]     # optional; default x1 … xn
//! measurements = ["position"]           # optional; default z1 … zm; = CSV column names
//! phi = [[1.0, 1.0], [0.0, 1.0]]        # n×n, rows
//! q   = [[0.0033, 0.005], [0.005, 0.01]]  # n×n, or a diagonal: [0.1, 0.2]
//! h   = [[1.0, 0.0]]                    # m×n
//! r   = [4.0]                           # m×m, or a diagonal
//! x0  = [0.0, 0.0]                      # n
//! p0  = [100.0, 10.0]                   # n×n, or a diagonal
//!
//! [filter]                              # optional, defaults shown
//! update = "batch"                      # "batch" or "sequential" (needs diagonal R)
//! covariance_update = "joseph"          # "joseph" or "standard"
//! policy = { kind = "none" }            # or { kind = "chi2_gate", probability = 0.999 }
//!                                       # or { kind = "huber", k = 1.345 }
//! ```
//!
//! (x0, P0) is the prior at the *first* epoch of the measurement file; each
//! later epoch is predicted with (Φ, Q) from the one before.

use std::path::Path;

use aidnav_estimation::{
    CovarianceUpdate, EstimationError, LinearGaussianModel, Matrix, PolicyChoice, RunOptions,
    UpdateMethod,
};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

use crate::config::{Invalid, Validate, find_key_line, load_toml, positive, probability};
use crate::error::{IoError, Result};

/// Upper bound on the number of states or measurement components in a model
/// file: guards against a typo allocating gigabytes (a 10 000-state P is 800 MB).
pub const MAX_MODEL_DIM: usize = 2000;

/// A matrix written as rows, or as its diagonal.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum MatrixSpec {
    /// Rows of the matrix.
    Full(Vec<Vec<f64>>),
    /// Diagonal of a diagonal matrix.
    Diagonal(Vec<f64>),
}

impl MatrixSpec {
    fn to_matrix(
        &self,
        key: &str,
        rows: usize,
        cols: usize,
    ) -> std::result::Result<DMatrix<f64>, Invalid> {
        match self {
            MatrixSpec::Full(r) => {
                if r.len() != rows {
                    return Err(Invalid::new(
                        key,
                        format!("{} rows", r.len()),
                        format!("{rows} rows"),
                    ));
                }
                for (i, row) in r.iter().enumerate() {
                    if row.len() != cols {
                        return Err(Invalid::new(
                            key,
                            format!("row {} with {} entries", i + 1, row.len()),
                            format!("{cols} entries per row"),
                        ));
                    }
                }
                Ok(DMatrix::from_fn(rows, cols, |i, j| r[i][j]))
            }
            MatrixSpec::Diagonal(d) => {
                if rows != cols {
                    return Err(Invalid::new(
                        key,
                        "a diagonal",
                        format!("a full {rows}×{cols} matrix"),
                    ));
                }
                if d.len() != rows {
                    return Err(Invalid::new(
                        key,
                        format!("a diagonal of {}", d.len()),
                        format!("a diagonal of {rows}"),
                    ));
                }
                Ok(DMatrix::from_diagonal(&DVector::from_column_slice(d)))
            }
        }
    }
}

/// `[filter]` table of the model file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct FilterSection {
    /// Batch or sequential update. Default batch.
    pub update: UpdateMethod,
    /// Joseph or standard covariance update. Default Joseph.
    pub covariance_update: CovarianceUpdate,
    /// Measurement policy. Default none (accept all).
    pub policy: PolicyChoice,
}

/// The model file as written.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelFile {
    /// State names (default x1…xn).
    #[serde(default)]
    pub states: Option<Vec<String>>,
    /// Measurement names = CSV column names (default z1…zm).
    #[serde(default)]
    pub measurements: Option<Vec<String>>,
    /// Transition Φ (n×n).
    pub phi: MatrixSpec,
    /// Process noise Q (n×n).
    pub q: MatrixSpec,
    /// Measurement matrix H (m×n).
    pub h: MatrixSpec,
    /// Measurement noise R (m×m).
    pub r: MatrixSpec,
    /// Initial state x0 (n).
    pub x0: Vec<f64>,
    /// Initial covariance P0 (n×n).
    pub p0: MatrixSpec,
    /// Filter options.
    #[serde(default)]
    pub filter: FilterSection,
}

impl Validate for ModelFile {
    fn validate(&self) -> std::result::Result<(), Invalid> {
        let n = self.x0.len();
        if n == 0 || n > MAX_MODEL_DIM {
            return Err(Invalid::new(
                "x0",
                format!("{n} states"),
                format!("1 to {MAX_MODEL_DIM} states"),
            ));
        }
        let m = match &self.h {
            MatrixSpec::Full(rows) => rows.len(),
            MatrixSpec::Diagonal(_) => {
                return Err(Invalid::new("h", "a diagonal", "rows [[…], …]"));
            }
        };
        if m == 0 || m > MAX_MODEL_DIM {
            return Err(Invalid::new(
                "h",
                format!("{m} rows"),
                format!("1 to {MAX_MODEL_DIM} rows"),
            ));
        }
        finite("phi", &self.phi.to_matrix("phi", n, n)?)?;
        let q = self.q.to_matrix("q", n, n)?;
        covariance("q", &q, Definiteness::SemiDefinite)?;
        finite("h", &self.h.to_matrix("h", m, n)?)?;
        let r = self.r.to_matrix("r", m, m)?;
        covariance("r", &r, Definiteness::Definite)?;
        finite("x0", &DMatrix::from_column_slice(n, 1, &self.x0))?;
        let p0 = self.p0.to_matrix("p0", n, n)?;
        covariance("p0", &p0, Definiteness::Definite)?;
        check_names("states", self.states.as_deref(), n)?;
        check_names("measurements", self.measurements.as_deref(), m)?;
        if let Some(names) = &self.measurements
            && names.iter().any(|s| s == "time")
        {
            return Err(Invalid::new(
                "measurements",
                "\"time\"",
                "names other than \"time\" (reserved for the time column)",
            ));
        }
        match self.filter.policy {
            PolicyChoice::None => {}
            PolicyChoice::Chi2Gate { probability: p } => {
                probability("probability", p).map_err(|e| e.within("filter.policy"))?
            }
            PolicyChoice::Huber { k } => positive("k", k).map_err(|e| e.within("filter.policy"))?,
        }
        if self.filter.update == UpdateMethod::Sequential
            && self.filter.policy != PolicyChoice::None
        {
            return Err(Invalid::new(
                "filter.update",
                "\"sequential\" with a policy",
                "\"batch\" when filter.policy is set (policies act on the whole innovation)",
            ));
        }
        Ok(())
    }
}

/// Relative tolerance of the symmetry and definiteness checks (of the
/// largest absolute entry).
pub const COVARIANCE_TOLERANCE: f64 = 1e-9;

/// What a covariance must be: Q ≥ 0, R and P0 > 0.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Definiteness {
    SemiDefinite,
    Definite,
}

fn finite(key: &str, a: &DMatrix<f64>) -> std::result::Result<(), Invalid> {
    match a.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(k) => {
            let (i, j) = (k % a.nrows(), k / a.nrows());
            Err(Invalid::new(
                key,
                format!("element ({}, {}) = {}", i + 1, j + 1, a[(i, j)]),
                "finite numbers",
            ))
        }
    }
}

/// A covariance matrix: finite, symmetric and positive (semi-)definite
/// within [`COVARIANCE_TOLERANCE`] of its largest entry (eigenvalues of the
/// symmetric part).
fn covariance(key: &str, a: &DMatrix<f64>, kind: Definiteness) -> std::result::Result<(), Invalid> {
    finite(key, a)?;
    let scale = a.amax();
    let tol = COVARIANCE_TOLERANCE * scale;
    for i in 0..a.nrows() {
        for j in i + 1..a.ncols() {
            if (a[(i, j)] - a[(j, i)]).abs() > tol {
                return Err(Invalid::new(
                    key,
                    format!(
                        "element ({}, {}) = {:e} against ({}, {}) = {:e}",
                        i + 1,
                        j + 1,
                        a[(i, j)],
                        j + 1,
                        i + 1,
                        a[(j, i)]
                    ),
                    "a symmetric matrix",
                ));
            }
        }
    }
    let eigen = (a + a.transpose()).scale(0.5).symmetric_eigenvalues();
    let min = eigen.min();
    let (ok, allowed) = match kind {
        Definiteness::SemiDefinite => (
            min >= -tol,
            "a positive semi-definite matrix (eigenvalues ≥ 0)",
        ),
        Definiteness::Definite => (min > tol, "a positive definite matrix (eigenvalues > 0)"),
    };
    if ok {
        Ok(())
    } else {
        Err(Invalid::new(
            key,
            format!("smallest eigenvalue {min:e}"),
            allowed,
        ))
    }
}

fn check_names(
    key: &str,
    names: Option<&[String]>,
    count: usize,
) -> std::result::Result<(), Invalid> {
    let Some(names) = names else { return Ok(()) };
    if names.len() != count {
        return Err(Invalid::new(
            key,
            format!("{} names", names.len()),
            format!("{count} names"),
        ));
    }
    for (i, a) in names.iter().enumerate() {
        if a.trim().is_empty() || a.contains(',') {
            return Err(Invalid::new(
                key,
                format!("{a:?}"),
                "non-empty names without commas",
            ));
        }
        if names[..i].contains(a) {
            return Err(Invalid::new(key, format!("{a:?} twice"), "unique names"));
        }
    }
    Ok(())
}

/// A loaded model: the engine's model, run options, names, and the file text.
#[derive(Debug, Clone)]
pub struct LoadedModel {
    /// The model.
    pub model: LinearGaussianModel,
    /// Options from `[filter]`.
    pub options: RunOptions,
    /// State names.
    pub state_names: Vec<String>,
    /// Measurement names (CSV columns).
    pub measurement_names: Vec<String>,
    /// The parsed file, to echo into `summary.json`.
    pub file: ModelFile,
}

/// Load and check a model file.
pub fn load_model(path: &Path) -> Result<LoadedModel> {
    let (file, text): (ModelFile, String) = load_toml(path)?;
    let n = file.x0.len();
    let m = match &file.h {
        MatrixSpec::Full(rows) => rows.len(),
        MatrixSpec::Diagonal(_) => 0,
    };
    let build = |spec: &MatrixSpec, key: &str, r: usize, c: usize| {
        spec.to_matrix(key, r, c).map_err(|inv| IoError::Config {
            path: path.to_path_buf(),
            line: find_key_line(&text, key).unwrap_or(0),
            key: key.to_string(),
            message: format!("{} given: expected {}", inv.value, inv.allowed),
        })
    };
    let phi = build(&file.phi, "phi", n, n)?;
    let q = build(&file.q, "q", n, n)?;
    let h = build(&file.h, "h", m, n)?;
    let r = build(&file.r, "r", m, m)?;
    let p0 = build(&file.p0, "p0", n, n)?;
    let x0 = DVector::from_column_slice(&file.x0);
    let model = LinearGaussianModel::new(phi, q, h, r, x0, p0).map_err(|e| {
        let key = match &e {
            EstimationError::NonFinite { matrix, .. }
            | EstimationError::NotPositiveDefinite { matrix, .. }
            | EstimationError::NotSymmetric { matrix, .. }
            | EstimationError::DimensionMismatch { matrix, .. } => key_of(*matrix),
            _ => "(model)",
        };
        IoError::Config {
            path: path.to_path_buf(),
            line: find_key_line(&text, key).unwrap_or(0),
            key: key.to_string(),
            message: e.to_string(),
        }
    })?;
    let state_names = file
        .states
        .clone()
        .unwrap_or_else(|| (1..=n).map(|i| format!("x{i}")).collect());
    let measurement_names = file
        .measurements
        .clone()
        .unwrap_or_else(|| (1..=m).map(|i| format!("z{i}")).collect());
    let options = RunOptions {
        update: file.filter.update,
        covariance_update: file.filter.covariance_update,
        policy: file.filter.policy,
        ..RunOptions::default()
    };
    if options.update == UpdateMethod::Sequential {
        let r = model.r();
        if let Some((i, j)) = (0..m)
            .flat_map(|i| (0..m).map(move |j| (i, j)))
            .find(|&(i, j)| i != j && r[(i, j)] != 0.0)
        {
            return Err(IoError::Config {
                path: path.to_path_buf(),
                line: find_key_line(&text, "r").unwrap_or(0),
                key: "r".into(),
                message: format!(
                    "element ({}, {}) is non-zero: filter.update = \"sequential\" needs a diagonal R",
                    i + 1,
                    j + 1
                ),
            });
        }
    }
    Ok(LoadedModel {
        model,
        options,
        state_names,
        measurement_names,
        file,
    })
}

fn key_of(m: Matrix) -> &'static str {
    match m {
        Matrix::Phi => "phi",
        Matrix::Q => "q",
        Matrix::H => "h",
        Matrix::R => "r",
        Matrix::X => "x0",
        Matrix::P => "p0",
        _ => "(model)",
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    fn load(text: &str) -> Result<LoadedModel> {
        let mut f = tempfile::NamedTempFile::new().unwrap();
        f.write_all(text.as_bytes()).unwrap();
        load_model(f.path())
    }

    const GOOD: &str = "phi = [[1.0, 1.0], [0.0, 1.0]]\nq = [0.0, 0.01]\nh = [[1.0, 0.0]]\nr = [4.0]\nx0 = [0.0, 0.0]\np0 = [100.0, 10.0]\n";

    #[test]
    fn loads_a_good_model_with_defaults() {
        let m = load(GOOD).unwrap();
        assert_eq!(m.model.states(), 2);
        assert_eq!(m.measurement_names, vec!["z1"]);
        assert_eq!(m.model.p0()[(1, 1)], 10.0);
    }

    #[test]
    fn wrong_row_length_names_key_and_line() {
        let e = load(&GOOD.replace("h = [[1.0, 0.0]]", "h = [[1.0, 0.0, 3.0]]"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(":3: h: row 1 with 3 entries is out of range: allowed 2 entries per row"),
            "{e}"
        );
    }

    #[test]
    fn non_positive_r_is_named() {
        let e = load(&GOOD.replace("r = [4.0]", "r = [-4.0]"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(":4: r: smallest eigenvalue -4e0 is out of range: allowed a positive definite matrix"),
            "{e}"
        );
    }

    #[test]
    fn bad_policy_parameter_is_named() {
        let text =
            format!("{GOOD}[filter]\npolicy = {{ kind = \"chi2_gate\", probability = 1.5 }}\n");
        let e = load(&text).unwrap_err().to_string();
        assert!(
            e.contains(
                ":8: filter.policy.probability: 1.5 is out of range: allowed 0 < probability < 1"
            ),
            "{e}"
        );
    }

    #[test]
    fn a_negative_q_is_refused_at_load() {
        let e = load(&GOOD.replace("q = [0.0, 0.01]", "q = [0.0, -0.01]"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(":2: q: smallest eigenvalue -1e-2 is out of range: allowed a positive semi-definite matrix"),
            "{e}"
        );
        let e = load(&GOOD.replace("q = [0.0, 0.01]", "q = [[1.0, 0.5], [0.4, 1.0]]"))
            .unwrap_err()
            .to_string();
        assert!(e.contains(":2: q: element (1, 2)"), "{e}");
        assert!(e.contains("a symmetric matrix"), "{e}");
    }

    #[test]
    fn an_indefinite_p0_is_refused_at_load() {
        let e = load(&GOOD.replace("p0 = [100.0, 10.0]", "p0 = [[1.0, 2.0], [2.0, 1.0]]"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(":6: p0: smallest eigenvalue -1e0 is out of range: allowed a positive definite matrix"),
            "{e}"
        );
        let e = load(&GOOD.replace("p0 = [100.0, 10.0]", "p0 = [100.0, 0.0]"))
            .unwrap_err()
            .to_string();
        assert!(e.contains(":6: p0: smallest eigenvalue"), "{e}");
        let e = load(&GOOD.replace("x0 = [0.0, 0.0]", "x0 = [0.0, inf]"))
            .unwrap_err()
            .to_string();
        assert!(e.contains(":5: x0: element (2, 1) = inf"), "{e}");
    }

    #[test]
    fn sequential_needs_diagonal_r() {
        let text = "phi = [1.0, 1.0]\nq = [0.1, 0.1]\nh = [[1.0, 0.0], [0.0, 1.0]]\nr = [[1.0, 0.5], [0.5, 1.0]]\nx0 = [0.0, 0.0]\np0 = [1.0, 1.0]\n[filter]\nupdate = \"sequential\"\n";
        let e = load(text).unwrap_err().to_string();
        assert!(e.contains(":4: r: element (1, 2) is non-zero"), "{e}");
    }
}
