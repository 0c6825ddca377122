//! The two meshes of CPC (thesis §4.4.6 step 3): a regular 2D grid over the ROI pixels and the
//! 3D mesh with the same connectivity, obtained by back-projecting the metric depth.
//!
//! Grid nodes sit at integer pixel centres `(i·s, j·s)`; each grid cell is split into the two
//! triangles `(p00, p10, p01)` and `(p10, p11, p01)` (`pXY`: X along u, Y along v), both with a
//! positive signed area in image coordinates (u right, v down). A triangle is kept when its three
//! corners are in the ROI with valid depth, no edge has a relative depth jump above the threshold,
//! its 3D shape is not degenerate and (guard) it is not seen at a grazing angle.
use crate::error::{CpcError, Result};
use laparo_core::camera::Intrinsics;
use laparo_core::depth::DepthMap;
use laparo_core::image::Mask;
use nalgebra::Vector3;
use rayon::prelude::*;
use serde::Serialize;

/// Sentinel for "no triangle" in [`CpcMesh::cell_faces`].
pub const NO_FACE: u32 = u32::MAX;

/// Parameters of the mesh construction.
#[derive(Clone, Debug, Serialize)]
pub struct MeshParams {
    /// Grid step in px (≥ 1).
    pub grid_step_px: usize,
    /// Drop a triangle if an edge has |z_i − z_j| / min(z_i, z_j) above this (depth discontinuity).
    pub max_rel_depth_jump: f64,
    /// Drop a 3D triangle whose `2·area / longest_edge²` is below this (degenerate / needle).
    pub min_shape_quality: f64,
    /// Grazing guard: drop triangles whose normal makes more than this angle (deg) with the viewing
    /// ray; `None` disables the guard.
    pub max_view_angle_deg: Option<f64>,
    /// Connected components with fewer triangles are dropped (and reported).
    pub min_component_triangles: usize,
}

impl Default for MeshParams {
    fn default() -> Self {
        MeshParams {
            grid_step_px: 4,
            max_rel_depth_jump: 0.1,
            min_shape_quality: 1e-4,
            max_view_angle_deg: Some(85.0),
            min_component_triangles: 8,
        }
    }
}

/// What happened while building the mesh (reported to the user).
#[derive(Clone, Debug, Default, Serialize)]
pub struct MeshReport {
    /// Grid step (px).
    pub grid_step_px: usize,
    /// Triangles whose three corners are inside the ROI.
    pub n_candidate_triangles: usize,
    /// Candidate triangles dropped for a corner without valid depth.
    pub dropped_invalid_depth: usize,
    /// Candidate triangles dropped for a relative depth jump along an edge.
    pub dropped_depth_jump: usize,
    /// Candidate triangles dropped as degenerate in 3D.
    pub dropped_degenerate: usize,
    /// Candidate triangles dropped as seen at a grazing angle (flip guard).
    pub dropped_grazing: usize,
    /// Triangles dropped with connected components below the minimum size.
    pub dropped_small_components: usize,
    /// Vertices of the kept mesh.
    pub n_vertices: usize,
    /// Triangles of the kept mesh.
    pub n_triangles: usize,
    /// Triangle count of every kept connected component (largest first).
    pub component_triangles: Vec<usize>,
}

/// The paired 2D/3D meshes.
#[derive(Clone, Debug)]
pub struct CpcMesh {
    /// Grid step in px.
    pub grid_step_px: usize,
    /// Number of grid nodes along u and v.
    pub grid_cols: usize,
    /// Number of grid nodes along v.
    pub grid_rows: usize,
    /// Initial 2D vertex positions P_init (px, u right, v down).
    pub p_init: Vec<[f64; 2]>,
    /// Back-projected 3D vertices (camera frame, unit of the depth map).
    pub x3d: Vec<Vector3<f64>>,
    /// Triangles (indices into the vertex arrays), positive orientation in the image.
    pub faces: Vec<[usize; 3]>,
    /// Per grid cell (row-major, (grid_cols−1)·(grid_rows−1)): its two triangles or [`NO_FACE`].
    pub cell_faces: Vec<[u32; 2]>,
    /// Connected component of every triangle (0 = largest).
    pub face_component: Vec<usize>,
    /// Construction report.
    pub report: MeshReport,
}

