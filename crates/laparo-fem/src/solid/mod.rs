//! Quadratic-tetrahedron (TET10) quasi-static FEM: the ground truth of the in-silico incision
//! benchmark (thesis §5.4.2). Nearly incompressible Neo-Hookean law of eq. 5.3
//! ([`crate::material::NeoHookean`]), dead tractions / nodal / body forces and prescribed
//! displacements ramped over load increments, Newton with a backtracking line search on the total
//! potential energy; the Newton systems by sparse Cholesky (faer; geometric nested-dissection or AMD
//! fill-reducing ordering) on small meshes and by conjugate gradients with a two-level (TET10 → linear
//! tetrahedra) preconditioner beyond ([`LinearSolver`]).
//!
//! Units: mm, kPa, mN (energy in mN·mm = µJ).
mod linear;
mod load_path;
mod newton;
mod ordering;
mod problem;
mod quadrature;
mod tet10;
mod two_level;

pub use load_path::LoadPath;
pub use newton::{
    factorization_profile, solve, FactorizationProfile, FillOrdering, LinearSolver, Solution, SolverSettings,
    StepReport, Timings,
};
pub use problem::{Assembled, BodyForce, Dirichlet, FaceTraction, Loads, NodalForce, SolidProblem};
pub use quadrature::{tet10_shape, tet10_shape_grad, QuadPoint, Quadrature, TET10_EDGES};
pub use tet10::{check_elements, Tet10Mesh};
