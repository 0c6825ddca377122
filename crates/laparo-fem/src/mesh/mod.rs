//! Tetrahedralisation of closed surfaces, mesh quality and incisions (thesis §5.4.2).
//!
//! - [`geom`]: closed-surface check, inside test (ray parity, majority of three axes), exact
//!   closest point, ray casting, dihedral angles.
//! - [`tetra`]: BCC-lattice tetrahedralisation with boundary snapping ([`tetrahedralize`]) and the
//!   [`QualityReport`].
//! - [`incision`]: a [`Blade`] cracks a tet mesh along existing faces ([`cut`] → [`CutMesh`]), lip
//!   curves and [`Landmarks`].
//! - [`scenario`]: the non-anatomical and anatomical benchmark cuts on the P2ILF liver.
//! - [`shapes`]: closed test surfaces (box, icosphere).
pub mod geom;
pub mod incision;
pub mod scenario;
pub mod shapes;
pub mod tetra;

pub use geom::{check_closed, Surface};
pub use incision::{cut, Blade, CutMesh, Landmark, Landmarks};
pub use scenario::{
    anatomical, anatomical_on, anterior_from_vertices, fixed_posterior_nodes, non_anatomical, non_anatomical_on,
    AnatomicalParams, NonAnatomicalParams, Scenario, ScenarioFrame, Sphere, P2ILF_ANTERIOR, P2ILF_CONTOUR_VERTICES,
    THICKNESS_WINDOW_MM,
};
pub use tetra::{
    orient_outward, quality_report, tetrahedralize, tetrahedralize_surface, Percentile, QualityReport, TetraParams,
};
