//! laparo-cpc — Conformal Perspective Correction (thesis Ch. 4).
//!
//! Given an image, its metric depth, the intrinsics and a region of interest, CPC computes a
//! virtual, locally fronto-parallel image of the surface by conformal flattening while limiting
//! resampling (§4.4). Pipeline (§4.4.6): [`mesh`] (2D grid + 3D mesh) → [`conformal`] (M_t,
//! eq. 4.6) → [`solve`] (convex least-displacement solve, eqs. 4.11/4.12, on the nested-dissection
//! [`ordering`]) → optional [`equiareal`] refinement (eqs. 4.8/4.9) → [`warp`] (piecewise-affine
//! texture mapping). [`lambda`] selects λ automatically (§4.5.4); [`scene`] renders synthetic test
//! scenes. [`cpc_warp`] runs the whole pipeline on one frame, [`cpc_warp_with`] on the frames of a
//! video with one [`CpcSolver`] (which reuses the mesh topology and owns its factor buffers).
//!
//! ```
//! use laparo_cpc::prelude::*;
//!
//! // The bumpy bowl of ../shared/bench/cpc_ref/scene.py (640×480, depth in mm), 16 px grid.
//! let scene = laparo_cpc::scene::bumpy_bowl_spec().render().unwrap();
//! let mut params = CpcParams::default();
//! params.mesh.grid_step_px = 16;
//! let r = cpc_warp(&scene.image, &scene.depth, &scene.intrinsics, &scene.roi, &params).unwrap();
//! // The flattened mesh keeps the 3D corner angles better than the image grid does (§4.4).
//! assert!(r.stats.angle_error_deg_after < r.stats.angle_error_deg_before);
//! assert!(r.mask.count() > 0);
//! ```
#![warn(missing_docs)]

pub mod conformal;
mod dd;
pub mod equiareal;
pub mod error;
pub mod eval;
mod factor_buffers;
pub mod lambda;
pub mod mesh;
pub mod metrics;
pub mod ordering;
pub mod pipeline;
pub mod scene;
pub mod solve;
mod topology;
pub mod warp;

pub use conformal::{ConformalParams, RowConvention};
pub use error::{CpcError, Result};
pub use mesh::{CpcMesh, MeshParams, MeshReport};
pub use pipeline::{
    cpc_warp, cpc_warp_with, CpcParams, CpcResult, CpcStats, LambdaChoice, ScaleRestore, DEFAULT_LAMBDA,
};
pub use solve::{CpcSolver, CpcSystem, CpcTopology};
pub use warp::{Warp, WarpMaps};

/// The types and functions most programs need: `use laparo_cpc::prelude::*;`.
pub mod prelude {
    pub use crate::conformal::ConformalParams;
    pub use crate::error::{CpcError, Result};
    pub use crate::mesh::{CpcMesh, MeshParams};
    pub use crate::pipeline::{cpc_warp, cpc_warp_with, CpcParams, CpcResult, CpcStats, LambdaChoice};
    pub use crate::solve::{CpcSolver, CpcSystem};
    pub use crate::warp::Warp;
}
