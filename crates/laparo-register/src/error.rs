//! The crate's one error type.
use thiserror::Error;

/// Every failure of `laparo-register`; messages name the offending input (file or parameter).
#[derive(Debug, Error)]
pub enum RegisterError {
    /// A parameter is out of range (name, value, reason).
    #[error("invalid parameter `{name}` = {value}: {reason}")]
    InvalidParameter {
        /// Parameter name.
        name: String,
        /// Offending value.
        value: f64,
        /// Why it is invalid.
        reason: String,
    },
    /// An input file or input object is unusable (name, reason).
    #[error("{input}: {reason}")]
    BadInput {
        /// The file path or the name of the input.
        input: String,
        /// What is wrong.
        reason: String,
    },
    /// The simulation engine failed.
    #[error("MPM: {0}")]
    Mpm(#[from] laparo_mpm::MpmError),
    /// laparo-core failed (I/O, image, mesh).
    #[error("{0}")]
    Core(#[from] laparo_core::CoreError),
}

impl RegisterError {
    /// A [`RegisterError::BadInput`].
    pub fn bad(input: impl Into<String>, reason: impl Into<String>) -> Self {
        RegisterError::BadInput { input: input.into(), reason: reason.into() }
    }
    /// A [`RegisterError::InvalidParameter`].
    pub fn param(name: impl Into<String>, value: f64, reason: impl Into<String>) -> Self {
        RegisterError::InvalidParameter { name: name.into(), value, reason: reason.into() }
    }
}

/// Result with [`RegisterError`].
pub type Result<T> = std::result::Result<T, RegisterError>;
