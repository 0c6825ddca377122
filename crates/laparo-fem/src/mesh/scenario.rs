//! The two incision scenarios of the in-silico benchmark (thesis §5.4.2; register.md §4 proposed
//! defaults): (i) non-anatomical resection around a virtual tumour with a 1 cm margin, (ii)
//! anatomical (Cantlie-like planar) cut; plus the fixed posterior region.
//!
//! Orientation. "Anterior" is a unit axis `a` given by the caller ([`ScenarioFrame::anterior`]). For
//! the P2ILF liver it is [`P2ILF_ANTERIOR`]: the direction from the volume centroid to the centroid
//! of all 19 vertices of the three contours of `patient2_1_3D-contours.json` (two ridge contours =
//! the anterior inferior margin, one falciform-ligament contour on the anterior surface), see
//! [`anterior_from_vertices`]; it is ≈ −y (−0.92), as in an LPS scanner frame. The **entry point** `P` is where the line
//! through the volume centroid along `a` leaves the organ on the anterior side; the **fixed region**
//! is the `fixed_fraction` (15 %) of outer-surface nodes with the smallest coordinate along `a`
//! (the posterior face, around the IVC).
use super::geom::{ray_hits, tet_signed_volume};
use super::incision::{cut, Blade, CutMesh};
use crate::error::{FemError, Result};
use laparo_core::mesh::{TetMesh, TriMesh};
use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};
use std::collections::BTreeSet;

type V3 = Vector3<f64>;

/// Anterior axis of the P2ILF `patient2_1_3d-liver-model.obj` (unit, model frame), from
/// [`anterior_from_vertices`] with the contour vertices [`P2ILF_CONTOUR_VERTICES`] (checked
/// against the data by a test).
pub const P2ILF_ANTERIOR: [f64; 3] = [0.3177509466289188, -0.9224989691278731, 0.21915744996334782];

/// Vertex ids (0-based) of the three contours (ridge, ridge, falciform ligament) of
/// `patient2_1_3D-contours.json`.
pub const P2ILF_CONTOUR_VERTICES: [usize; 19] =
    [1227, 1544, 1626, 1635, 2012, 1942, 2013, 2132, 2151, 2164, 2254, 2438, 2514, 2709, 2744, 2774, 2866, 2885, 2922];

/// Unit axis from the volume centroid of the closed surface `surface` to the mean of `ids`.
pub fn anterior_from_vertices(surface: &TriMesh, ids: &[usize]) -> Result<V3> {
    if ids.is_empty() || ids.iter().any(|&i| i >= surface.vertices.len()) {
        return Err(FemError::bad(
            "anterior vertices",
            format!("empty or out of range for {} vertices", surface.vertices.len()),
        ));
    }
    let c = surface.volume_centroid();
    let m = ids.iter().map(|&i| surface.vertices[i]).sum::<V3>() / ids.len() as f64;
    Ok((m - c).normalize())
}

/// Orientation of a scenario on the organ.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(default)]
pub struct ScenarioFrame {
    /// Anterior axis (normalised on use).
    pub anterior: [f64; 3],
    /// Fraction of outer-surface nodes fixed, the most posterior ones.
    pub fixed_fraction: f64,
    /// Blade overshoot above the surface (mm).
    pub overshoot_mm: f64,
    /// Mouth polyline samples.
    pub samples: usize,
}

impl Default for ScenarioFrame {
    fn default() -> Self {
        ScenarioFrame { anterior: P2ILF_ANTERIOR, fixed_fraction: 0.15, overshoot_mm: 10.0, samples: 61 }
    }
}

/// (i) Non-anatomical resection (register.md §4): a virtual tumour sphere and a curved,
/// wedge-like cut at `margin_mm` outside it.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(default)]
pub struct NonAnatomicalParams {
    /// Tumour radius (mm).
    pub tumour_radius_mm: f64,
    /// Depth of the tumour centre under the entry point, along the inward surface normal (mm).
    pub tumour_depth_mm: f64,
    /// Oncologic margin: distance of the blade's deep edge from the tumour surface (mm).
    pub margin_mm: f64,
    /// Length of the incision on the surface (mm).
    pub length_mm: f64,
    /// Blade depth below the surface (mm).
    pub depth_mm: f64,
    /// Inward tilt of the blade towards the tumour axis (deg): the mouth lies on a circle of radius
    /// r + margin + depth·tan(tilt) about the tumour axis, the deep edge at r + margin.
    pub wedge_deg: f64,
}

