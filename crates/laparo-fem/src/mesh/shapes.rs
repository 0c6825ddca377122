//! Closed test surfaces with closed-form volumes (an axis-aligned box, an icosphere) and a structured
//! tetrahedral box.
use laparo_core::mesh::{TetMesh, TriMesh};
use nalgebra::Vector3;
use std::collections::HashMap;

/// The box `[lo, hi]` as 12 outward triangles (volume Π(hi − lo)): [`TriMesh::cuboid`].
pub fn box_surface(lo: &Vector3<f64>, hi: &Vector3<f64>) -> TriMesh {
    TriMesh::cuboid(lo, hi)
}

/// The box [0, nx h] × [0, ny h] × [0, nz h] (mm) cut into nx × ny × nz cubes of edge `h_mm`, each split
/// into the 6 Kuhn tetrahedra around its main diagonal (a conforming mesh, positively and negatively
/// oriented tets mixed). Vertex (i, j, k) has id (i (ny + 1) + j)(nz + 1) + k.
pub fn kuhn_box([nx, ny, nz]: [usize; 3], h_mm: f64) -> TetMesh {
    let id = |i: usize, j: usize, k: usize| (i * (ny + 1) + j) * (nz + 1) + k;
    let mut vertices = Vec::with_capacity((nx + 1) * (ny + 1) * (nz + 1));
    for i in 0..=nx {
        for j in 0..=ny {
            for k in 0..=nz {
                vertices.push(Vector3::new(i as f64, j as f64, k as f64) * h_mm);
            }
        }
    }
    let mut tets = Vec::with_capacity(6 * nx * ny * nz);
    for i in 0..nx {
        for j in 0..ny {
            for k in 0..nz {
                for p in [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]] {
                    let mut c = [i, j, k];
                    let mut t = [id(i, j, k), 0, 0, 0];
                    for (s, &ax) in p.iter().enumerate() {
                        c[ax] += 1;
                        t[s + 1] = id(c[0], c[1], c[2]);
                    }
                    tets.push(t);
                }
            }
        }
    }
    TetMesh::new(vertices, tets).expect("a Kuhn box is a valid tet mesh")
}

/// An icosphere of radius `radius` centred at `centre`: the icosahedron subdivided `levels` times,
/// vertices pushed to the sphere; outward triangles.
pub fn icosphere(centre: &Vector3<f64>, radius: f64, levels: usize) -> TriMesh {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut v: Vec<Vector3<f64>> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| Vector3::new(x, y, z).normalize())
    .collect();
    let mut f: Vec<[usize; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..levels {
        let mut mid: HashMap<(usize, usize), usize> = HashMap::new();
        let mut m = |a: usize, b: usize, v: &mut Vec<Vector3<f64>>| -> usize {
            let key = (a.min(b), a.max(b));
            *mid.entry(key).or_insert_with(|| {
                v.push(((v[a] + v[b]) / 2.0).normalize());
                v.len() - 1
            })
        };
        let mut g = Vec::with_capacity(f.len() * 4);
        for [a, b, c] in f {
            let ab = m(a, b, &mut v);
            let bc = m(b, c, &mut v);
            let ca = m(c, a, &mut v);
            g.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        f = g;
    }
    TriMesh { vertices: v.into_iter().map(|p| centre + p * radius).collect(), faces: f }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shapes_are_closed_outward_with_expected_volume() {
        let b = box_surface(&Vector3::new(-1.0, 0.0, 2.0), &Vector3::new(2.0, 1.0, 4.0));
        assert!(b.is_closed() && b.is_consistently_oriented());
        assert!((b.signed_volume() - 6.0).abs() < 1e-12);
        let s = icosphere(&Vector3::new(1.0, 2.0, 3.0), 10.0, 3);
        assert!(s.is_closed() && s.is_consistently_oriented());
        let v = s.signed_volume();
        // Inscribed polyhedron: below the ball volume, within 2 % at 1280 faces.
        let ball = 4.0 / 3.0 * std::f64::consts::PI * 1000.0;
        assert!(v > 0.97 * ball && v < ball, "{v} vs {ball}");
    }
}
