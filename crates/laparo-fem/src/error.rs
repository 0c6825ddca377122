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
    /// Two tetrahedra of a mesh have the same four vertices (the stiffness would count twice).
    #[error("tet mesh: tetrahedra {first} and {second} have the same vertices {vertices:?} (a duplicated element)")]
    DuplicateElement {
        /// The first of the two (index in the mesh).
        first: usize,
        /// The duplicate.
        second: usize,
        /// Its vertices.
        vertices: [usize; 4],
    },
    /// Two tetrahedra sharing a face lie on the same side of it: one is inverted (folded over the other).
    #[error(
        "tet mesh: tetrahedra {first} and {second} lie on the same side of their shared face {face:?}: one of them \
         is inverted (folded over the other)"
    )]
    InvertedElement {
        /// A tetrahedron on the face.
        first: usize,
        /// The one overlapping it.
        second: usize,
        /// The shared face (vertex ids).
        face: [usize; 3],
    },
    /// The applied loads are non-finite or absurd for the material and the size of the body.
    #[error(
        "loads: the total applied force {total_mn:.3e} mN is {what} for this body: more than {max_ratio:e} × E·L² = \
         {limit_mn:.3e} mN (E {young_kpa} kPa, L = {size_mm:.4} mm the mesh's diagonal), strains of order \
         {strain:.1e}; check the units and the sign of the loads"
    )]
    LoadOutOfScale {
        /// Σ |f| over the nodes (mN); infinite on overflow.
        total_mn: f64,
        /// The largest accepted (mN).
        limit_mn: f64,
        /// The ratio limit / (E·L²).
        max_ratio: f64,
        /// Young's modulus of the material (kPa).
        young_kpa: f64,
        /// The mesh's bounding-box diagonal (mm).
        size_mm: f64,
        /// total / (E·L²).
        strain: f64,
        /// "not finite" or "absurd".
        what: &'static str,
    },
    /// A solve from rest returned the rest state although the free nodes carry load: the convergence
    /// tolerance swallowed the load (e.g. most of it on fixed nodes).
    #[error(
        "solver: returned without a Newton step although the free nodes carry a load ({free_load_mn:.3e} mN, \
         tolerance {tolerance_mn:.3e} mN): the displacement would be zero; tighten the relative tolerance or \
         move the load off the fixed nodes"
    )]
    NoNewtonStep {
        /// ‖free residual‖ at rest (mN).
        free_load_mn: f64,
        /// The tolerance that accepted it (mN).
        tolerance_mn: f64,
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