impl Default for NonAnatomicalParams {
    fn default() -> Self {
        NonAnatomicalParams {
            tumour_radius_mm: 12.0,
            tumour_depth_mm: 20.0,
            margin_mm: 10.0,
            length_mm: 60.0,
            depth_mm: 25.0,
            wedge_deg: 15.0,
        }
    }
}

/// (ii) Anatomical resection (register.md §4): a planar, Cantlie-like cut.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(default)]
pub struct AnatomicalParams {
    /// Length of the incision on the surface (mm).
    pub length_mm: f64,
    /// Blade depth as a fraction of the local thickness along −anterior (the median over ±[`THICKNESS_WINDOW_MM`]
    /// of the mouth, so a fold of the surface leaves no uncut slot).
    pub depth_fraction: f64,
    /// Shift of the cut plane along its normal (mm; + towards side B, along the volume's major
    /// principal axis), from the plane through the entry point.
    pub offset_mm: f64,
}

impl Default for AnatomicalParams {
    fn default() -> Self {
        AnatomicalParams { length_mm: 100.0, depth_fraction: 0.6, offset_mm: 0.0 }
    }
}

/// A sphere (mm).
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
pub struct Sphere {
    /// Centre (mm).
    pub centre: V3,
    /// Radius (mm).
    pub radius_mm: f64,
}

/// A cut scenario on a tet mesh.
#[derive(Clone, Debug)]
pub struct Scenario {
    /// "non-anatomical" or "anatomical".
    pub name: String,
    /// The cut mesh, lips and crack faces.
    pub cut: CutMesh,
    /// The blade.
    pub blade: Blade,
    /// Virtual tumour (non-anatomical only).
    pub tumour: Option<Sphere>,
    /// Fixed nodes (cut-mesh ids, sorted): the posterior region.
    pub fixed_nodes: Vec<usize>,
    /// Unit anterior axis used.
    pub anterior: V3,
    /// Entry point P on the anterior surface (mm).
    pub entry_point: V3,
    /// Smallest distance from the blade to the tumour surface (mm), non-anatomical only.
    pub min_margin_mm: Option<f64>,
}

/// The outer surface of a tet mesh (boundary faces, all vertices kept).
fn outer(mesh: &TetMesh) -> TriMesh {
    mesh.boundary()
}

/// First crossing of the ray from far along `+dir` beyond `p` back along `−dir` (the surface
/// point seen from outside along `dir`), if any.
fn surface_along(surf: &TriMesh, p: &V3, dir: &V3, far: f64) -> Option<V3> {
    let o = p + dir * far;
    let ts = ray_hits(surf, &o, &(-dir));
    ts.first().map(|&t| o - dir * t)
}

fn check_frame(f: &ScenarioFrame) -> Result<V3> {
    let a = V3::from(f.anterior);
    if !(a.norm() > 0.0 && a.iter().all(|x| x.is_finite())) {
        return Err(FemError::param("anterior", a.norm(), "must be a finite non-zero axis"));
    }
    if !(f.fixed_fraction > 0.0 && f.fixed_fraction < 1.0) {
        return Err(FemError::param("fixed_fraction", f.fixed_fraction, "must be in (0, 1)"));
    }
    if f.samples < 3 {
        return Err(FemError::param("samples", f.samples as f64, "need ≥ 3 mouth samples"));
    }
    Ok(a.normalize())
}

/// Entry point P and the outward normal there (mean normal of the surface faces within 15 mm).
fn entry(surf: &TriMesh, a: &V3, far: f64) -> Result<(V3, V3)> {
    let c = surf.volume_centroid();
    let p = surface_along(surf, &c, a, far).ok_or_else(|| {
        FemError::bad("scenario", "the line through the centroid along the anterior axis misses the mesh")
    })?;
    Ok((p, smooth_normal(surf, &p, a)))
}

/// Outward normal at `p`: area-weighted mean normal of the faces within 15 mm (`a` if none).
fn smooth_normal(surf: &TriMesh, p: &V3, a: &V3) -> V3 {
    let mut n = V3::zeros();
    for f in &surf.faces {
        let q = f.map(|k| surf.vertices[k]);
        if ((q[0] + q[1] + q[2]) / 3.0 - p).norm() < 15.0 {
            n += (q[1] - q[0]).cross(&(q[2] - q[0]));
        }
    }
    let n = if n.norm() > 0.0 { n.normalize() } else { *a };
    if n.dot(a) < 0.0 {
        -n
    } else {
        n
    }
}

