//! The error type of laparo-core. Every variant that concerns a file names it.
use std::path::PathBuf;

/// Errors raised by laparo-core.
#[derive(Debug, thiserror::Error)]
pub enum CoreError {
    /// The operating system failed to read or write `path`.
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// `path` could be read but its content is not what its format requires.
    #[error("{path}: {msg}")]
    Format { path: PathBuf, msg: String },
    /// A parameter or an in-memory value is invalid (the message names it).
    #[error("invalid {what}: {msg}")]
    Invalid { what: String, msg: String },
    /// Two inputs that must agree in size do not.
    #[error("size mismatch: {0}")]
    SizeMismatch(String),
}

/// Result alias for laparo-core.
pub type Result<T, E = CoreError> = std::result::Result<T, E>;

impl CoreError {
    /// An I/O error on `path`.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        CoreError::Io { path: path.into(), source }
    }
    /// A format error in `path`.
    pub fn format(path: impl Into<PathBuf>, msg: impl Into<String>) -> Self {
        CoreError::Format { path: path.into(), msg: msg.into() }
    }
    /// An invalid parameter or value called `what`.
    pub fn invalid(what: impl Into<String>, msg: impl Into<String>) -> Self {
        CoreError::Invalid { what: what.into(), msg: msg.into() }
    }
}
