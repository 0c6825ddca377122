//! laparo-cpc — Conformal Perspective Correction (thesis Ch. 4).
//!
//! Given an image, its metric depth, the intrinsics and a region of interest, CPC computes a
//! virtual, locally fronto-parallel image of the surface by conformal flattening while limiting
//! resampling (§4.4). Pipeline (§4.4.6): [`mesh`] (2D grid + 3D mesh) → [`conformal`] (M_t,
//! eq. 4.6) → [`solve`] (convex least-displacement solve, eqs. 4.11/4.12) → optional
//! [`equiareal`] refinement (eqs. 4.8/4.9) → [`warp`] (piecewise-affine texture mapping).
//! [`lambda`] selects λ automatically (§4.5.4); [`scene`] renders synthetic test scenes.
pub mod conformal;
pub mod dd;
pub mod equiareal;
pub mod error;
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
pub use pipeline::{cpc_warp, cpc_warp_with, CpcParams, CpcResult, CpcStats};
pub use solve::{CpcSolver, CpcSystem, CpcTopology};
pub use warp::{Warp, WarpMaps};
