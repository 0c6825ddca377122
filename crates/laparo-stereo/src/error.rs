//! The one error type of laparo-stereo: augmentation, CATS configuration and dataset conversion
//! errors (calibration, rectification and evaluation return `laparo_core::CoreError`, which
//! converts into it).
use laparo_core::CoreError;
use std::path::PathBuf;

/// Errors of laparo-stereo. Every message names the parameter or file at fault.
#[derive(Debug, thiserror::Error)]
pub enum StereoError {
    /// A file, format or geometry error of laparo-core.
    #[error(transparent)]
    Core(#[from] CoreError),
    /// A parameter is invalid (`what` names it).
    #[error("invalid {what}: {msg}")]
    Invalid {
        /// The parameter.
        what: String,
        /// Why.
        msg: String,
    },
    /// Inputs of different sizes.
    #[error("size mismatch: {0}")]
    SizeMismatch(String),
    /// A CATS distribution or camera parameter is invalid (the message names it).
    #[error("invalid CATS config: {0}")]
    Config(String),
    /// TOML syntax or schema error of a CATS config (quoted in the message).
    #[error("CATS config: {0}")]
    Toml(toml::de::Error),
    /// Dataset layout or file problem (the message names the file).
    #[error("{path}: {msg}")]
    File {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        msg: String,
    },
}

impl From<toml::de::Error> for StereoError {
    fn from(e: toml::de::Error) -> Self {
        StereoError::Toml(e)
    }
}

/// Former name of [`StereoError`] for augmentation (kept for one release).
pub type AugmentError = StereoError;
/// Former name of [`StereoError`] for CATS configurations (kept for one release).
pub type ConfigError = StereoError;
/// Former name of [`StereoError`] for dataset conversion (kept for one release).
pub type DatasetError = StereoError;
