//! laparo-mpm — differentiable MLS-MPM with exact gradients, 2D and 3D (thesis §5.2.3–5.2.4, §5.3.2,
//! eqs. 5.3–5.7).
//!
//! A [`Scene`] holds particles, material, grid, boundary conditions, Δt and the horizon T;
//! [`simulate`] runs it; [`simulate_with_gradient`] also returns the exact gradient of a [`Loss`]
//! on particle positions with respect to the initial velocities and positions, E and ν, by a
//! hand-derived adjoint of every stage (see README.md). Scenes can also be read from TOML files
//! ([`load_scene_file`]) with bodies sampled from boxes, ellipsoids, closed surfaces and
//! tetrahedral meshes ([`sampling`]). Every failure is an [`MpmError`]; non-fatal findings are
//! returned as [`Warning`]s (the library never prints).
//!
//! ```
//! use laparo_mpm::prelude::*;
//!
//! // A 2D block of 10×5 particles (spacing Δx/2) pulled apart along x, no gravity.
//! let grid = GridSpec::unit(32);
//! let material = Material { model: Model::NeoHookean, youngs_modulus: 5.0, poisson_ratio: 0.3, density: 1.0 };
//! let spacing = grid.dx / 2.0;
//! let x0 = box_lattice(Vector::<2>::new(0.42, 0.45), Vector::<2>::new(0.5, 0.49), spacing);
//! let dt = cfl_dt(&material, grid.dx, 0.3);
//! let mut scene = Scene::new(x0, spacing * spacing, material, grid, dt, 20);
//! let n = scene.n_particles();
//! let cx = scene.positions.iter().map(|p| p[0]).sum::<f64>() / n as f64;
//! for p in 0..n {
//!     scene.velocities[p] = Vector::<2>::new(2.0 * (scene.positions[p][0] - cx), 0.0);
//! }
//! let sim = simulate(&scene)?;
//! // No external force and walls far away: linear momentum is conserved (it starts at 0).
//! let d = diagnostics(&scene, &sim.final_state);
//! assert!(d.linear_momentum[0].abs() < 1e-12);
//!
//! // ∂L/∂v₀ of L = mean distance of particle 0 to a target after T steps.
//! let loss = LandmarkLoss { indices: vec![0], targets: vec![Vector::<2>::new(0.40, 0.45)] };
//! let g = simulate_with_gradient(&scene, &loss)?;
//! assert_eq!(g.d_velocities.len(), scene.n_particles());
//! assert!(g.loss > 0.0 && g.d_velocities[0].norm() > 0.0);
//! # Ok::<(), laparo_mpm::MpmError>(())
//! ```
#![warn(missing_docs)]
// `!(a > b)` comparisons are deliberate: they also reject NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

// The MPM stages and the sparse grid are internal: the hot loops inline across these modules.
mod adjoint;
mod backward;
mod budget;
mod cfl;
mod constitutive;
mod error;
mod fixed_corotated;
mod g2p;
mod grid_spec;
mod grid_update;
mod linalg;
mod loss;
mod neo_hookean;
mod p2g;
pub mod reference;
pub mod render;
pub mod sampling;
mod scene;
mod scene_file;
mod simulate;
mod sparse_grid;
mod stencil;

pub use adjoint::{
    checkpoint_segment_for, simulate_with_gradient, simulate_with_gradient_in, GradientResult, GradientWorkspace,
};
pub use budget::{estimate_memory_bytes, DEFAULT_MEMORY_LIMIT_BYTES};
pub use cfl::{cfl_dt, cfl_number, cfl_warnings};
pub use constitutive::{lame, ConstitutiveModel};
pub use error::{MpmError, Warning};
pub use fixed_corotated::FixedCorotated;
pub use grid_spec::GridSpec;
pub use linalg::{det, Matrix, Vector};
pub use loss::{FinalLoss, LandmarkLoss, Loss, StepsLoss};
pub use neo_hookean::NeoHookean;
pub use scene::{box_lattice, ellipsoid_lattice, lattice_where, Boundary, Material, Model, Scene, WallKind};
pub use scene_file::{load_scene_file, load_scene_file_with, LoadOptions, LoadedScene, MIN_PARTICLES_PER_CELL};
pub use simulate::{diagnostics, simulate, simulate_observed, Diagnostics, ParticleState, Simulation};

/// The items most programs need: `use laparo_mpm::prelude::*;`.
pub mod prelude {
    pub use crate::{
        box_lattice, cfl_dt, diagnostics, ellipsoid_lattice, simulate, simulate_observed, simulate_with_gradient,
        Boundary, FinalLoss, GridSpec, LandmarkLoss, Loss, Material, Matrix, Model, MpmError, ParticleState, Scene,
        Vector, WallKind,
    };
}
