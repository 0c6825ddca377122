//! Errors of the MPM engine.

/// Everything that can go wrong in laparo-mpm.
#[derive(Debug, thiserror::Error)]
pub enum MpmError {
    /// The scene has no particles.
    #[error("the scene has no particles")]
    NoParticles,
    /// A scalar parameter is out of range.
    #[error("invalid parameter {name} = {value}: {reason}")]
    InvalidParameter { name: String, value: f64, reason: String },
    /// A per-particle array has the wrong length.
    #[error("{name} has {got} entries, expected {expected} (one per particle)")]
    LengthMismatch { name: String, expected: usize, got: usize },
    /// Anything else wrong with the scene.
    #[error("invalid scene: {0}")]
    InvalidScene(String),
    /// A particle is (or moved) outside the part of the grid its B-spline stencil needs.
    #[error("particle {particle} is outside the grid domain at step {step} (its 3-node stencil leaves the grid)")]
    OutsideDomain { particle: usize, step: usize },
    /// The simulation blew up.
    #[error("simulation blew up at step {step}, particle {particle}: {reason} (reduce dt; see the CFL warning)")]
    BlowUp { step: usize, particle: usize, reason: String },
    /// Bad mesh input for particle sampling.
    #[error("mesh {path}: {reason}")]
    Mesh { path: String, reason: String },
    /// The loss returned something unusable.
    #[error("loss: {0}")]
    Loss(String),
}