/// The half-extent in (0, `max`] whose traced polyline is `length` long (bisection; the traced
/// length grows with the extent), or the longest that stays on the organ.
fn fit_length(length: f64, max: f64, trace: &dyn Fn(f64) -> Result<Vec<V3>>) -> Result<f64> {
    let (mut lo, mut hi) = (0.0, max);
    if let Ok(t) = trace(hi) {
        if polyline_length(&t) < length {
            return Ok(hi);
        }
    }
    for _ in 0..40 {
        let mid = 0.5 * (lo + hi);
        // A trace leaving the organ counts as too long.
        match trace(mid) {
            Ok(t) if polyline_length(&t) < length => lo = mid,
            _ => hi = mid,
        }
    }
    trace(lo)?;
    Ok(lo)
}

/// Entry point for the tumour: among outer-surface nodes whose vertex normal has n·a ≥ 0.8
/// (anterior-facing), those whose point `depth` under them along −n (n: 15 mm mean normal) has the node itself as its
/// closest surface point (within 0.5 mm: the tumour axis is not cut short by another part of the
/// surface); of these the one closest to the line through the volume centroid along `a`.
fn tumour_entry(surf: &TriMesh, a: &V3, depth: f64) -> Result<(V3, V3)> {
    let c = surf.volume_centroid();
    let normals = surf.vertex_normals();
    let used: BTreeSet<usize> = surf.faces.iter().flatten().copied().collect();
    let tris: Vec<[V3; 3]> = surf.faces.iter().map(|f| f.map(|k| surf.vertices[k])).collect();
    let mut cands: Vec<(f64, usize)> = used
        .iter()
        .filter(|&&k| normals[k].norm() > 0.5 && normals[k].dot(a) >= 0.8)
        .map(|&k| {
            let d = surf.vertices[k] - c;
            ((d - a * a.dot(&d)).norm(), k)
        })
        .collect();
    cands.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
    for &(_, k) in &cands {
        let p = surf.vertices[k];
        let n = smooth_normal(surf, &p, a);
        let t = p - n * depth;
        let dmin = tris
            .iter()
            .map(|q| (super::geom::closest_point_on_triangle(&t, &q[0], &q[1], &q[2]) - t).norm())
            .fold(f64::INFINITY, f64::min);
        if dmin >= depth - 0.5 {
            return Ok((p, n));
        }
    }
    Err(FemError::bad(
        "non-anatomical scenario",
        format!("no anterior surface point has {depth} mm of tissue under it"),
    ))
}

fn polyline_length(p: &[V3]) -> f64 {
    p.windows(2).map(|w| (w[1] - w[0]).norm()).sum()
}

/// Fixed posterior nodes: the `fraction` of outer-surface nodes (not on crack faces) with the
/// smallest coordinate along `a`, sorted ids.
pub fn fixed_posterior_nodes(cut: &CutMesh, a: &V3, fraction: f64) -> Vec<usize> {
    let crack: BTreeSet<usize> = cut.crack_faces.iter().flatten().flatten().copied().collect();
    let surf: BTreeSet<usize> =
        cut.mesh.boundary().faces.iter().flatten().copied().filter(|k| !crack.contains(k)).collect();
    let mut nodes: Vec<(f64, usize)> = surf.into_iter().map(|k| (cut.mesh.vertices[k].dot(a), k)).collect();
    nodes.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
    let n = ((nodes.len() as f64) * fraction).round() as usize;
    let mut ids: Vec<usize> = nodes.into_iter().take(n).map(|x| x.1).collect();
    ids.sort_unstable();
    ids
}

fn bbox_diag(m: &TetMesh) -> f64 {
    m.bounding_box().map(|(lo, hi)| (hi - lo).norm()).unwrap_or(1.0)
}

/// Smallest distance from the blade triangles to a point (mm).
fn blade_distance(blade: &Blade, p: &V3) -> f64 {
    let s = blade.surface();
    s.faces
        .iter()
        .map(|f| {
            let q = super::geom::closest_point_on_triangle(p, &s.vertices[f[0]], &s.vertices[f[1]], &s.vertices[f[2]]);
            (q - p).norm()
        })
        .fold(f64::INFINITY, f64::min)
}

