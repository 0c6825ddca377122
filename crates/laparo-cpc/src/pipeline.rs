//! The whole CPC pipeline (§4.4.6 steps 3–5) on one frame: meshes → system → λ (fixed or
//! automatic, §4.5.4) → convex solve (eq. 4.11) → optional equiareal refinement (eq. 4.9) → warp.
use crate::conformal::ConformalParams;
use crate::equiareal::{refine, EquiarealParams};
use crate::error::{CpcError, Result};
use crate::lambda::{auto_lambda, default_lambda_grid, LambdaSweep};
use crate::mesh::{CpcMesh, MeshParams, MeshReport};
use crate::metrics;
use crate::solve::{validate_lambda, CpcSolver};
use crate::warp::Warp;
use laparo_core::camera::Intrinsics;
use laparo_core::depth::DepthMap;
use laparo_core::image::{Image, Mask};
use laparo_core::remap::Interp;
use serde::Serialize;
use std::collections::BTreeMap;
use std::time::Instant;

/// How λ is chosen.
#[derive(Clone, Debug, Serialize)]
pub enum LambdaChoice {
    /// A fixed λ ∈ [0, 1).
    Fixed(f64),
    /// Automatic selection (§4.5.4) over this λ grid.
    Auto(Vec<f64>),
}

/// Default λ when none is given: strongly conformal while keeping the scale (see README).
pub const DEFAULT_LAMBDA: f64 = 0.95;

/// All parameters of a CPC run.
#[derive(Clone, Debug, Serialize)]
pub struct CpcParams {
    /// Mesh construction (grid step, triangle filters).
    pub mesh: MeshParams,
    /// Conformal basis (θ, row convention).
    pub conformal: ConformalParams,
    /// λ: fixed or selected automatically (§4.5.4).
    pub lambda: LambdaChoice,
    /// Equiareal refinement (eq. 4.9); `None` (default) keeps the convex solution.
    pub equiareal: Option<EquiarealParams>,
    /// Near-grazing guard: output pixels of triangles whose local magnification (largest singular
    /// value of the original → warped affine map) exceeds this multiple of the median over the
    /// mesh are masked out of the warped image and its validity mask (no rim spikes); `None`
    /// keeps every triangle. Default [`DEFAULT_MAX_REL_MAGNIFICATION`].
    pub max_rel_magnification: Option<f64>,
    /// Which similarity is applied to the flattening before warping (the conformal term and
    /// every angle are unchanged by it). Default [`ScaleRestore::Resolution`].
    pub scale: ScaleRestore,
    /// Interpolation of the warped image. Default bicubic: bilinear resampling at sub-pixel
    /// offsets blurs fine texture enough to cost a third of the SIFT/ORB keypoints on a
    /// near-identity warp (measured on `laparo cpc pair --kind easy`, see the crate README).
    pub interp: Interp,
}

/// The scale of the warped image. The convex solve (eq. 4.11) changes the global scale with λ
/// (the shrink of the thesis' Fig. 4.11); a similarity fixes it without touching angles.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum ScaleRestore {
    /// The raw solve of eq. 4.11 (the thesis' warp).
    Raw,
    /// The original total ROI area ([`metrics::restore_scale`]): an oblique view is then
    /// downsampled along its unforeshortened direction by √cos θ, losing fine texture.
    TotalArea,
    /// No local minification at the area-weighted median triangle
    /// ([`metrics::restore_resolution`]): foreshortened directions are stretched, none is
    /// downsampled, and views of the same surface at the same distance get the same scale.
    Resolution,
}

impl std::str::FromStr for ScaleRestore {
    type Err = CpcError;
    /// `raw`, `area` or `resolution`.
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "raw" => Ok(ScaleRestore::Raw),
            "area" => Ok(ScaleRestore::TotalArea),
            "resolution" => Ok(ScaleRestore::Resolution),
            o => Err(CpcError::invalid("scale", format!("'{o}' is not raw, area or resolution"))),
        }
    }
}

