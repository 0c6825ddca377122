//! Display surface of a (registered) particle body: marching tetrahedra (the tetrahedral member of the
//! marching-cubes family, chosen because it needs no ambiguity tables and its output over a consistent
//! Kuhn split of the cubes is a closed 2-manifold) on a particle density field
//! φ(y) = Σ_p K(|y − x_p| / h), K the cubic B-spline of support 2h, h = `kernel_radius` × spacing. The
//! iso-level is half the density of the rest interior, so an incision whose lips are more than ≈2h apart
//! shows as open.
use crate::error::{RegisterError, Result};
use laparo_mpm::Vector;
use std::collections::HashMap;

/// Surface extraction settings (relative to the particle spacing).
#[derive(Clone, Debug, serde::Serialize)]
pub struct SurfaceConfig {
    /// Kernel h in particle spacings (support 2h).
    pub kernel_radius: f64,
    /// Sampling grid step in particle spacings.
    pub grid_step: f64,
    /// Iso-level as a fraction of the interior density.
    pub iso_fraction: f64,
}

impl Default for SurfaceConfig {
    fn default() -> Self {
        SurfaceConfig { kernel_radius: 0.75, grid_step: 0.5, iso_fraction: 0.5 }
    }
}

fn cubic(q: f64) -> f64 {
    if q < 1.0 {
        1.0 - 1.5 * q * q + 0.75 * q * q * q
    } else if q < 2.0 {
        0.25 * (2.0 - q).powi(3)
    } else {
        0.0
    }
}

/// A triangle mesh (vertices, faces), outward oriented.
pub type Surface = (Vec<Vector<3>>, Vec<[usize; 3]>);

/// Display surface of particles `x` sampled at `spacing` (their rest spacing).
pub fn particle_surface(x: &[Vector<3>], spacing: f64, cfg: &SurfaceConfig) -> Result<Surface> {
    if x.is_empty() {
        return Err(RegisterError::bad("particles", "no particle: no surface"));
    }
    let h = cfg.kernel_radius * spacing;
    let g = cfg.grid_step * spacing;
    if !(h > 0.0 && g > 0.0) {
        return Err(RegisterError::param("kernel_radius/grid_step", h.min(g), "must be > 0"));
    }
    let mut lo = x[0];
    let mut hi = x[0];
    for p in x {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    let pad = 2.0 * h + 2.0 * g;
    let origin = lo - Vector::<3>::repeat(pad);
    let n: [usize; 3] = std::array::from_fn(|d| ((hi[d] - lo[d] + 2.0 * pad) / g).ceil() as usize + 1);
    let total = n[0] * n[1] * n[2];
    if total > 400_000_000 {
        return Err(RegisterError::param(
            "grid_step",
            cfg.grid_step,
            format!("density grid of {total} nodes is too large"),
        ));
    }
    let at = |i: usize, j: usize, k: usize| (i * n[1] + j) * n[2] + k;
    let mut phi = vec![0.0f64; total];
    let r = (2.0 * h / g).ceil() as i64;
    for p in x {
        let c: [i64; 3] = std::array::from_fn(|d| ((p[d] - origin[d]) / g).round() as i64);
        for i in (c[0] - r).max(0)..=(c[0] + r).min(n[0] as i64 - 1) {
            for j in (c[1] - r).max(0)..=(c[1] + r).min(n[1] as i64 - 1) {
                for k in (c[2] - r).max(0)..=(c[2] + r).min(n[2] as i64 - 1) {
                    let y = origin + Vector::<3>::new(i as f64, j as f64, k as f64) * g;
                    let w = cubic((y - p).norm() / h);
                    if w > 0.0 {
                        phi[at(i as usize, j as usize, k as usize)] += w;
                    }
                }
            }
        }
    }
    // interior density of the rest lattice of `spacing`: Σ over lattice offsets (evaluated exactly)
    let m = (2.0 * h / spacing).ceil() as i64 + 1;
    let mut interior: f64 = 0.0;
    for a in -m..=m {
        for b in -m..=m {
            for c in -m..=m {
                interior +=
                    cubic(Vector::<3>::new(a as f64 + 0.5, b as f64 + 0.5, c as f64 + 0.5).norm() * spacing / h);
            }
        }
    }
    // average over the position of the sample in the lattice cell (use the cell centre and corner)
    let mut corner_sum = 0.0;
    for a in -m..=m {
        for b in -m..=m {
            for c in -m..=m {
                corner_sum += cubic(Vector::<3>::new(a as f64, b as f64, c as f64).norm() * spacing / h);
            }
        }
    }
    let iso = cfg.iso_fraction * 0.5 * (interior + corner_sum);
    // marching tetrahedra over the Kuhn split of each cube
    let node = |i: usize, j: usize, k: usize| at(i, j, k);
    let val = |id: usize| {
        let s = phi[id] - iso;
        if s == 0.0 {
            1e-300
        } else {
            s
        }
    };
    let pos = |id: usize| {
        let k = id % n[2];
        let j = id / n[2] % n[1];
        let i = id / (n[1] * n[2]);
        origin + Vector::<3>::new(i as f64, j as f64, k as f64) * g
    };
    let mut verts: Vec<Vector<3>> = Vec::new();
    let mut edge_vert: HashMap<(usize, usize), usize> = HashMap::new();
    let mut faces: Vec<[usize; 3]> = Vec::new();
    let perms: [[usize; 3]; 6] = [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]];
    for i in 0..n[0] - 1 {
        for j in 0..n[1] - 1 {
            for k in 0..n[2] - 1 {
                let ids = [node(i, j, k), node(i + 1, j + 1, k + 1)];
                let (s0, s1) = (val(ids[0]), val(ids[1]));
                // quick reject: all 8 corners on one side
                let corners = [
                    node(i, j, k),
                    node(i + 1, j, k),
                    node(i, j + 1, k),
                    node(i, j, k + 1),
                    node(i + 1, j + 1, k),
                    node(i + 1, j, k + 1),
                    node(i, j + 1, k + 1),
                    node(i + 1, j + 1, k + 1),
                ];
                let pos_count = corners.iter().filter(|&&c| val(c) > 0.0).count();
                if pos_count == 0 || pos_count == 8 {
                    let _ = (s0, s1);
                    continue;
                }
                for perm in perms {
                    let mut t = [[i, j, k]; 4];
                    for s in 0..3 {
                        t[s + 1] = t[s];
                        t[s + 1][perm[s]] += 1;
                    }
                    let tid = t.map(|c| node(c[0], c[1], c[2]));
                    tet(&tid, &val, &pos, &mut verts, &mut edge_vert, &mut faces);
                }
            }
        }
    }
    if faces.is_empty() {
        return Err(RegisterError::bad("particles", "the density field has no iso-surface (too sparse particles?)"));
    }
    Ok((verts, faces))
}

