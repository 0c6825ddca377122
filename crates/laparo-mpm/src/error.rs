//! The error type of the crate and the non-fatal warnings it returns (libraries never print).

/// Everything that can go wrong in laparo-mpm.
#[derive(Debug, thiserror::Error)]
pub enum MpmError {
    /// The scene has no particles.
    #[error("the scene has no particles")]
    NoParticles,
    /// A scalar parameter is out of range.
    #[error("invalid parameter {name} = {value}: {reason}")]
    InvalidParameter {
        /// Parameter name.
        name: String,
        /// Its value.
        value: f64,
        /// What is wrong with it.
        reason: String,
    },
    /// A per-particle array has the wrong length.
    #[error("{name} has {got} entries, expected {expected} (one per particle)")]
    LengthMismatch {
        /// Array name.
        name: String,
        /// Number of particles.
        expected: usize,
        /// Length of the array.
        got: usize,
    },
    /// Anything else wrong with the scene.
    #[error("invalid scene: {0}")]
    InvalidScene(String),
    /// A particle is (or moved) outside the part of the grid its B-spline stencil needs.
    #[error("particle {particle} is outside the grid domain at step {step} (its 3-node stencil leaves the grid)")]
    OutsideDomain {
        /// Particle index.
        particle: usize,
        /// Time step.
        step: usize,
    },
    /// The simulation blew up.
    #[error("simulation blew up at step {step}, particle {particle}: {reason} (reduce dt; see the CFL warning)")]
    BlowUp {
        /// Time step.
        step: usize,
        /// Particle index.
        particle: usize,
        /// What went wrong.
        reason: String,
    },
    /// Bad mesh input for particle sampling.
    #[error("mesh {path}: {reason}")]
    Mesh {
        /// Mesh file.
        path: String,
        /// What is wrong with it.
        reason: String,
    },
    /// The loss returned something unusable.
    #[error("loss: {0}")]
    Loss(String),
}

/// Something the caller should know but that does not stop the simulation (libraries don't print).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub enum Warning {
    /// c Δt / Δx exceeds the scene's `cfl_limit`: explicit MPM may blow up.
    CflViolated {
        /// Configured Δt.
        dt: f64,
        /// c Δt / Δx with c = sqrt((λ + 2μ)/ρ).
        cfl_number: f64,
        /// The limit that was exceeded.
        limit: f64,
        /// Largest Δt within the limit.
        max_dt: f64,
    },
    /// A body sampled with fewer than ~2 particles per grid cell: MPM under-resolves it (it may
    /// collapse or pass through itself); use spacing ≤ Δx / 2^(1/D).
    SparseParticles {
        /// Body index in the scene file.
        body: usize,
        /// (Δx / spacing)^D.
        particles_per_cell: f64,
        /// The body's particle spacing (length units).
        spacing: f64,
        /// Grid cell width Δx (length units).
        dx: f64,
    },
}

impl std::fmt::Display for Warning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Warning::CflViolated { dt, cfl_number, limit, max_dt } => write!(
                f,
                "dt = {dt:.3e} violates the CFL condition: c*dt/dx = {cfl_number:.3} > {limit} (use dt <= {max_dt:.3e})"
            ),
            Warning::SparseParticles { body, particles_per_cell, spacing, dx } => write!(
                f,
                "body {body}: {particles_per_cell:.2} particles per grid cell (spacing {spacing:.3e}, dx {dx:.3e}); \
                 MPM needs about 2 or more (spacing <= dx/2 gives 4 in 2D, 8 in 3D)"
            ),
        }
    }
}
