//! laparo-register — RODS-MPM deformable registration (thesis Ch. 5, §5.3 eqs. 5.8–5.10, §5.4, App. A).
//!
//! An organ is sampled into particles ([`organ`]); source landmark particles are scored against
//! their targets (points, polylines, triangle surfaces, point clouds) with the mean unsquared
//! distance of eq. 5.10 ([`loss`], [`distance`]); the initial velocities v₀ (and optionally E) are
//! optimised through `laparo-mpm`'s exact adjoint ([`optimize`]); the result is transferred to
//! arbitrary points such as a tumour ([`transfer`]), turned into a display surface ([`surface`]) and
//! projected over a laparoscopic image ([`overlay`]). [`rigid`] gives the initial rigid alignment
//! (Umeyama, ICP, RANSAC floor plane, gravity projection); [`fig55`] the 2D set-ups of Fig. 5.5.
//!
//! ```
//! use laparo_register::prelude::*;
//! use laparo_mpm::prelude::*;
//! use std::sync::Arc;
//!
//! // 2D block of 16×8 particles; its right-edge middle particle must move right by 0.4 Δx.
//! let grid = GridSpec::unit(32);
//! let mat = Material { model: Model::NeoHookean, youngs_modulus: 5.0, poisson_ratio: 0.3, density: 1.0 };
//! let s = grid.dx / 2.0;
//! let x0 = box_lattice(Vector::<2>::new(0.4, 0.45), Vector::<2>::new(0.4 + 16.0 * s, 0.45 + 8.0 * s), s);
//! let scene = Scene::new(x0, s * s, mat, grid, cfl_dt(&mat, grid.dx, 0.3), 20);
//! let p = nearest_particles(&scene.positions, &[Vector::<2>::new(0.6, 0.5)])[0];
//! let target = scene.positions[p] + Vector::<2>::new(0.4 * grid.dx, 0.0);
//! let loss = RegistrationLoss::new(vec![LandmarkGroup {
//!     name: "tip".into(),
//!     particles: vec![p],
//!     target: GroupTarget::Shared(Arc::new(Polyline::open(vec![target]))),
//!     weight: 1.0,
//! }]);
//! let cfg = OptimizerConfig { iterations: 15, ..Default::default() };
//! let r = register(&scene, &loss, &cfg, None, &mut |_, _| true)?;
//! assert!(r.history.last().unwrap().mean_distance < 0.5 * r.history[0].mean_distance);
//! # Ok::<(), laparo_register::RegisterError>(())
//! ```
#![warn(missing_docs)]
#![allow(clippy::neg_cmp_op_on_partial_ord)]
// Index loops over several parallel arrays read better than zipped iterators here.
#![allow(clippy::needless_range_loop)]

pub mod baselines;
pub mod benchmark;
pub mod bump;
pub mod crack;
pub mod distance;
mod error;
pub mod fig55;
pub mod io;
pub mod loss;
pub mod optimize;
pub mod organ;
pub mod overlay;
pub mod pipeline;
pub mod rigid;
pub mod smoothing;
pub mod surface;
pub mod transfer;

pub use error::{RegisterError, Result};

fn io_ext(path: &std::path::Path) -> String {
    path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase()
}

/// Nearest particle to each annotated source point (deterministic: ties to the smallest index).
pub fn nearest_particles<const D: usize>(
    positions: &[laparo_mpm::Vector<D>],
    points: &[laparo_mpm::Vector<D>],
) -> Vec<usize> {
    let cloud = distance::PointCloud::new(positions.to_vec());
    points.iter().map(|q| distance::ClosestPoint::closest(&cloud, q).1).collect()
}

/// The items most programs need.
pub mod prelude {
    pub use crate::distance::{ClosestPoint, PointCloud, Polyline, TriangleSurface};
    pub use crate::loss::{GroupTarget, LandmarkGroup, RegionTerm, RegistrationLoss};
    pub use crate::nearest_particles;
    pub use crate::optimize::{register, OptimizerConfig, OptimizerKind, Registration};
    pub use crate::RegisterError;
}
