//! laparo-depth — RoDEM: accuracy and robustness evaluation of monocular depth estimation
//! in surgery (thesis §2.3.3, §3.2, Appendix C).

pub mod perturb;
pub mod reproject;
pub mod synthetic;
pub mod align;
pub mod error;
pub mod metrics;
pub mod robustness;
pub mod manifest;
pub mod eval;
pub mod report;
pub mod bench;
pub mod fastmath;
