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
