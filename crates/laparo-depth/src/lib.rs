//! laparo-depth — RoDEM: accuracy and robustness evaluation of monocular depth estimation
//! in surgery (thesis §2.3.3, §3.2, Appendix C).
//!
//! * one prediction against one ground truth: [`evaluate_pair`] (the metrics of
//!   `depth_eval_ref.py`: Abs Rel, Sq Rel, RMSE, RMSE log, SILog, δ_t; eqs. 3.1–3.2) under the
//!   three alignments of [`Alignment`] (none, scale, scale and shift);
//! * a whole benchmark: a [`Manifest`] (scaffolded from a folder layout) evaluated by
//!   [`evaluate_manifest`], summarised with mCE/mRR ([`robustness`], eqs. 3.3–3.4) and written
//!   as tables and figures by [`report`];
//! * dataset tools: seeded synthetic perturbations ([`perturb`]), depth-sensor to laparoscope
//!   reprojection ([`reproject`]) and synthetic scenes ([`synthetic`]).
//!
//! ```
//! use laparo_depth::prelude::*;
//!
//! // Ground-truth depth (m) and a prediction that is exactly its inverse depth (disparity up to
//! // scale 1): without alignment every metric is perfect.
//! let gt = [0.05, 0.10, 0.20, 0.25];
//! let pred: Vec<f64> = gt.iter().map(|z| 1.0 / z).collect();
//! let r = evaluate_pair(&pred, PredKind::Disparity, &gt, None, &PairOptions::default()).unwrap();
//! assert_eq!(r.n_valid, 4);
//! let m = r.get(Alignment::None).unwrap();
//! assert!(m.abs_rel.abs() < 1e-12 && m.rmse.abs() < 1e-12);
//! // Twice the disparity halves every depth: Abs Rel = mean(|z − z/2| / z) = 0.5 without
//! // alignment, 0 once the scale is fitted (s = med(1/z) / med(2/z) = 1/2).
//! let pred2: Vec<f64> = pred.iter().map(|d| 2.0 * d).collect();
//! let r = evaluate_pair(&pred2, PredKind::Disparity, &gt, None, &PairOptions::default()).unwrap();
//! assert!((r.get(Alignment::None).unwrap().abs_rel - 0.5).abs() < 1e-12);
//! assert!(r.get(Alignment::Scale).unwrap().abs_rel.abs() < 1e-12);
//! ```
#![warn(missing_docs)]

pub mod align;
pub mod error;
pub mod eval;
mod fastmath;
pub mod manifest;
pub mod metrics;
pub mod perturb;
pub mod report;
pub mod reproject;
pub mod robustness;
pub mod synthetic;

pub use align::{AlignParams, Alignment, DepthRange, PredKind};
pub use error::{DepthError, Result};
pub use eval::{evaluate_files, evaluate_manifest, EvalConfig, EvalOutput};
pub use manifest::{scaffold, Manifest, ScaffoldOptions};
pub use metrics::{evaluate_pair, InvalidPredPolicy, Metrics, PairMetrics, PairOptions, METRIC_NAMES};
pub use perturb::Perturbation;

/// The types and functions most programs need: `use laparo_depth::prelude::*;`.
pub mod prelude {
    pub use crate::align::{Alignment, DepthRange, PredKind};
    pub use crate::error::{DepthError, Result};
    pub use crate::eval::{evaluate_files, evaluate_manifest, EvalConfig, EvalOutput};
    pub use crate::manifest::{scaffold, Manifest, ScaffoldOptions};
    pub use crate::metrics::{evaluate_pair, InvalidPredPolicy, Metrics, PairMetrics, PairOptions, METRIC_NAMES};
    pub use crate::perturb::Perturbation;
}