/// Default limit of [`CpcParams::max_rel_magnification`]: a triangle stretched 4× more than the
/// median triangle of the warp is treated as a smeared rim triangle.
pub const DEFAULT_MAX_REL_MAGNIFICATION: f64 = 4.0;

impl Default for CpcParams {
    fn default() -> Self {
        CpcParams {
            mesh: MeshParams::default(),
            conformal: ConformalParams::default(),
            lambda: LambdaChoice::Fixed(DEFAULT_LAMBDA),
            equiareal: None,
            max_rel_magnification: Some(DEFAULT_MAX_REL_MAGNIFICATION),
            scale: ScaleRestore::Resolution,
            interp: Interp::Bicubic,
        }
    }
}

impl CpcParams {
    /// Automatic λ over the default grid.
    pub fn auto_lambda() -> LambdaChoice {
        LambdaChoice::Auto(default_lambda_grid())
    }
}

/// Figures of one CPC run (written as `stats.json` by the CLI).
#[derive(Clone, Debug, Serialize)]
pub struct CpcStats {
    /// λ used for the solve.
    pub lambda: f64,
    /// Vertices of the mesh.
    pub n_vertices: usize,
    /// Triangles of the mesh.
    pub n_triangles: usize,
    /// Connected components of the mesh.
    pub n_components: usize,
    /// Mean |2D corner angle − 3D corner angle| (deg) of the initial grid.
    pub angle_error_deg_before: f64,
    /// Same for the flattened mesh.
    pub angle_error_deg_after: f64,
    /// δ_area (eq. 4.13) of the flattened mesh.
    pub delta_area: f64,
    /// Number of flipped triangles of the flattened mesh.
    pub n_flipped: usize,
    /// Mean vertex displacement |p − P_init| (px).
    pub mean_displacement_px: f64,
    /// Maximum vertex displacement (px).
    pub max_displacement_px: f64,
    /// Width of the output canvas (px).
    pub canvas_width: usize,
    /// Height of the output canvas (px).
    pub canvas_height: usize,
    /// Flattened coordinates of canvas pixel (0, 0).
    pub canvas_origin: [f64; 2],
    /// Iterations of the equiareal refinement (0 without it).
    pub equiareal_iterations: usize,
    /// Triangles masked out by the magnification limit ([`CpcParams::max_rel_magnification`]).
    pub n_magnified_masked: usize,
    /// Uniform scale applied by [`CpcParams::scale`] (1 for [`ScaleRestore::Raw`]).
    pub scale_restored: f64,
    /// Warnings (e.g. the automatic λ fell back to a fixed value); the CLI prints them.
    pub warnings: Vec<String>,
    /// What happened while building the mesh.
    pub mesh: MeshReport,
    /// Wall time of each stage (ms), by stage name.
    pub timings_ms: BTreeMap<String, f64>,
}