/// Scenario (i): tumour centre T = P − depth·n; the mouth is the surface trace (cast along −n) of
/// an arc of the circle of radius ρ = r + margin + depth·tan(tilt) about the axis (T, n), centred
/// on the in-plane direction u (the coordinate axis least aligned with n, made orthogonal), its
/// angle set so that the traced polyline is `length_mm` long; each mouth point is swept to the
/// point `depth_mm` under it (along −n) at radius r + margin.
///
/// The blade is traced on the tet mesh's own boundary; [`non_anatomical_on`] traces it on the organ's input
/// surface instead, so that every mesh of one organ gets the same cut.
pub fn non_anatomical(mesh: &TetMesh, frame: &ScenarioFrame, p: &NonAnatomicalParams) -> Result<Scenario> {
    non_anatomical_on(mesh, &outer(mesh), frame, p)
}

/// Scenario (i) with the blade traced on `surface` (the organ's closed input surface, mm) and cut into `mesh`:
/// the same blade for every mesh of that surface, which a mesh-convergence study needs.
pub fn non_anatomical_on(
    mesh: &TetMesh,
    surface: &TriMesh,
    frame: &ScenarioFrame,
    p: &NonAnatomicalParams,
) -> Result<Scenario> {
    let a = check_frame(frame)?;
    for (name, v) in [
        ("tumour_radius_mm", p.tumour_radius_mm),
        ("tumour_depth_mm", p.tumour_depth_mm),
        ("margin_mm", p.margin_mm),
        ("length_mm", p.length_mm),
        ("depth_mm", p.depth_mm),
    ] {
        if !(v.is_finite() && v > 0.0) {
            return Err(FemError::param(name, v, "must be a positive length in mm"));
        }
    }
    if !(0.0..80.0).contains(&p.wedge_deg) {
        return Err(FemError::param("wedge_deg", p.wedge_deg, "must be in [0, 80) deg"));
    }
    let surf = surface;
    let far = 2.0 * bbox_diag(mesh).max(surface.bounding_box().map(|(lo, hi)| (hi - lo).norm()).unwrap_or(0.0));
    let (entry_point, n) = tumour_entry(surf, &a, p.tumour_depth_mm)?;
    let centre = entry_point - n * p.tumour_depth_mm;
    let e =
        (0..3).map(|k| V3::ith(k, 1.0)).min_by(|x, y| x.dot(&n).abs().total_cmp(&y.dot(&n).abs())).unwrap_or(V3::x());
    let u = (e - n * n.dot(&e)).normalize();
    let w = n.cross(&u);
    let r_deep = p.tumour_radius_mm + p.margin_mm;
    let r_top = r_deep + p.depth_mm * p.wedge_deg.to_radians().tan();
    let trace = |half: f64| -> Result<Vec<V3>> {
        (0..frame.samples)
            .map(|i| {
                let phi = -half + 2.0 * half * i as f64 / (frame.samples - 1) as f64;
                let q = entry_point + (u * phi.cos() + w * phi.sin()) * r_top;
                surface_along(surf, &q, &n, far).ok_or_else(|| {
                    FemError::bad(
                        "non-anatomical scenario",
                        format!("the mouth circle leaves the organ at angle {phi:.3} rad"),
                    )
                })
            })
            .collect()
    };
    let half = fit_length(p.length_mm, std::f64::consts::PI * 0.95, &trace)?;
    let mouth = trace(half)?;
    let mut directions = Vec::new();
    let mut depths = Vec::new();
    for q in &mouth {
        let radial = {
            let r = q - centre;
            let r = r - n * n.dot(&r);
            r.normalize()
        };
        let bottom = q - n * p.depth_mm - radial * (r_top - r_deep);
        let d = bottom - q;
        depths.push(d.norm());
        directions.push(d.normalize());
    }
    let blade = Blade { mouth, directions, depths, overshoot_mm: frame.overshoot_mm };
    let cut_mesh = cut(mesh, &blade)?;
    let margin = blade_distance(&blade, &centre) - p.tumour_radius_mm;
    let fixed_nodes = fixed_posterior_nodes(&cut_mesh, &a, frame.fixed_fraction);
    Ok(Scenario {
        name: "non-anatomical".into(),
        cut: cut_mesh,
        blade,
        tumour: Some(Sphere { centre, radius_mm: p.tumour_radius_mm }),
        fixed_nodes,
        anterior: a,
        entry_point,
        min_margin_mm: Some(margin),
    })
}

