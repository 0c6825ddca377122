//! The one error type of laparo-guide: every failure names the stage and the input.
use thiserror::Error;

/// Errors of the guidance pipeline.
#[derive(Debug, Error)]
pub enum GuideError {
    /// A stage refused its input (bad polyline, pose too far, too little texture, ...).
    #[error("stage `{stage}`, input `{input}`: {msg}")]
    Stage {
        /// Stage name (stereo, rigid, landmarks, targets, registration, ...).
        stage: String,
        /// The offending input (file or parameter).
        input: String,
        /// What is wrong.
        msg: String,
    },
    /// laparo-core (I/O, meshes, images).
    #[error(transparent)]
    Core(#[from] laparo_core::CoreError),
    /// laparo-stereo.
    #[error(transparent)]
    Stereo(#[from] laparo_stereo::StereoError),
    /// laparo-register.
    #[error(transparent)]
    Register(#[from] laparo_register::RegisterError),
    /// laparo-features.
    #[error(transparent)]
    Features(#[from] laparo_features::FeaturesError),
}

impl GuideError {
    /// A stage error naming the stage and the input.
    pub fn stage(stage: impl Into<String>, input: impl Into<String>, msg: impl Into<String>) -> Self {
        GuideError::Stage { stage: stage.into(), input: input.into(), msg: msg.into() }
    }
}

/// Result of laparo-guide.
pub type Result<T> = std::result::Result<T, GuideError>;
