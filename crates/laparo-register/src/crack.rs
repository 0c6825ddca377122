//! A crack surface for laparo-mpm's two-field grid: which particles lie on either side of a known or assumed
//! incision (`laparo register --crack`, the benchmark's two-field RODS-MPM). Particles near the surface take
//! side ±1 and get their own velocity field on the grid nodes they share with the other lip, so the lips
//! can separate (see laparo-mpm's README, "two-field grid").
use crate::error::{RegisterError, Result};
use crate::organ::Organ;
use nalgebra::Vector3;

/// A crack surface for the two-field grid: particles within `band_mm` of it whose offset from their
/// closest crack point lies within 60° of that face's normal take side ±1 (+1 on the normal's side),
/// the others (beyond the crack front, or far) side 0.
#[derive(Clone, Debug)]
pub struct CrackSurface {
    /// Vertices (mm, model frame).
    pub vertices: Vec<Vector3<f64>>,
    /// Triangles, wound so that their normals point from side −1 to side +1.
    pub faces: Vec<[usize; 3]>,
    /// Labelling band (mm); None = 3 Δx of the simulation grid.
    pub band_mm: Option<f64>,
}

/// Crack side (−1, 0, +1) of each point (see [`CrackSurface`]); a point on the surface itself (closer
/// than 1e-6 mm) is judged by its `inside` point (e.g. the centroid of the tetrahedron it was sampled in).
pub fn crack_sides(
    points: &[Vector3<f64>],
    inside: &[Vector3<f64>],
    crack: &CrackSurface,
    band_mm: f64,
) -> Result<Vec<i8>> {
    if crack.faces.is_empty() {
        return Err(RegisterError::bad("crack surface", "no triangle"));
    }
    if !(band_mm > 0.0) {
        return Err(RegisterError::param("crack band (mm)", band_mm, "must be > 0"));
    }
    if let Some(f) = crack.faces.iter().find(|f| f.iter().any(|&i| i >= crack.vertices.len())) {
        return Err(RegisterError::bad("crack surface", format!("face {f:?} of {} vertices", crack.vertices.len())));
    }
    let surface = crate::distance::TriangleSurface::new(crack.vertices.clone(), crack.faces.clone());
    let normal = |k: usize| {
        let q = crack.faces[k].map(|i| crack.vertices[i]);
        (q[1] - q[0]).cross(&(q[2] - q[0])).try_normalize(0.0)
    };
    Ok(points
        .iter()
        .zip(inside)
        .map(|(x, y)| {
            use crate::distance::ClosestPoint;
            let (c, k) = surface.closest(x);
            let mut d = x - c;
            if d.norm() > band_mm {
                return 0;
            }
            if d.norm() < 1e-6 {
                let (c2, _) = surface.closest(y);
                d = y - c2;
            }
            match normal(k) {
                Some(n) if d.dot(&n) > 0.5 * d.norm() => 1,
                Some(n) if d.dot(&n) < -0.5 * d.norm() => -1,
                _ => 0,
            }
        })
        .collect())
}

impl CrackSurface {
    /// A crack surface from a triangle mesh (mm, model frame; normals from side −1 to side +1), checked:
    /// at least one triangle, finite vertices, no degenerate (zero-area) triangle. `input` names it in errors.
    pub fn from_mesh(mesh: &laparo_core::mesh::TriMesh, input: &str, band_mm: Option<f64>) -> Result<Self> {
        if mesh.faces.is_empty() {
            return Err(RegisterError::bad(input, "the crack surface has no triangle"));
        }
        if let Some(k) = mesh.vertices.iter().position(|v| !v.iter().all(|c| c.is_finite())) {
            return Err(RegisterError::bad(input, format!("vertex {k} is not finite")));
        }
        let (vertices, faces) = (mesh.vertices.clone(), mesh.faces.clone());
        if let Some(f) = faces.iter().find(|f| f.iter().any(|&i| i >= vertices.len())) {
            return Err(RegisterError::bad(input, format!("face {f:?} of {} vertices", vertices.len())));
        }
        if let Some(k) = faces.iter().position(|f| {
            let q = f.map(|i| vertices[i]);
            (q[1] - q[0]).cross(&(q[2] - q[0])).norm() < 1e-12
        }) {
            return Err(RegisterError::bad(input, format!("triangle {k} is degenerate (zero area)")));
        }
        if let Some(b) = band_mm {
            if !(b > 0.0 && b.is_finite()) {
                return Err(RegisterError::param("crack band (mm)", b, "must be finite and > 0"));
            }
        }
        Ok(CrackSurface { vertices, faces, band_mm })
    }
}

/// How a crack surface labelled an organ's particles.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct CrackLabels {
    /// Particles on side −1 and on side +1.
    pub particles: [usize; 2],
    /// Labelling band used (mm).
    pub band_mm: f64,
    /// Triangles of the crack surface.
    pub faces: usize,
}

impl CrackLabels {
    /// One line for a report.
    pub fn note(&self) -> String {
        format!(
            "two-field grid: {} particles on side -1, {} on side +1 (band {:.1} mm, {} crack faces)",
            self.particles[0], self.particles[1], self.band_mm, self.faces
        )
    }
}

