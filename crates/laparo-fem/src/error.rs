//! The crate's one error type.
use thiserror::Error;

/// Every failure of `laparo-fem`; messages name the offending input (file, mesh or parameter).
#[derive(Debug, Error)]
pub enum FemError {
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
    /// An input (file, mesh, cut, load) is unusable (name, reason).
    #[error("{input}: {reason}")]
    BadInput {
        /// The file path or the name of the input.
        input: String,
        /// What is wrong.
        reason: String,
    },
    /// The nonlinear or linear solver failed (what, why).
    #[error("solver: {0}")]
    Solver(String),
    /// laparo-core failed (I/O, mesh).
    #[error("{0}")]
    Core(#[from] laparo_core::CoreError),
}

impl FemError {
    /// A [`FemError::BadInput`].
    pub fn bad(input: impl Into<String>, reason: impl Into<String>) -> Self {
        FemError::BadInput { input: input.into(), reason: reason.into() }
    }
    /// A [`FemError::InvalidParameter`].
    pub fn param(name: impl Into<String>, value: f64, reason: impl Into<String>) -> Self {
        FemError::InvalidParameter { name: name.into(), value, reason: reason.into() }
    }
}

/// Result with [`FemError`].
pub type Result<T> = std::result::Result<T, FemError>;
