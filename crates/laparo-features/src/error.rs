//! Errors of laparo-features: every message names the parameter or input at fault.
use laparo_core::error::CoreError;

/// Errors raised by detection, matching, robust estimation and evaluation.
#[derive(Debug, thiserror::Error)]
pub enum FeaturesError {
    /// A parameter or input is invalid (the message names it).
    #[error("invalid {what}: {msg}")]
    Invalid {
        /// The parameter or input.
        what: String,
        /// What is wrong with it.
        msg: String,
    },
    /// Too few correspondences, or a degenerate configuration, for a robust fit.
    #[error("estimation failed: {0}")]
    Estimation(String),
    /// An SQLite error while writing a COLMAP database.
    #[error("COLMAP database {path}: {msg}")]
    Database {
        /// The database file.
        path: String,
        /// What went wrong.
        msg: String,
    },
    /// An error from laparo-core (file I/O, formats).
    #[error(transparent)]
    Core(#[from] CoreError),
}

/// Result alias for laparo-features.
pub type Result<T, E = FeaturesError> = std::result::Result<T, E>;

impl FeaturesError {
    /// An invalid parameter or value called `what`.
    pub fn invalid(what: impl Into<String>, msg: impl Into<String>) -> Self {
        FeaturesError::Invalid { what: what.into(), msg: msg.into() }
    }
}