/// Label `organ`'s particles (model positions `points`, mm; `inside` as in [`crack_sides`]) by side of
/// `crack` and turn on the two-field grid; an error when either side gets no particle (the surface misses
/// the organ, or lies farther than the band from every particle).
pub fn label_organ(
    organ: &mut Organ,
    crack: &CrackSurface,
    points: &[Vector3<f64>],
    inside: &[Vector3<f64>],
) -> Result<CrackLabels> {
    let band = crack.band_mm.unwrap_or(3.0 * organ.scene.grid.dx);
    let sides = crack_sides(points, inside, crack, band)?;
    let count = |v: i8| sides.iter().filter(|&&s| s == v).count();
    let labels = CrackLabels { particles: [count(-1), count(1)], band_mm: band, faces: crack.faces.len() };
    if labels.particles.contains(&0) {
        return Err(RegisterError::bad(
            "crack surface",
            format!(
                "{} particles on side -1 and {} on side +1 within {band:.1} mm: the surface misses the organ (it must cross it, model frame, mm)",
                labels.particles[0], labels.particles[1]
            ),
        ));
    }
    organ.scene.crack_side = sides;
    // the preconditioner's sides: the same test without the band (the whole material in front of Σ)
    organ.smoothing_sides = crack_sides(points, inside, crack, f64::MAX)?;
    Ok(labels)
}

/// Unit outward normals of a closed surface at `points`: the area-weighted normals of its faces whose
/// centroid lies within `radius_mm` (a local average over a surface triangulated finer than the radius, as
/// organ meshes are); where no centroid is that close, the normal of the face closest to the point.
pub fn outward_normals(
    surface: &laparo_core::mesh::TriMesh,
    points: &[Vector3<f64>],
    radius_mm: f64,
) -> Vec<Vector3<f64>> {
    points
        .iter()
        .map(|p| {
            let mut n = Vector3::zeros();
            for f in &surface.faces {
                let q = f.map(|k| surface.vertices[k]);
                if ((q[0] + q[1] + q[2]) / 3.0 - p).norm() < radius_mm {
                    n += (q[1] - q[0]).cross(&(q[2] - q[0]));
                }
            }
            n.try_normalize(0.0).unwrap_or_else(|| nearest_face_normal(surface, p))
        })
        .collect()
}

/// The unit normal of the face of `surface` closest to `p` (+z for a surface without a proper face).
fn nearest_face_normal(surface: &laparo_core::mesh::TriMesh, p: &Vector3<f64>) -> Vector3<f64> {
    use crate::distance::ClosestPoint;
    if surface.faces.is_empty() {
        return Vector3::z();
    }
    let s = crate::distance::TriangleSurface::new(surface.vertices.clone(), surface.faces.clone());
    let (_, k) = s.closest(p);
    let q = surface.faces[k].map(|i| surface.vertices[i]);
    (q[1] - q[0]).cross(&(q[2] - q[0])).try_normalize(0.0).unwrap_or_else(Vector3::z)
}

impl CrackSurface {
    /// The cut surface Σ a surgeon's system can assume from one lip alone (the cut François et al. assume):
    /// the lip's source polyline `lip` (mm, on the organ's closed `surface`) swept along the surface's inward
    /// normal (averaged within 10 mm) from `above_mm` outside the surface to `depth_mm` under it, as a ribbon
    /// of two triangles per lip segment. Its normals point to the left of the lip's direction seen from
    /// outside; the two-field grid only needs them consistent. Errors name `input`: fewer than two distinct
    /// lip points, a non-finite point or a depth that is not finite and > 0.
    pub fn swept_from_lip(
        surface: &laparo_core::mesh::TriMesh,
        lip: &[Vector3<f64>],
        depth_mm: f64,
        band_mm: Option<f64>,
        input: &str,
    ) -> Result<Self> {
        if !(depth_mm > 0.0 && depth_mm.is_finite()) {
            return Err(RegisterError::param("assumed cut depth (mm)", depth_mm, "must be finite and > 0"));
        }
        if let Some(k) = lip.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
            return Err(RegisterError::bad(input, format!("lip point {k} is not finite")));
        }
        // distinct consecutive points: a repeated point would give a zero-area triangle
        let mut mouth: Vec<Vector3<f64>> = Vec::with_capacity(lip.len());
        for p in lip {
            if mouth.last().is_none_or(|q: &Vector3<f64>| (p - q).norm() > 1e-9) {
                mouth.push(*p);
            }
        }
        if mouth.len() < 2 {
            return Err(RegisterError::bad(
                input,
                format!(
                    "the lip polyline has {} distinct point(s): a cut surface needs at least two to sweep",
                    mouth.len()
                ),
            ));
        }
        if surface.faces.is_empty() {
            return Err(RegisterError::bad(input, "the organ surface has no triangle to take the cut direction from"));
        }
        const ABOVE_MM: f64 = 2.0;
        let normals = outward_normals(surface, &mouth, 10.0);
        let n = mouth.len();
        let mut vertices = Vec::with_capacity(2 * n);
        for (p, nrm) in mouth.iter().zip(&normals) {
            vertices.push(p + nrm * ABOVE_MM);
            vertices.push(p - nrm * depth_mm);
        }
        let mut faces = Vec::with_capacity(2 * (n - 1));
        for k in 0..n - 1 {
            let (a, b, c, d) = (2 * k, 2 * k + 1, 2 * k + 2, 2 * k + 3);
            faces.push([a, b, c]);
            faces.push([c, b, d]);
        }
        let mesh = laparo_core::mesh::TriMesh { vertices, faces };
        CrackSurface::from_mesh(&mesh, input, band_mm)
    }
}
