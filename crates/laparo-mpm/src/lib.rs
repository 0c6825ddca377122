//! laparo-mpm — differentiable MLS-MPM with exact gradients, 2D and 3D (thesis §5.2.3–5.2.4, §5.3.2,
//! eqs. 5.3–5.7).
//!
//! A [`Scene`] holds particles, material, grid, boundary conditions, Δt and the horizon T;
//! [`simulate`] runs it; [`simulate_with_gradient`] also returns the exact gradient of a [`Loss`]
//! on particle positions with respect to the initial velocities and positions, E and ν, by a
//! hand-derived adjoint of every stage (see README.md).
// `!(a > b)` comparisons are deliberate: they also reject NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]
pub mod adjoint;
pub mod backward;
pub mod cfl;
pub mod constitutive;
pub mod error;
pub mod fixed_corotated;
pub mod g2p;
pub mod grid_update;
pub mod linalg;
pub mod loss;
pub mod neo_hookean;
pub mod p2g;
pub mod reference;
pub mod render;
pub mod sampling;
pub mod scene;
pub mod scene_file;
pub mod simulate;
pub mod sparse_grid;

pub use adjoint::{simulate_with_gradient, simulate_with_gradient_in, GradientResult, GradientWorkspace};
pub use cfl::{cfl_dt, Warning};
pub use constitutive::{lame, ConstitutiveModel};
pub use error::MpmError;
pub use fixed_corotated::FixedCorotated;
pub use linalg::{Matrix, Vector};
pub use loss::{FinalLoss, LandmarkLoss, Loss, StepsLoss};
pub use neo_hookean::NeoHookean;
pub use scene::{box_lattice, ellipsoid_lattice, Boundary, GridSpec, Material, Model, Scene, WallKind};
pub use simulate::{diagnostics, simulate, simulate_observed, Diagnostics, ParticleState, Simulation};