fn tet(
    t: &[usize; 4],
    val: &dyn Fn(usize) -> f64,
    pos: &dyn Fn(usize) -> Vector<3>,
    verts: &mut Vec<Vector<3>>,
    edge_vert: &mut HashMap<(usize, usize), usize>,
    faces: &mut Vec<[usize; 3]>,
) {
    let s = t.map(val);
    let inside: Vec<usize> = (0..4).filter(|&a| s[a] > 0.0).collect();
    let outside: Vec<usize> = (0..4).filter(|&a| s[a] <= 0.0).collect();
    if inside.is_empty() || outside.is_empty() {
        return;
    }
    let mut ev = |a: usize, b: usize| -> usize {
        let (na, nb) = (t[a], t[b]);
        let key = (na.min(nb), na.max(nb));
        *edge_vert.entry(key).or_insert_with(|| {
            let (sa, sb) = (s[a], s[b]);
            let w = (sa / (sa - sb)).clamp(1e-6, 1.0 - 1e-6);
            verts.push(pos(na) + (pos(nb) - pos(na)) * w);
            verts.len() - 1
        })
    };
    let cin = inside.iter().map(|&a| pos(t[a])).sum::<Vector<3>>() / inside.len() as f64;
    let cout = outside.iter().map(|&a| pos(t[a])).sum::<Vector<3>>() / outside.len() as f64;
    let outward = cout - cin;
    let emit = |tri: [usize; 3], verts: &Vec<Vector<3>>, faces: &mut Vec<[usize; 3]>| {
        let nrm = (verts[tri[1]] - verts[tri[0]]).cross(&(verts[tri[2]] - verts[tri[0]]));
        if nrm.dot(&outward) < 0.0 {
            faces.push([tri[0], tri[2], tri[1]]);
        } else {
            faces.push(tri);
        }
    };
    if inside.len() == 1 || outside.len() == 1 {
        let (apex, others) = if inside.len() == 1 { (inside[0], &outside) } else { (outside[0], &inside) };
        let tri = [ev(apex, others[0]), ev(apex, others[1]), ev(apex, others[2])];
        emit(tri, verts, faces);
    } else {
        let (a, b) = (inside[0], inside[1]);
        let (c, d) = (outside[0], outside[1]);
        let (v_ac, v_ad, v_bc, v_bd) = (ev(a, c), ev(a, d), ev(b, c), ev(b, d));
        // quad a-c, a-d, b-d, b-c
        emit([v_ac, v_ad, v_bd], verts, faces);
        emit([v_ac, v_bd, v_bc], verts, faces);
    }
}
