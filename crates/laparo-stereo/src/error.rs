//! The one error type of laparo-stereo: every public function returns [`StereoError`]
//! (laparo-core, laparo-features, TOML and JSON errors are kept as typed sources, not strings).
use laparo_core::CoreError;
use laparo_features::FeaturesError;
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
    /// laparo-core rejected a parameter (intrinsics, distortion, warp, image size); `what` names it.
    #[error("invalid {what}: {source}")]
    Rejected {
        /// The parameter.
        what: String,
        /// laparo-core's reason.
        #[source]
        source: CoreError,
    },
    /// Inputs of different sizes.
    #[error("size mismatch: {0}")]
    SizeMismatch(String),
    /// Feature detection, matching or the robust fit of the matches failed (`what` names the step).
    #[error("{what}: {source}")]
    Features {
        /// The step (e.g. "SIFT matching").
        what: String,
        /// laparo-features' error.
        #[source]
        source: FeaturesError,
    },
    /// A CATS distribution or camera parameter is invalid (the message names it).
    #[error("invalid CATS config: {0}")]
    Config(String),
    /// A CATS camera or parameter file field rejected by laparo-core (`what` names the field).
    #[error("invalid CATS config: {what}: {source}")]
    ConfigField {
        /// The field.
        what: String,
        /// laparo-core's reason.
        #[source]
        source: CoreError,
    },
    /// Hand-written CATS parameters (JSON) that do not parse (`what` says which part).
    #[error("invalid CATS config: {what}: {source}")]
    ConfigJson {
        /// What was being read.
        what: String,
        /// serde_json's error.
        #[source]
        source: serde_json::Error,
    },
    /// Hand-written CATS parameters that parse but describe invalid cameras.
    #[error("invalid CATS config: {what}: {source}")]
    ConfigCheck {
        /// What was being checked.
        what: String,
        /// The check that failed.
        #[source]
        source: Box<StereoError>,
    },
    /// TOML syntax or schema error of a CATS config (quoted in the message).
    #[error("CATS config: {0}")]
    Toml(#[from] toml::de::Error),
    /// Dataset layout or file problem (the message names the file).
    #[error("{path}: {msg}")]
    File {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        msg: String,
    },
    /// A number in a dataset file does not parse (`what` names the key).
    #[error("{path}: {what}: {source}")]
    FileNumber {
        /// The file.
        path: PathBuf,
        /// The key.
        what: String,
        /// The parse error.
        #[source]
        source: std::num::ParseFloatError,
    },
    /// A dataset file's value rejected by laparo-core (`what` names the key).
    #[error("{path}: {what}: {source}")]
    FileField {
        /// The file.
        path: PathBuf,
        /// The key.
        what: String,
        /// laparo-core's reason.
        #[source]
        source: CoreError,
    },
    /// A sample's parameters failed a check (`path` names the sample).
    #[error("{path}: {what}: {source}")]
    FileCheck {
        /// The sample's left image.
        path: PathBuf,
        /// What was checked.
        what: String,
        /// The check that failed.
        #[source]
        source: Box<StereoError>,
    },
}

/// Result of laparo-stereo.
pub type Result<T> = std::result::Result<T, StereoError>;

impl StereoError {
    /// A [`StereoError::Invalid`] naming the parameter.
    pub(crate) fn invalid(what: impl Into<String>, msg: impl Into<String>) -> Self {
        StereoError::Invalid { what: what.into(), msg: msg.into() }
    }

    /// A [`StereoError::Rejected`]: laparo-core's error about the parameter `what`.
    pub(crate) fn rejected(what: impl Into<String>) -> impl FnOnce(CoreError) -> Self {
        let what = what.into();
        move |source| StereoError::Rejected { what, source }
    }
}
