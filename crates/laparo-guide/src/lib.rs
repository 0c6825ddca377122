//! laparo-guide — the guidance pipeline of thesis §5.4.3 (Fig. 5.10) in silico, with ground truth:
//! a scenario generator ([`scenario`]: the patient liver with a tumour, before and after an incision,
//! rendered as an uncalibrated stereo laparoscope pair by [`render`]) and the pipeline
//! ([`pipeline`]: stereo → depth → rigid alignment → incision landmarks → lips targets →
//! RODS-MPM → deformed liver and tumour → overlay), with the errors of every stage and an HTML report
//! ([`report`]).
//!
//! The most used names are in [`prelude`]. The renderer gives the exact depth of what it draws: a
//! plane `z = 100 + x / 2` (mm) seen by a pinhole camera at the origin is at
//! `z = 100 / (1 − (u − c_x) / (2 f))` at pixel column `u`:
//!
//! ```
//! use laparo_core::{Image, Intrinsics};
//! use laparo_guide::prelude::*;
//! use nalgebra::{Matrix3, Vector3};
//!
//! let k = Intrinsics::new(80.0, 80.0, 31.5, 23.5, 64, 48)?;
//! let view = View { k, r: Matrix3::identity(), t: Vector3::zeros() };
//! let plane = |x: f64, y: f64| Vector3::new(x, y, 100.0 + 0.5 * x);
//! let vertices = [plane(-100.0, -100.0), plane(100.0, -100.0), plane(100.0, 100.0), plane(-100.0, 100.0)];
//! let (faces, uv) = ([[0, 1, 2], [0, 2, 3]], [[0.0, 0.0], [7.0, 0.0], [7.0, 7.0], [0.0, 7.0]]);
//! let mesh = Textured { vertices: &vertices, faces: &faces, uv: &uv, tint: &[[1.0; 3]; 2], label: 1 };
//! let r = render(&view, &[mesh], &Image::filled(8, 8, 3, 128u8));
//! for (u, v) in [(0, 0), (31, 23), (63, 47), (10, 40)] {
//!     let z = 100.0 / (1.0 - 0.5 * (u as f64 - 31.5) / 80.0);
//!     assert!((r.depth_mm.get(u, v, 0) - z).abs() < 1e-6, "({u}, {v}): {} vs {z}", r.depth_mm.get(u, v, 0));
//!     assert_eq!(r.label.get(u, v, 0), 1);
//! }
//! # Ok::<(), laparo_core::CoreError>(())
//! ```
#![warn(missing_docs)]
// `!(x > 0.0)` is the NaN-rejecting check used on inputs.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod deformation;
pub mod end_to_end;
mod error;
pub mod pipeline;
pub mod render;
pub mod report;
pub mod scenario;
pub mod tetmesh;

pub use error::{GuideError, Result};

/// The types and functions most programs need: `use laparo_guide::prelude::*;`.
pub mod prelude {
    pub use crate::deformation::{synthetic_incision, Deformation, IncisionSpec};
    pub use crate::error::{GuideError, Result};
    pub use crate::pipeline::{GuideConfig, GuideReport, Route};
    pub use crate::render::{render, Rendered, Textured, View};
    pub use crate::scenario::{default_incision, generate, ScenarioConfig};
    pub use crate::tetmesh::{grid_tet_mesh, GridTetMesh};
}