/// Check the inputs shared by every CPC entry point.
pub fn validate_inputs(roi: &Mask, depth: &DepthMap, k: &Intrinsics) -> Result<()> {
    k.validate().map_err(|e| CpcError::invalid("intrinsics", e.to_string()))?;
    if depth.width != roi.width || depth.height != roi.height {
        return Err(CpcError::SizeMismatch(format!(
            "depth is {}x{}, ROI mask is {}x{}",
            depth.width, depth.height, roi.width, roi.height
        )));
    }
    if k.width != depth.width || k.height != depth.height {
        return Err(CpcError::SizeMismatch(format!(
            "intrinsics are for {}x{}, depth is {}x{}",
            k.width, k.height, depth.width, depth.height
        )));
    }
    if roi.channels != 1 {
        return Err(CpcError::invalid("ROI mask", format!("has {} channels, expected 1", roi.channels)));
    }
    if !depth.data.iter().any(|&z| DepthMap::is_valid(z)) {
        return Err(CpcError::invalid("depth", "no valid value (all NaN, zero or negative)"));
    }
    if !roi.data.iter().any(|&b| b) {
        return Err(CpcError::invalid("ROI mask", "is empty"));
    }
    Ok(())
}

impl CpcMesh {
    /// Build the 2D grid and the 3D mesh over `roi` (§4.4.6 step 3).
    pub fn build(roi: &Mask, depth: &DepthMap, k: &Intrinsics, params: &MeshParams) -> Result<CpcMesh> {
        validate_inputs(roi, depth, k)?;
        let s = params.grid_step_px;
        if s == 0 {
            return Err(CpcError::invalid("grid step", "must be at least 1 px"));
        }
        if params.max_rel_depth_jump.is_nan() || params.max_rel_depth_jump <= 0.0 {
            return Err(CpcError::invalid(
                "max relative depth jump",
                format!("{} (must be > 0)", params.max_rel_depth_jump),
            ));
        }
        if let Some(a) = params.max_view_angle_deg {
            if !(a > 0.0 && a <= 90.0) {
                return Err(CpcError::invalid("max view angle", format!("{a} deg (must be in (0, 90])")));
            }
        }
        let (w, h) = (roi.width, roi.height);
        let gc = (w - 1) / s + 1;
        let gr = (h - 1) / s + 1;
        // Grid nodes: in ROI with valid depth?
        let node_in_roi = |i: usize, j: usize| roi.data[(j * s) * w + i * s];
        let node_z = |i: usize, j: usize| depth.data[(j * s) * w + i * s];
        // Back-project every grid node in the ROI once (a node is shared by up to 6 triangles).
        let node_pos: Vec<Vector3<f64>> = (0..gc * gr)
            .into_par_iter()
            .with_min_len(2048)
            .map(|id| {
                let (i, j) = (id % gc, id / gc);
                if node_in_roi(i, j) {
                    k.backproject((i * s) as f64, (j * s) as f64, node_z(i, j))
                } else {
                    Vector3::zeros()
                }
            })
            .collect();
        let node_x = |i: usize, j: usize| node_pos[j * gc + i];
        let mut rep = MeshReport { grid_step_px: s, ..Default::default() };
        let cos_max = params.max_view_angle_deg.map(|a| a.to_radians().cos());
        let nc = gc.saturating_sub(1);
        // Candidate triangles of each grid row (rows in parallel, concatenated in row order: the
        // result does not depend on the thread count), kept ones as `2 · cell + slot` (the grid
        // nodes follow from the cell). Counters: [candidates, invalid depth, depth jump,
        // degenerate, grazing].
        let rows: Vec<(Vec<u32>, [usize; 5])> = (0..gr.saturating_sub(1))
            .into_par_iter()
            .map(|j| {
                let mut kept: Vec<u32> = Vec::with_capacity(2 * nc);
                let mut cnt = [0usize; 5];
                for i in 0..nc {
                    let cell = j * nc + i;
                    for slot in 0..2 {
                        let t = cell_nodes(i, j, slot);
                        if !t.iter().all(|&(a, b)| node_in_roi(a, b)) {
                            continue;
                        }
                        cnt[0] += 1;
                        match triangle_test(
                            t.map(|(a, b)| node_z(a, b)),
                            || t.map(|(a, b)| node_x(a, b)),
                            params,
                            cos_max,
                        ) {
                            Ok(()) => kept.push((2 * cell + slot) as u32),
                            Err(k) => cnt[k] += 1,
                        }
                    }
                }
                (kept, cnt)
            })
            .collect();
        let mut tris: Vec<u32> = Vec::with_capacity(rows.iter().map(|r| r.0.len()).sum());
        for (rt, cnt) in rows {
            tris.extend_from_slice(&rt);
            rep.n_candidate_triangles += cnt[0];
            rep.dropped_invalid_depth += cnt[1];
            rep.dropped_depth_jump += cnt[2];
            rep.dropped_degenerate += cnt[3];
            rep.dropped_grazing += cnt[4];
        }
        // Grid nodes of a kept triangle.
        let tri_nodes = |code: u32| {
            let cell = code as usize / 2;
            cell_nodes(cell % nc, cell / nc, code as usize % 2)
        };
        // Connected components (union–find on grid nodes).
        let n_nodes = gc * gr;
        let mut parent: Vec<u32> = (0..n_nodes as u32).collect();
        fn find(p: &mut [u32], mut a: usize) -> usize {
            while p[a] as usize != a {
                p[a] = p[p[a] as usize];
                a = p[a] as usize;
            }
            a
        }
        let nid = |(a, b): (usize, usize)| b * gc + a;
        for &code in &tris {
            let t = tri_nodes(code);
            let r0 = find(&mut parent, nid(t[0]));
            for &q in &t[1..] {
                let r = find(&mut parent, nid(q));
                if r != r0 {
                    parent[r] = r0 as u32;
                }
            }
        }
        // Triangle count per root (dense over grid nodes: no hashing).
        let mut comp_count = vec![0usize; n_nodes];
        let roots: Vec<u32> = tris.iter().map(|&code| find(&mut parent, nid(tri_nodes(code)[0])) as u32).collect();
        for &r in &roots {
            comp_count[r as usize] += 1;
        }
        let mut comps: Vec<(usize, usize)> =
            comp_count.iter().enumerate().filter(|&(_, &c)| c > 0).map(|(r, &c)| (r, c)).collect();
        comps.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(&b.0)));
        let mut comp_id = vec![usize::MAX; n_nodes];
        for (i, &(r, _)) in comps.iter().enumerate() {
            comp_id[r] = i;
        }
        let mut node_vertex = vec![u32::MAX; n_nodes];
        let nt = tris.len();
        let mut mesh = CpcMesh {
            grid_step_px: s,
            grid_cols: gc,
            grid_rows: gr,
            p_init: Vec::with_capacity(nt / 2 + 2 * gc),
            x3d: Vec::with_capacity(nt / 2 + 2 * gc),
            faces: Vec::with_capacity(nt),
            cell_faces: vec![[NO_FACE; 2]; nc * gr.saturating_sub(1)],
            face_component: Vec::with_capacity(nt),
            report: MeshReport::default(),
        };
        for (&code, &r) in tris.iter().zip(&roots) {
            let c = comp_id[r as usize];
            if comps[c].1 < params.min_component_triangles {
                rep.dropped_small_components += 1;
                continue;
            }
            let mut f = [0usize; 3];
            for (q, fi) in tri_nodes(code).iter().zip(f.iter_mut()) {
                let id = nid(*q);
                if node_vertex[id] == u32::MAX {
                    node_vertex[id] = mesh.p_init.len() as u32;
                    mesh.p_init.push([(q.0 * s) as f64, (q.1 * s) as f64]);
                    mesh.x3d.push(node_x(q.0, q.1));
                }
                *fi = node_vertex[id] as usize;
            }
            mesh.cell_faces[code as usize / 2][code as usize % 2] = mesh.faces.len() as u32;
            mesh.faces.push(f);
            mesh.face_component.push(c);
        }
        rep.component_triangles =
            comps.iter().map(|&(_, n)| n).filter(|&n| n >= params.min_component_triangles).collect();
        rep.n_vertices = mesh.p_init.len();
        rep.n_triangles = mesh.faces.len();
        if mesh.faces.is_empty() {
            return Err(CpcError::invalid(
                "ROI mask",
                format!(
                    "yields no usable triangle at grid step {s} px ({} candidates: {} invalid depth, {} depth jump, \
                     {} degenerate, {} grazing, {} in too small components)",
                    rep.n_candidate_triangles,
                    rep.dropped_invalid_depth,
                    rep.dropped_depth_jump,
                    rep.dropped_degenerate,
                    rep.dropped_grazing,
                    rep.dropped_small_components
                ),
            ));
        }
        mesh.report = rep;
        Ok(mesh)
    }

    /// Number of vertices.
    pub fn n_vertices(&self) -> usize {
        self.p_init.len()
    }

    /// Number of triangles.
    pub fn n_triangles(&self) -> usize {
        self.faces.len()
    }

    /// Number of kept connected components.
    pub fn n_components(&self) -> usize {
        self.report.component_triangles.len()
    }

    /// The triangle of the initial 2D grid containing pixel point `(u, v)` and its barycentric
    /// coordinates, or `None` outside the mesh. O(1) thanks to the regular grid.
    pub fn locate_initial(&self, u: f64, v: f64) -> Option<(usize, [f64; 3])> {
        let s = self.grid_step_px as f64;
        let (gu, gv) = (u / s, v / s);
        if !(gu >= 0.0 && gv >= 0.0) {
            return None;
        }
        let (nc, nr) = (self.grid_cols - 1, self.grid_rows - 1);
        if nc == 0 || nr == 0 {
            return None;
        }
        // Points on a grid line also belong to the cells on its left / above.
        let i = (gu.floor() as usize).min(nc);
        let j = (gv.floor() as usize).min(nr);
        let eps = 1e-12;
        for (di, dj) in [(0usize, 0usize), (1, 0), (0, 1), (1, 1)] {
            if i < di || j < dj {
                continue;
            }
            let (ci, cj) = (i - di, j - dj);
            if ci >= nc || cj >= nr {
                continue;
            }
            let (fu, fv) = (gu - ci as f64, gv - cj as f64);
            if !(fu >= -eps && fv >= -eps && fu <= 1.0 + eps && fv <= 1.0 + eps) {
                continue;
            }
            let cf = self.cell_faces[cj * nc + ci];
            // Triangle 0 = (p00, p10, p01): barycentrics (1−fu−fv, fu, fv).
            if fu + fv <= 1.0 + eps && cf[0] != NO_FACE {
                return Some((cf[0] as usize, [1.0 - fu - fv, fu, fv]));
            }
            // Triangle 1 = (p10, p11, p01): barycentrics w10 = 1 − fv, w11 = fu + fv − 1, w01 = 1 − fu.
            if fu + fv >= 1.0 - eps && cf[1] != NO_FACE {
                return Some((cf[1] as usize, [1.0 - fv, fu + fv - 1.0, 1.0 - fu]));
            }
        }
        None
    }
}

