//! A tetrahedral mesh of the inside of a closed surface for the in-silico scenario: the grid cubes
//! of cell `h` (mm) whose 8 corners are inside the surface, each split into the 6 Kuhn tetrahedra
//! (a conforming split: neighbouring cubes share their face diagonals); boundary nodes are then
//! moved onto the surface (closest point) wherever that keeps every tetrahedron positive.
//! The grid index of every node is kept so that a planar cut can follow grid faces exactly.
use crate::error::{GuideError, Result};
use laparo_core::mesh::{TetMesh, TriMesh};
use laparo_register::distance::{ClosestPoint, TriangleSurface};
use nalgebra::Vector3;
use rayon::prelude::*;
use std::collections::HashMap;

/// A grid-based tetrahedral mesh.
#[derive(Clone, Debug)]
pub struct GridTetMesh {
    /// The mesh (mm), all tetrahedra positively oriented.
    pub mesh: TetMesh,
    /// Grid index (i, j, k) of every node.
    pub grid: Vec<[i64; 3]>,
    /// Grid origin (mm).
    pub origin: Vector3<f64>,
    /// Grid cell (mm).
    pub h: f64,
}

fn tet_volume(v: &[Vector3<f64>], t: &[usize; 4]) -> f64 {
    (v[t[1]] - v[t[0]]).cross(&(v[t[2]] - v[t[0]])).dot(&(v[t[3]] - v[t[0]])) / 6.0
}

