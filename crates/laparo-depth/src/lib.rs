//! laparo-depth — RoDEM: accuracy and robustness evaluation of monocular depth estimation
//! in surgery (thesis §2.3.3, §3.2, Appendix C).

pub mod align;
pub mod error;
pub mod eval;
pub mod fastmath;
pub mod manifest;
pub mod metrics;
pub mod perturb;
pub mod report;
pub mod reproject;
pub mod robustness;
pub mod synthetic;
