//! The error type of the I/O layer: always names the file, and the line,
//! column or key where it can.

use std::path::PathBuf;

/// An I/O-layer error.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum IoError {
    /// The file could not be read.
    #[error("{path}: cannot read: {source}")]
    Read {
        /// File.
        path: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
    /// The file could not be written.
    #[error("{path}: cannot write: {message}")]
    Write {
        /// File.
        path: PathBuf,
        /// Cause.
        message: String,
    },
    /// A configuration (TOML) file is malformed or holds an invalid value.
    #[error("{path}:{line}: {key}: {message}")]
    Config {
        /// File.
        path: PathBuf,
        /// 1-based line (0 when unknown).
        line: usize,
        /// Dotted key, e.g. `filter.policy.probability`.
        key: String,
        /// What is wrong and what is allowed.
        message: String,
    },
    /// A data (CSV) file is malformed.
    #[error("{path}:{line}: column `{column}`: {message}")]
    Data {
        /// File.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// Column name (or number when the header is unreadable).
        column: String,
        /// What is wrong.
        message: String,
    },
    /// A data file exceeds a documented limit.
    #[error("{path}: {message}")]
    Limit {
        /// File.
        path: PathBuf,
        /// Which limit and how to change it.
        message: String,
    },
}

/// Result alias of the I/O layer.
pub type Result<T> = std::result::Result<T, IoError>;
