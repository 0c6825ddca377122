//! Volume meshing, incisions and a quasi-static Neo-Hookean FEM for the in-silico incision benchmark
//! (thesis §5.4.2): the ground truth that RODS-MPM and the mesh-based baselines are scored against.
//! It must not come from `laparo-mpm` (that would test the method against itself).
//!
//! - [`material`]: the Neo-Hookean law of eq. 5.3 (ψ, P, ∂P/∂F), shared with the baselines.
//! - [`mesh`]: tetrahedralisation of a closed surface, quality report, incisions.
//! - [`solid`]: quadratic-tetrahedron (TET10) quasi-static solver, Newton with a line search.
//!
//! The most used names are in [`prelude`]. The patch test of `tests/solid_verification.rs`: every
//! boundary node of a 10 mm box moved by an affine field `u(X) = (G − I) X` — the solver must
//! reproduce the field at the interior nodes and `J = det G` everywhere:
//!
//! ```
//! use laparo_fem::prelude::*;
//! use nalgebra::{Matrix3, Vector3};
//!
//! let lin = laparo_fem::mesh::shapes::kuhn_box([2, 2, 2], 5.0); // 2³ cubes of 6 tetrahedra
//! let mesh = Tet10Mesh::from_linear(&lin)?;
//! let g = Matrix3::new(1.1, 0.05, 0.0, 0.0, 0.95, 0.02, -0.03, 0.0, 1.05);
//! let exact = |x: &Vector3<f64>| (g - Matrix3::identity()) * x;
//! let on_boundary = |x: &Vector3<f64>| x.iter().any(|&c| c.abs() < 1e-9 || (c - 10.0).abs() < 1e-9);
//! let bc: Vec<Dirichlet> = (0..mesh.n_nodes())
//!     .filter(|&i| on_boundary(&mesh.nodes[i]))
//!     .map(|i| Dirichlet { node: i, value_mm: exact(&mesh.nodes[i]) })
//!     .collect();
//! let nodes = mesh.nodes.clone();
//! let p = SolidProblem::new(mesh, NeoHookean::liver(), &bc, &Loads::default(), Quadrature::Degree2)?;
//! let s = solve(&p, &SolverSettings { steps: 2, rel_tol: 1e-13, ..Default::default() })?;
//! let interior: Vec<usize> = (0..nodes.len()).filter(|&i| !p.is_prescribed(i)).collect();
//! assert!(!interior.is_empty());
//! for i in interior {
//!     assert!((s.displacement[i] - exact(&nodes[i])).norm() < 1e-10);
//! }
//! assert!((s.min_j - g.determinant()).abs() < 1e-9);
//! # Ok::<(), FemError>(())
//! ```
#![warn(missing_docs)]

pub mod error;
pub mod material;
pub mod mesh;
pub mod solid;

pub use error::{FemError, Result};
pub use material::NeoHookean;

/// The types and functions most programs need: `use laparo_fem::prelude::*;`.
pub mod prelude {
    pub use crate::error::{FemError, Result};
    pub use crate::material::NeoHookean;
    pub use crate::mesh::{
        cut, tetrahedralize_surface, Blade, CutMesh, Landmarks, QualityReport, Scenario, ScenarioFrame, TetraParams,
    };
    pub use crate::solid::{
        solve, Dirichlet, FaceTraction, LoadPath, Loads, Quadrature, SolidProblem, Solution, SolverSettings, Tet10Mesh,
    };
}
