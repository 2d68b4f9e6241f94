//! The error of the vehicle simulation: a parameter out of range, named by
//! its path in the scenario (the TOML key it will come from).

/// Why a scenario was not simulated.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SimError {
    /// A numeric parameter is out of its range.
    #[error("invalid scenario parameter `{field}` = {value}: {requirement}")]
    InvalidParameter {
        /// Path of the parameter in the scenario, e.g. `gnss.rate_hz`.
        field: String,
        /// The value given (unit of that parameter).
        value: f64,
        /// What the value must satisfy.
        requirement: &'static str,
    },
    /// A table of the scenario does not read (unknown field, wrong type).
    #[error("invalid scenario table [{table}]: {message}")]
    Table {
        /// The table, e.g. `imu`.
        table: String,
        /// What is wrong.
        message: String,
    },
    /// A route segment cannot be driven (e.g. a turn at standstill).
    #[error("route segment {index} cannot be driven: {reason}")]
    InfeasibleSegment {
        /// Index of the segment in `route.segments` (0-based).
        index: usize,
        /// What is wrong with it.
        reason: &'static str,
    },
}

/// `Ok` when `value` is finite and positive, else the error for `field`.
pub(crate) fn positive(field: impl Into<String>, value: f64) -> Result<(), SimError> {
    check(
        field,
        value,
        value.is_finite() && value > 0.0,
        "must be finite and > 0",
    )
}

/// `Ok` when `value` is finite and non-negative, else the error for `field`.
pub(crate) fn non_negative(field: impl Into<String>, value: f64) -> Result<(), SimError> {
    check(
        field,
        value,
        value.is_finite() && value >= 0.0,
        "must be finite and ≥ 0",
    )
}

/// `Ok` when `value` is finite, else the error for `field`.
pub(crate) fn finite(field: impl Into<String>, value: f64) -> Result<(), SimError> {
    check(field, value, value.is_finite(), "must be finite")
}

/// `Ok` when `ok`, else the error for `field` with `requirement`.
pub(crate) fn check(
    field: impl Into<String>,
    value: f64,
    ok: bool,
    requirement: &'static str,
) -> Result<(), SimError> {
    if ok {
        Ok(())
    } else {
        Err(SimError::InvalidParameter {
            field: field.into(),
            value,
            requirement,
        })
    }
}