/// Grid nodes (i, j) of triangle `slot` of grid cell (i, j): `(p00, p10, p01)` or `(p10, p11, p01)`.
#[inline(always)]
fn cell_nodes(i: usize, j: usize, slot: usize) -> [(usize, usize); 3] {
    if slot == 0 {
        [(i, j), (i + 1, j), (i, j + 1)]
    } else {
        [(i + 1, j), (i + 1, j + 1), (i, j + 1)]
    }
}

/// Whether a candidate triangle (corner depths `z`, 3D corners from `x`) is kept; otherwise the
/// index of the report counter of the reason: 1 invalid depth, 2 depth jump, 3 degenerate,
/// 4 grazing.
#[inline(always)]
fn triangle_test(
    z: [f64; 3],
    x: impl FnOnce() -> [Vector3<f64>; 3],
    params: &MeshParams,
    cos_max: Option<f64>,
) -> std::result::Result<(), usize> {
    if !z.iter().all(|&v| DepthMap::is_valid(v)) {
        return Err(1);
    }
    let jump = |a: f64, b: f64| (a - b).abs() / a.min(b);
    if jump(z[0], z[1]) > params.max_rel_depth_jump
        || jump(z[1], z[2]) > params.max_rel_depth_jump
        || jump(z[0], z[2]) > params.max_rel_depth_jump
    {
        return Err(2);
    }
    let x = x();
    let n = (x[1] - x[0]).cross(&(x[2] - x[0]));
    let area2 = n.norm();
    let lmax = (x[1] - x[0]).norm_squared().max((x[2] - x[1]).norm_squared()).max((x[0] - x[2]).norm_squared());
    if !(area2.is_finite() && area2 > params.min_shape_quality * lmax) {
        return Err(3);
    }
    if let Some(cmax) = cos_max {
        let c = (x[0] + x[1] + x[2]) / 3.0;
        let cosv = n.dot(&c).abs() / (area2 * c.norm());
        if cosv < cmax {
            return Err(4);
        }
    }
    Ok(())
}

/// Signed area of the 2D triangle (a, b, c) in px² (positive for the grid orientation).
#[inline]
pub fn signed_area(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))
}