/// Output of [`cpc_warp`].
pub struct CpcResult {
    /// The piecewise-affine warp (flattened mesh, canvas).
    pub warp: Warp,
    /// The warped image on the canvas.
    pub warped: Image<u8>,
    /// Canvas pixels covered by the warped mesh.
    pub mask: Mask,
    /// Summary numbers of the run.
    pub stats: CpcStats,
    /// The λ sweep when λ was selected automatically.
    pub sweep: Option<LambdaSweep>,
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// Run CPC on one frame: `image` (any channels), metric `depth`, intrinsics `k`, ROI `roi`.
pub fn cpc_warp(
    image: &Image<u8>,
    depth: &DepthMap,
    k: &Intrinsics,
    roi: &Mask,
    params: &CpcParams,
) -> Result<CpcResult> {
    cpc_warp_with(&mut CpcSolver::new(), image, depth, k, roi, params)
}

/// [`cpc_warp`] for the frames of a video: `solver` keeps the mesh topology (sparsity pattern,
/// ordering, symbolic factorisation, factor buffers) of the previous frame and reuses it when the
/// new mesh has the same topology (same ROI and kept triangles); the result is the same.
pub fn cpc_warp_with(
    solver: &mut CpcSolver,
    image: &Image<u8>,
    depth: &DepthMap,
    k: &Intrinsics,
    roi: &Mask,
    params: &CpcParams,
) -> Result<CpcResult> {
    // The whole frame on a pool worker (its parallel stages are not injected one by one).
    laparo_core::par::on_pool(|| frame(solver, image, depth, k, roi, params))
}

fn frame(
    solver: &mut CpcSolver,
    image: &Image<u8>,
    depth: &DepthMap,
    k: &Intrinsics,
    roi: &Mask,
    params: &CpcParams,
) -> Result<CpcResult> {
    if image.width != depth.width || image.height != depth.height {
        return Err(CpcError::SizeMismatch(format!(
            "image is {}x{}, depth is {}x{}",
            image.width, image.height, depth.width, depth.height
        )));
    }
    if let LambdaChoice::Fixed(l) = params.lambda {
        validate_lambda(l)?;
    }
    let mut timings = BTreeMap::new();
    let t = Instant::now();
    let mesh = CpcMesh::build(roi, depth, k, &params.mesh)?;
    timings.insert("mesh".to_string(), ms(t));
    let t = Instant::now();
    let system = solver.assemble(&mesh, &params.conformal)?;
    timings.insert("assemble".to_string(), ms(t));
    let mut sweep = None;
    let mut warnings = Vec::new();
    let lambda = match &params.lambda {
        LambdaChoice::Fixed(l) => *l,
        LambdaChoice::Auto(grid) => {
            let t = Instant::now();
            let s = auto_lambda(&system, &mesh, grid)?;
            timings.insert("lambda_sweep".to_string(), ms(t));
            let l = s.ell;
            warnings.extend(s.warning.clone());
            sweep = Some(s);
            l
        }
    };
    let t = Instant::now();
    let mut p = system.solve(lambda)?;
    timings.insert("solve".to_string(), ms(t));
    let mut eq_iters = 0;
    if let Some(ep) = &params.equiareal {
        let t = Instant::now();
        let r = refine(&system, &mesh, &p, lambda, ep)?;
        p = r.p;
        eq_iters = r.iterations;
        timings.insert("equiareal".to_string(), ms(t));
    }
    let scale_restored = match params.scale {
        ScaleRestore::Raw => 1.0,
        ScaleRestore::TotalArea => metrics::restore_scale(&mut p, &mesh.p_init, &mesh.faces),
        ScaleRestore::Resolution => metrics::restore_resolution(&mut p, &mesh.p_init, &mesh.faces),
    };
    let t = Instant::now();
    let mut warp = Warp::new(&mesh, p, image.width, image.height)?;
    let n_magnified_masked = match params.max_rel_magnification {
        Some(limit) => warp.mask_magnified(limit)?,
        None => 0,
    };
    let (warped, mask) = warp.warp_image_with(image, params.interp)?;
    timings.insert("warp".to_string(), ms(t));
    let p = &warp.p_flat;
    let (mean_d, max_d) = metrics::displacement_px(p, &mesh.p_init);
    let stats = CpcStats {
        lambda,
        n_vertices: mesh.n_vertices(),
        n_triangles: mesh.n_triangles(),
        n_components: mesh.n_components(),
        angle_error_deg_before: metrics::angle_error_deg(&mesh.p_init, &mesh.x3d, &mesh.faces),
        angle_error_deg_after: metrics::angle_error_deg(p, &mesh.x3d, &mesh.faces),
        delta_area: metrics::delta_area(p, &mesh.p_init, &mesh.faces),
        n_flipped: metrics::n_flipped(p, &mesh.faces),
        mean_displacement_px: mean_d,
        max_displacement_px: max_d,
        canvas_width: warp.width,
        canvas_height: warp.height,
        canvas_origin: warp.origin,
        equiareal_iterations: eq_iters,
        n_magnified_masked,
        scale_restored,
        warnings,
        mesh: mesh.report.clone(),
        timings_ms: timings,
    };
    Ok(CpcResult { warp, warped, mask, stats, sweep })
}
