//! How a plausibility check of the readers (and of the application) acts on
//! what it finds: refuse the log, warn and go on, or not look.
//!
//! A plausibility check judges a whole log against what sensors usually
//! are (the median specific force about 1 g, a gyro at rest reading only
//! its bias): a correct log from an unusual platform can fail it, so the
//! user may turn it into a warning or off. Limits that no sensor can
//! exceed (`crate::limits`) are not plausibility checks and always refuse.

use serde::{Deserialize, Serialize};

use crate::Result;

/// What a plausibility check does when the log fails it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CheckLevel {
    /// Refuse the log with the check's message (the default).
    #[default]
    Error,
    /// Keep the message as a warning of the reader and go on.
    Warn,
    /// Do not act on the check.
    Off,
}

impl CheckLevel {
    /// Act on a check's `outcome`: an error is returned (`error`), pushed
    /// onto `warnings` as its message (`warn`) or dropped (`off`).
    ///
    /// ```
    /// use aidnav_io::checks::CheckLevel;
    /// use aidnav_io::IoError;
    /// let failed = || -> aidnav_io::Result<()> {
    ///     Err(IoError::Limit { path: "imu.csv".into(), message: "odd".into() })
    /// };
    /// let mut warnings = Vec::new();
    /// assert!(CheckLevel::Error.apply(failed(), &mut warnings).is_err());
    /// assert!(CheckLevel::Warn.apply(failed(), &mut warnings).is_ok());
    /// assert!(CheckLevel::Off.apply(failed(), &mut warnings).is_ok());
    /// assert_eq!(warnings, ["imu.csv: odd"]);
    /// ```
    pub fn apply(self, outcome: Result<()>, warnings: &mut Vec<String>) -> Result<()> {
        match (self, outcome) {
            (_, Ok(())) | (CheckLevel::Off, Err(_)) => Ok(()),
            (CheckLevel::Error, Err(e)) => Err(e),
            (CheckLevel::Warn, Err(e)) => {
                warnings.push(e.to_string());
                Ok(())
            }
        }
    }
}
