//! The error type of laparo-core. Every variant that concerns a file names it.
use std::path::PathBuf;

/// Errors raised by laparo-core.
#[derive(Debug, thiserror::Error)]
pub enum CoreError {
    /// The operating system failed to read or write `path`. The OS error is part of the message
    /// (not also reported as `source()`, so an error chain does not print it twice).
    #[error("{path}: {error}")]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// The operating-system error.
        error: std::io::Error,
    },
    /// `path` could be read but its content is not what its format requires.
    #[error("{path}: {msg}")]
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong with its content.
        msg: String,
    },
    /// A parameter or an in-memory value is invalid (the message names it).
    #[error("invalid {what}: {msg}")]
    Invalid {
        /// The parameter or value.
        what: String,
        /// What is wrong with it.
        msg: String,
    },
    /// Two inputs that must agree in size do not.
    #[error("size mismatch: {0}")]
    SizeMismatch(String),
}

/// Result alias for laparo-core.
pub type Result<T, E = CoreError> = std::result::Result<T, E>;

impl CoreError {
    /// An I/O error on `path`.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        CoreError::Io { path: path.into(), error: source }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn io_error_names_the_file_once_in_a_chain() {
        let e = CoreError::io("a.npy", std::io::Error::new(std::io::ErrorKind::NotFound, "No such file"));
        assert_eq!(e.to_string(), "a.npy: No such file");
        // The OS error is in the message, so it is not a separate cause (anyhow's {:#} would repeat it).
        assert!(std::error::Error::source(&e).is_none());
        assert_eq!(anyhow_like(&e), "a.npy: No such file");
    }

    /// Join an error and its causes the way `anyhow`'s `{:#}` does.
    fn anyhow_like(e: &dyn std::error::Error) -> String {
        let mut s = e.to_string();
        let mut c = e.source();
        while let Some(x) = c {
            s += &format!(": {x}");
            c = x.source();
        }
        s
    }
}