/// Mesh the inside of the closed `surface` with Kuhn tetrahedra of grid cell `h_mm`.
pub fn grid_tet_mesh(surface: &TriMesh, h_mm: f64) -> Result<GridTetMesh> {
    let bad = |m: String| GuideError::stage("mesh", "organ surface", m);
    if !(h_mm > 0.0) {
        return Err(bad(format!("grid cell {h_mm} mm (need > 0)")));
    }
    let (lo, hi) = surface.bounding_box().ok_or_else(|| bad("empty surface".into()))?;
    let n: Vec<i64> = (0..3).map(|d| ((hi[d] - lo[d]) / h_mm).ceil() as i64 + 1).collect();
    if n.iter().product::<i64>() > 40_000_000 {
        return Err(bad(format!(
            "grid of {}x{}x{} nodes is too large: increase the cell ({h_mm} mm)",
            n[0], n[1], n[2]
        )));
    }
    let origin = lo - Vector3::repeat(0.5 * h_mm);
    let n: Vec<i64> = n.iter().map(|v| v + 1).collect();
    // inside test by ray parity along +x, one ray per (j, k) row (jittered off the grid)
    let (jit_y, jit_z) = (1.234567e-4 * h_mm, 2.345678e-4 * h_mm);
    let fbox: Vec<[f64; 4]> = surface
        .faces
        .iter()
        .map(|f| {
            let p = [surface.vertices[f[0]], surface.vertices[f[1]], surface.vertices[f[2]]];
            [
                p.iter().map(|q| q[1]).fold(f64::INFINITY, f64::min),
                p.iter().map(|q| q[1]).fold(f64::NEG_INFINITY, f64::max),
                p.iter().map(|q| q[2]).fold(f64::INFINITY, f64::min),
                p.iter().map(|q| q[2]).fold(f64::NEG_INFINITY, f64::max),
            ]
        })
        .collect();
    let (nx, ny, nz) = (n[0] as usize, n[1] as usize, n[2] as usize);
    let inside: Vec<bool> = (0..ny * nz)
        .into_par_iter()
        .flat_map_iter(|row| {
            let (j, k) = (row % ny, row / ny);
            let y = origin[1] + j as f64 * h_mm + jit_y;
            let z = origin[2] + k as f64 * h_mm + jit_z;
            let o = Vector3::new(origin[0] - h_mm, y, z);
            let dir = Vector3::new(1.0, 0.0, 0.0);
            let mut xs: Vec<f64> = surface
                .faces
                .iter()
                .zip(&fbox)
                .filter(|(_, b)| b[0] <= y && y <= b[1] && b[2] <= z && z <= b[3])
                .filter_map(|(f, _)| {
                    laparo_register::rigid::ray_triangle(
                        &o,
                        &dir,
                        &surface.vertices[f[0]],
                        &surface.vertices[f[1]],
                        &surface.vertices[f[2]],
                    )
                })
                .map(|t| o[0] + t)
                .collect();
            xs.sort_by(f64::total_cmp);
            (0..nx).map(move |i| {
                let x = origin[0] + i as f64 * h_mm;
                xs.iter().filter(|&&c| c < x).count() % 2 == 1
            })
        })
        .collect();
    // inside[(k*ny + j)*nx + i]
    let at = |i: i64, j: i64, k: i64| -> bool {
        i >= 0 && j >= 0 && k >= 0 && i < n[0] && j < n[1] && k < n[2] && inside[((k * n[1] + j) * n[0] + i) as usize]
    };
    let mut ids: HashMap<[i64; 3], usize> = HashMap::new();
    let mut grid = Vec::new();
    let mut tets = Vec::new();
    const PERMS: [[usize; 3]; 6] = [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]];
    for k in 0..n[2] {
        for j in 0..n[1] {
            for i in 0..n[0] {
                let all = (0..8).all(|c| at(i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1)));
                if !all {
                    continue;
                }
                for p in PERMS {
                    let mut g = [i, j, k];
                    let mut t = [0usize; 4];
                    for (s, slot) in t.iter_mut().enumerate() {
                        if s > 0 {
                            g[p[s - 1]] += 1;
                        }
                        let next = grid.len();
                        *slot = *ids.entry(g).or_insert_with(|| {
                            grid.push(g);
                            next
                        });
                    }
                    tets.push(t);
                }
            }
        }
    }
    if tets.is_empty() {
        return Err(bad(format!("no grid cube of {h_mm} mm inside the surface (open surface or cell too large)")));
    }
    let vertices: Vec<Vector3<f64>> =
        grid.iter().map(|g| origin + Vector3::new(g[0] as f64, g[1] as f64, g[2] as f64) * h_mm).collect();
    let mut mesh = TetMesh { vertices, tets };
    mesh.orient_positive();
    // snap boundary nodes to the surface, reverting those that would invert a tetrahedron
    let boundary = mesh.boundary();
    let mut on_b = vec![false; mesh.vertices.len()];
    for f in &boundary.faces {
        for &v in f {
            on_b[v] = true;
        }
    }
    let ts = TriangleSurface::new(surface.vertices.clone(), surface.faces.clone());
    let grid_pos = mesh.vertices.clone();
    let snapped: Vec<Vector3<f64>> = (0..grid_pos.len())
        .into_par_iter()
        .map(|v| if on_b[v] { ts.closest(&grid_pos[v]).0 } else { grid_pos[v] })
        .collect();
    let mut pos = snapped;
    let min_vol = 0.02 * h_mm.powi(3) / 6.0;
    for _ in 0..20 {
        let mut reverted = false;
        for t in &mesh.tets {
            if tet_volume(&pos, t) < min_vol {
                for &v in t {
                    if pos[v] != grid_pos[v] {
                        pos[v] = grid_pos[v];
                        reverted = true;
                    }
                }
            }
        }
        if !reverted {
            break;
        }
    }
    mesh.vertices = pos;
    Ok(GridTetMesh { mesh, grid, origin, h: h_mm })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cube_surface_is_filled_with_positive_tets_of_the_right_volume() {
        // a 20 mm cube: the grid cubes inside fill it up to the border layer, then snapping moves
        // the boundary nodes onto the faces, so the volume is close to 8000 mm³
        let c = laparo_fem::mesh::shapes::box_surface(&Vector3::zeros(), &Vector3::repeat(20.0));
        let g = grid_tet_mesh(&c, 2.0).unwrap();
        assert!(g.mesh.tets.iter().enumerate().all(|(i, _)| g.mesh.tet_volume(i) > 0.0));
        let vol = g.mesh.volume();
        let (lo, hi) = c.bounding_box().unwrap();
        let exact = (hi - lo).product();
        assert!((vol - exact).abs() < 0.05 * exact, "volume {vol} vs {exact}");
        // conforming: every interior face is shared by exactly two tets, so the boundary is closed
        assert!(g.mesh.boundary().is_closed());
    }
}
