//! The error type of the I/O layer: always names the file, and the line,
//! column or key where it can.

use std::path::PathBuf;

/// An I/O-layer error.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum IoError {
    /// The file could not be read.
    ///
    /// The operating system's reason is part of the message and deliberately
    /// not also returned by `Error::source`, so a printer walking the chain
    /// shows it once.
    #[error("{path}: cannot read: {reason}")]
    Read {
        /// File.
        path: PathBuf,
        /// The operating system's reason.
        reason: std::io::Error,
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
    /// A binary data file (a receiver's UBX log) holds a value that cannot
    /// be used.
    #[error("{path}: byte {offset}: {field}: {message}")]
    Binary {
        /// File.
        path: PathBuf,
        /// Byte offset from the file's start of the frame (its first sync
        /// byte) holding the value.
        offset: usize,
        /// Message and field, e.g. `NAV-PVT hAcc`.
        field: String,
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

#[cfg(test)]
mod tests {

    #[test]
    fn read_error_names_the_reason_once() {
        let err =
            crate::text::read_bytes(std::path::Path::new("/no/such/dir/imu.csv")).unwrap_err();
        let text = err.to_string();
        assert!(
            text.starts_with("/no/such/dir/imu.csv: cannot read: "),
            "{text}"
        );
        // The OS reason is in the message, so it is not also the source.
        assert!(std::error::Error::source(&err).is_none(), "{text}");
    }
}
