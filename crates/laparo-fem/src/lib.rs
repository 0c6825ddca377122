//! Volume meshing, incisions and a quasi-static Neo-Hookean FEM for the in-silico incision benchmark
//! (thesis §5.4.2): the ground truth that RODS-MPM and the mesh-based baselines are scored against.
//! It must not come from `laparo-mpm` (that would test the method against itself).
//!
//! - [`material`]: the Neo-Hookean law of eq. 5.3 (ψ, P, ∂P/∂F), shared with the baselines.
//! - [`mesh`]: tetrahedralisation of a closed surface, quality report, incisions.
//! - [`solid`]: quadratic-tetrahedron (TET10) quasi-static solver, Newton with a line search.
#![warn(missing_docs)]

pub mod error;
pub mod material;
pub mod mesh;
pub mod solid;

pub use error::{FemError, Result};
pub use material::NeoHookean;
