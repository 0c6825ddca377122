//! The error type of the RoDEM evaluation modules. Every variant that concerns a file names it.
use std::path::PathBuf;

/// Errors raised by the RoDEM evaluation (alignment, metrics, manifest, evaluation, reports).
#[derive(Debug, thiserror::Error)]
pub enum DepthError {
    /// A laparo-core error (file I/O and formats name the file).
    #[error(transparent)]
    Core(#[from] laparo_core::CoreError),
    /// An input that names a file is unusable (size mismatch, all invalid, ...).
    #[error("{path}: {msg}")]
    File {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        msg: String,
    },
    /// A parameter or an in-memory value is invalid (the message names it).
    #[error("invalid {what}: {msg}")]
    Invalid {
        /// The parameter or input.
        what: String,
        /// What is wrong with it.
        msg: String,
    },
    /// The manifest failed validation; every problem is listed.
    #[error("manifest {path}: {} problem(s):\n  {}", problems.len(), problems.join("\n  "))]
    Manifest {
        /// The manifest file.
        path: PathBuf,
        /// Every problem found.
        problems: Vec<String>,
    },
}

/// Result alias for laparo-depth.
pub type Result<T, E = DepthError> = std::result::Result<T, E>;

impl DepthError {
    /// A problem with the file `path`.
    pub fn file(path: impl Into<PathBuf>, msg: impl Into<String>) -> Self {
        DepthError::File { path: path.into(), msg: msg.into() }
    }
    /// An invalid parameter or value called `what`.
    pub fn invalid(what: impl Into<String>, msg: impl Into<String>) -> Self {
        DepthError::Invalid { what: what.into(), msg: msg.into() }
    }
}