/// Half-width (mm along the cut plane's lateral direction) of the window whose median thickness sets
/// the anatomical blade's depth.
///
/// Under a fold or fissure of the anterior surface the ray along −anterior leaves the organ after a
/// millimetre or two and re-enters (on the P2ILF liver, one to three of 61 mouth samples: 1.4 mm where
/// the neighbours measure 140–170 mm); a blade that followed it would leave a slot of uncut tissue
/// from the mouth to the crack's floor, tying the two lips together. The median over ±10 mm ignores
/// such a dip when it is narrower than 10 mm and follows any wider change of thickness.
pub const THICKNESS_WINDOW_MM: f64 = 10.0;

/// The median of `values` over the samples whose position (mm, one per value) lies within
/// `half_window_mm` of each one's: a running median that keeps a linear trend and removes dips
/// narrower than the half-window.
pub(crate) fn local_median(position_mm: &[f64], values: &[f64], half_window_mm: f64) -> Vec<f64> {
    (0..values.len())
        .map(|i| {
            let mut w: Vec<f64> = (0..values.len())
                .filter(|&j| (position_mm[j] - position_mm[i]).abs() <= half_window_mm)
                .map(|j| values[j])
                .collect();
            w.sort_by(f64::total_cmp);
            let m = w.len() / 2;
            if w.len() % 2 == 1 {
                w[m]
            } else {
                0.5 * (w[m - 1] + w[m])
            }
        })
        .collect()
}

/// Scenario (ii): a planar cut through P containing the anterior axis, its plane normal the
/// mesh's major principal axis made orthogonal to `a` (left–right); the mouth is the surface trace
/// (cast along −a) of a segment through P along `a × normal`, scaled to `length_mm` of traced
/// length; each mouth point is swept along −a by `depth_fraction` × the local thickness (distance
/// along −a to where that ray leaves the organ, the median over ±[`THICKNESS_WINDOW_MM`] of the
/// mouth's lateral extent so that a fold of the surface does not leave a slot of uncut tissue).
///
/// [`anatomical_on`] traces the blade on the organ's input surface instead of the mesh boundary.
pub fn anatomical(mesh: &TetMesh, frame: &ScenarioFrame, p: &AnatomicalParams) -> Result<Scenario> {
    anatomical_on(mesh, &outer(mesh), frame, p)
}

