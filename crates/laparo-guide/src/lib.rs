//! laparo-guide — the guidance pipeline of thesis §5.4.3 (Fig. 5.10) in silico, with ground truth:
//! a scenario generator ([`scenario`]: the patient liver with a tumour, before and after an incision,
//! rendered as an uncalibrated stereo laparoscope pair by [`render`]) and the pipeline
//! ([`pipeline`]: stereo → depth → rigid alignment → incision landmarks → lips targets →
//! RODS-MPM → deformed liver and tumour → overlay), with the errors of every stage and an HTML report
//! ([`report`]).
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
