//! Errors of laparo-cpc: every message names the parameter or input at fault.
use laparo_core::error::CoreError;

/// Errors raised by the CPC pipeline.
#[derive(Debug, thiserror::Error)]
pub enum CpcError {
    /// A parameter or input is invalid (the message names it).
    #[error("invalid {what}: {msg}")]
    Invalid {
        /// The parameter or input.
        what: String,
        /// What is wrong with it.
        msg: String,
    },
    /// Two inputs that must agree in size do not.
    #[error("size mismatch: {0}")]
    SizeMismatch(String),
    /// The sparse solver failed (not positive definite, out of memory, ...).
    #[error("solver: {0}")]
    Solver(String),
    /// An error from laparo-core (file I/O, formats).
    #[error(transparent)]
    Core(#[from] CoreError),
}

/// Result alias for laparo-cpc.
pub type Result<T, E = CpcError> = std::result::Result<T, E>;

impl CpcError {
    /// An invalid parameter or value called `what`.
    pub fn invalid(what: impl Into<String>, msg: impl Into<String>) -> Self {
        CpcError::Invalid { what: what.into(), msg: msg.into() }
    }
}