/// Scenario (ii) with the blade traced on `surface` (the organ's closed input surface, mm) and cut into `mesh`.
pub fn anatomical_on(
    mesh: &TetMesh,
    surface: &TriMesh,
    frame: &ScenarioFrame,
    p: &AnatomicalParams,
) -> Result<Scenario> {
    let a = check_frame(frame)?;
    if !(p.length_mm.is_finite() && p.length_mm > 0.0) {
        return Err(FemError::param("length_mm", p.length_mm, "must be a positive length in mm"));
    }
    if !(p.depth_fraction > 0.0 && p.depth_fraction < 1.0) {
        return Err(FemError::param("depth_fraction", p.depth_fraction, "must be in (0, 1)"));
    }
    if !p.offset_mm.is_finite() {
        return Err(FemError::param("offset_mm", p.offset_mm, "must be a finite shift in mm"));
    }
    let surf = surface;
    let far = 2.0 * bbox_diag(mesh).max(surface.bounding_box().map(|(lo, hi)| (hi - lo).norm()).unwrap_or(0.0));
    let (entry_point, _) = entry(surf, &a, far)?;
    // Major principal axis of the tet volume (volume-weighted tet centroids).
    let mut vol = 0.0;
    let mut mean = V3::zeros();
    let cents: Vec<(f64, V3)> = mesh
        .tets
        .iter()
        .map(|t| {
            let q = t.map(|k| mesh.vertices[k]);
            (tet_signed_volume(&q).abs(), (q[0] + q[1] + q[2] + q[3]) / 4.0)
        })
        .collect();
    for (v, c) in &cents {
        vol += v;
        mean += c * *v;
    }
    mean /= vol;
    let mut cov = Matrix3::zeros();
    for (v, c) in &cents {
        let d = c - mean;
        cov += d * d.transpose() * *v;
    }
    let cov = cov - a * (a.transpose() * cov * a) * a.transpose();
    let eig = cov.symmetric_eigen();
    let imax = (0..3).max_by(|&i, &j| eig.eigenvalues[i].total_cmp(&eig.eigenvalues[j])).unwrap_or(0);
    let mut normal: V3 = eig.eigenvectors.column(imax).into();
    normal = (normal - a * a.dot(&normal)).normalize();
    let t = a.cross(&normal).normalize();
    let entry_point = entry_point + normal * p.offset_mm;
    let trace = |half: f64| -> Result<Vec<V3>> {
        (0..frame.samples)
            .map(|i| {
                let s = -half + 2.0 * half * i as f64 / (frame.samples - 1) as f64;
                surface_along(surf, &(entry_point + t * s), &a, far).ok_or_else(|| {
                    FemError::bad(
                        "anatomical scenario",
                        format!("the cut line leaves the organ at {s:.1} mm from the entry point"),
                    )
                })
            })
            .collect()
    };
    let half = fit_length(p.length_mm, p.length_mm, &trace)?;
    let mouth = trace(half)?;
    let mut thickness = Vec::new();
    for (i, q) in mouth.iter().enumerate() {
        // Thickness: from q (just inside) along −a to the next crossing.
        let o = q - a * 1e-6;
        let hits = ray_hits(surf, &o, &(-a));
        let th = hits.into_iter().find(|&t| t > 1e-3).ok_or_else(|| {
            FemError::bad("anatomical scenario", format!("no exit along −anterior from mouth point {i}"))
        })?;
        thickness.push(th);
    }
    // the window runs along the plane's lateral direction t (where the samples are evenly spaced), not
    // along the mouth's arc, which jumps where the surface folds
    let lateral: Vec<f64> = mouth.iter().map(|q| (q - mouth[0]).dot(&t)).collect();
    let depths = local_median(&lateral, &thickness, THICKNESS_WINDOW_MM).iter().map(|t| p.depth_fraction * t).collect();
    let blade = Blade { directions: vec![-a; mouth.len()], mouth, depths, overshoot_mm: frame.overshoot_mm };
    let cut_mesh = cut(mesh, &blade)?;
    let fixed_nodes = fixed_posterior_nodes(&cut_mesh, &a, frame.fixed_fraction);
    Ok(Scenario {
        name: "anatomical".into(),
        cut: cut_mesh,
        blade,
        tumour: None,
        fixed_nodes,
        anterior: a,
        entry_point,
        min_margin_mm: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn local_median_keeps_a_ramp_and_removes_a_narrow_dip() {
        // 61 samples 1.7 mm apart on a straight mouth, thickness rising 100 → 160 mm
        let mouth: Vec<f64> = (0..61).map(|i| 1.7 * i as f64).collect();
        let ramp: Vec<f64> = (0..61).map(|i| 100.0 + i as f64).collect();
        let m = local_median(&mouth, &ramp, THICKNESS_WINDOW_MM);
        // a symmetric window of a linear trend has the centre as its median; near the ends the window is
        // one-sided and the median moves inwards by half the missing samples
        for i in 6..55 {
            assert!((m[i] - ramp[i]).abs() < 1e-12, "sample {i}: {} vs {}", m[i], ramp[i]);
        }
        assert!((m[0] - 102.5).abs() < 1e-12, "end: the window is samples 0..=5, median 102.5: {}", m[0]);
        // three samples of a fold (the ray leaving after 4, 9, 13 mm) vanish
        let mut dip = ramp.clone();
        dip[30..33].copy_from_slice(&[4.0, 9.0, 13.0]);
        let md = local_median(&mouth, &dip, THICKNESS_WINDOW_MM);
        assert!(md.iter().all(|&t| t >= 100.0), "min {}", md.iter().copied().fold(f64::INFINITY, f64::min));
        for i in 30..33 {
            assert!((md[i] - ramp[i]).abs() <= 3.0, "sample {i}: {}", md[i]);
        }
        // a change wider than the window is followed: a 30 mm long shallow part stays shallow
        let mut shelf = ramp;
        for t in &mut shelf[20..38] {
            *t = 20.0;
        }
        let ms = local_median(&mouth, &shelf, THICKNESS_WINDOW_MM);
        assert_eq!(ms[29], 20.0);
    }
}
