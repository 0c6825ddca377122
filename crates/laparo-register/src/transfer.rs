//! Deformation transfer (§5.4.3: "deformation field by barycentric interpolation" from the registered
//! particles): the rest particles lie on a lattice, whose cells are split into D! Kuhn (Freudenthal)
//! simplices — a conforming tetrahedralisation of the rest particles with no Delaunay degeneracy. A query
//! point gets the barycentric coordinates of its simplex in the rest configuration, and the same weights
//! are applied to the deformed particles. Points outside every complete cell use the nearest complete
//! cell's simplex (affine extrapolation, flagged). A simplex with an edge stretched more than
//! `straddle_stretch` × its rest length straddles a separation (an incision) and is flagged.
use crate::distance::build_tree;
use crate::error::{RegisterError, Result};
use kiddo::SquaredEuclidean;
use laparo_mpm::Vector;
use std::collections::HashMap;

/// Barycentric transfer over the rest lattice.
pub struct Transfer<const D: usize> {
    origin: Vector<D>,
    spacing: f64,
    index: HashMap<[i64; D], usize>,
    complete: Vec<[i64; D]>,
    tree: Option<crate::distance::Tree<D>>,
    /// Stretch ratio above which a simplex is flagged as straddling a separation.
    pub straddle_stretch: f64,
}

/// A transferred point.
#[derive(Clone, Copy, Debug)]
pub struct Transferred<const D: usize> {
    /// Deformed position.
    pub position: Vector<D>,
    /// Outside every complete lattice cell (extrapolated).
    pub extrapolated: bool,
    /// The simplex straddles a separation.
    pub straddles: bool,
}

impl<const D: usize> Transfer<D> {
    /// Index the rest particles (on a lattice of `spacing`; positions off the lattice by more than 1e-6
    /// spacing are an error).
    pub fn new(rest: &[Vector<D>], spacing: f64) -> Result<Self> {
        if rest.is_empty() {
            return Err(RegisterError::bad("particles", "no particle to transfer from"));
        }
        let mut lo = rest[0];
        for p in rest {
            lo = lo.inf(p);
        }
        let origin = lo;
        let mut index = HashMap::with_capacity(rest.len());
        for (i, p) in rest.iter().enumerate() {
            let mut key = [0i64; D];
            for d in 0..D {
                let u = (p[d] - origin[d]) / spacing;
                let r = u.round();
                if (u - r).abs() > 1e-6 {
                    return Err(RegisterError::bad(
                        "particles",
                        format!("particle {i} is not on the lattice of spacing {spacing}"),
                    ));
                }
                key[d] = r as i64;
            }
            index.entry(key).or_insert(i);
        }
        let mut complete: Vec<[i64; D]> =
            index.keys().filter(|k| (0..1usize << D).all(|c| index.contains_key(&corner(k, c)))).copied().collect();
        complete.sort();
        let centres: Vec<Vector<D>> =
            complete.iter().map(|k| origin + Vector::<D>::from_fn(|d, _| (k[d] as f64 + 0.5) * spacing)).collect();
        let tree = (!centres.is_empty()).then(|| build_tree(&centres));
        Ok(Transfer { origin, spacing, index, complete, tree, straddle_stretch: 3.0 })
    }

    /// Number of complete lattice cells.
    pub fn cells(&self) -> usize {
        self.complete.len()
    }

    /// Map a rest point q through the deformation given by `deformed` (same order as `rest`).
    pub fn apply(&self, q: &Vector<D>, deformed: &[Vector<D>]) -> Result<Transferred<D>> {
        let u: Vector<D> = (q - self.origin) / self.spacing;
        let mut cell = [0i64; D];
        for d in 0..D {
            cell[d] = u[d].floor() as i64;
        }
        let mut extrapolated = false;
        if !(0..1usize << D).all(|c| self.index.contains_key(&corner(&cell, c))) {
            let Some(tree) = &self.tree else {
                return Err(RegisterError::bad(
                    "particles",
                    "no complete lattice cell: too few particles to interpolate",
                ));
            };
            let a: [f64; D] = std::array::from_fn(|d| q[d]);
            cell = self.complete[tree.nearest_one::<SquaredEuclidean>(&a).item as usize];
            extrapolated = true;
        }
        let f: [f64; D] = std::array::from_fn(|d| u[d] - cell[d] as f64);
        // Kuhn simplex: axes sorted by the fractional coordinate (clamped for the choice only)
        let mut order: [usize; D] = std::array::from_fn(|d| d);
        order.sort_by(|&a, &b| f[b].clamp(0.0, 1.0).total_cmp(&f[a].clamp(0.0, 1.0)).then(a.cmp(&b)));
        let mut verts = [cell; 4];
        let mut weights = [0.0; 4];
        weights[0] = 1.0 - f[order[0]];
        for k in 0..D {
            verts[k + 1] = verts[k];
            verts[k + 1][order[k]] += 1;
            let next = if k + 1 < D { f[order[k + 1]] } else { 0.0 };
            weights[k + 1] = f[order[k]] - next;
        }
        let mut pos = Vector::<D>::zeros();
        let ids: Vec<usize> = (0..=D).map(|k| self.index[&verts[k]]).collect();
        for k in 0..=D {
            pos += deformed[ids[k]] * weights[k];
        }
        let mut straddles = false;
        for a in 0..=D {
            for b in a + 1..=D {
                let rest_len =
                    (0..D).map(|d| ((verts[a][d] - verts[b][d]) as f64).powi(2)).sum::<f64>().sqrt() * self.spacing;
                straddles |= (deformed[ids[a]] - deformed[ids[b]]).norm() > self.straddle_stretch * rest_len;
            }
        }
        Ok(Transferred { position: pos, extrapolated, straddles })
    }
}

fn corner<const D: usize>(k: &[i64; D], c: usize) -> [i64; D] {
    std::array::from_fn(|d| k[d] + ((c >> d) & 1) as i64)
}
