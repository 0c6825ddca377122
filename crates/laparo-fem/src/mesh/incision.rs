//! Incisions: a blade (ruled surface swept from a surface polyline into the organ) cracks a
//! tetrahedral mesh along existing faces by duplicating nodes (thesis §5.4.2: the cut that the
//! equal and opposite lip forces then open). Lip curves and landmarks are stored as node
//! references so that the same material points can be evaluated in any deformed configuration.
use super::geom::{closest_point_on_triangle, ray_triangle, tet_min_dihedral_deg, tet_signed_volume};
use super::tetra::node_tets;
use crate::error::{FemError, Result};
use laparo_core::mesh::{TetMesh, TriMesh};
use nalgebra::Vector3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::Path;

type V3 = Vector3<f64>;

/// Smallest dihedral angle (deg) that snapping crack nodes onto the blade may leave in a tet.
pub const CRACK_SNAP_MIN_DIHEDRAL_DEG: f64 = 10.0;

/// A blade: the ruled surface between `mouth[i] − overshoot_mm · directions[i]` and
/// `mouth[i] + depths[i] · directions[i]`, i.e. the polyline `mouth` (on the organ surface, mm)
/// swept inward. Side A of the cut is the side of the normal (mouth tangent) × (direction).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Blade {
    /// Where the blade enters the organ surface, ordered along the incision (mm).
    pub mouth: Vec<V3>,
    /// Per mouth point, the unit direction into the organ.
    pub directions: Vec<V3>,
    /// Per mouth point, the depth along `directions` (mm).
    pub depths: Vec<f64>,
    /// How far the blade extends outward beyond the mouth (mm), so that it surely crosses the surface.
    pub overshoot_mm: f64,
}

impl Blade {
    /// A blade with one direction and depth for every point of `mouth`.
    pub fn uniform(mouth: Vec<V3>, direction: V3, depth_mm: f64, overshoot_mm: f64) -> Self {
        let n = mouth.len();
        Blade { mouth, directions: vec![direction.normalize(); n], depths: vec![depth_mm; n], overshoot_mm }
    }

    fn validate(&self) -> Result<()> {
        let n = self.mouth.len();
        if n < 2 {
            return Err(FemError::bad("blade", format!("the mouth polyline needs ≥ 2 points, has {n}")));
        }
        if self.directions.len() != n || self.depths.len() != n {
            return Err(FemError::bad(
                "blade",
                format!("{n} mouth points but {} directions and {} depths", self.directions.len(), self.depths.len()),
            ));
        }
        for (i, d) in self.depths.iter().enumerate() {
            if !(d.is_finite() && *d > 0.0) {
                return Err(FemError::param(format!("blade depth[{i}]"), *d, "must be a positive length in mm"));
            }
        }
        if !(self.overshoot_mm.is_finite() && self.overshoot_mm >= 0.0) {
            return Err(FemError::param("blade overshoot_mm", self.overshoot_mm, "must be ≥ 0 mm"));
        }
        if self.mouth.iter().chain(&self.directions).any(|p| !p.iter().all(|x| x.is_finite())) {
            return Err(FemError::bad("blade", "non-finite mouth point or direction"));
        }
        Ok(())
    }

    /// The blade as triangles (two per mouth segment), normals towards side A.
    pub fn surface(&self) -> TriMesh {
        let n = self.mouth.len();
        let mut vertices = Vec::with_capacity(2 * n);
        for i in 0..n {
            let d = self.directions[i].normalize();
            vertices.push(self.mouth[i] - d * self.overshoot_mm);
            vertices.push(self.mouth[i] + d * self.depths[i]);
        }
        let mut faces = Vec::with_capacity(2 * n);
        for i in 0..n - 1 {
            let (t0, b0, t1, b1) = (2 * i, 2 * i + 1, 2 * i + 2, 2 * i + 3);
            faces.push([t0, t1, b0]);
            faces.push([t1, b1, b0]);
        }
        TriMesh { vertices, faces }
    }
}

/// A tetrahedral mesh cracked along a blade.
#[derive(Clone, Debug)]
pub struct CutMesh {
    /// The cut mesh: crack nodes duplicated, all tetrahedra positively oriented (mm).
    pub mesh: TetMesh,
    /// Per tetrahedron: 1 if it owns a crack face of side A, 2 for side B, 0 otherwise.
    pub tet_side: Vec<u8>,
    /// Crack faces of side A (`[0]`) and side B (`[1]`), each wound outward from its own side's tet.
    pub crack_faces: [Vec<[usize; 3]>; 2],
    /// Per node of the cut mesh, the node of the input mesh it comes from.
    pub original_node: Vec<usize>,
    /// Lip curves of side A and B: the ordered surface polylines (node ids) where the crack meets
    /// the outer surface (the mouth of the incision), both running from the blade's first mouth
    /// point towards its last.
    pub lips: [Vec<usize>; 2],
    /// Crack-front nodes: nodes on crack faces of both sides (not duplicated).
    pub front_nodes: Vec<usize>,
    /// The blade triangles.
    pub blade: TriMesh,
}

/// A material point on a lip curve: `(1 − t) x[a] + t x[b]` for any configuration `x`.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
pub struct Landmark {
    /// 0 = side A, 1 = side B.
    pub side: u8,
    /// First node (cut-mesh id).
    pub a: usize,
    /// Second node (cut-mesh id).
    pub b: usize,
    /// Weight of `b` in [0, 1].
    pub t: f64,
}

/// Landmarks on both lips (N/2 per side, equally spaced by arc length in the rest configuration).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Landmarks {
    /// Side A's landmarks then side B's, each in lip order.
    pub items: Vec<Landmark>,
}

impl Landmarks {
    /// Positions of the landmarks in a configuration `positions` (one per cut-mesh node, mm).
    pub fn landmark_positions(&self, positions: &[V3]) -> Vec<V3> {
        self.items.iter().map(|l| positions[l.a] * (1.0 - l.t) + positions[l.b] * l.t).collect()
    }
}

/// Faces opposite each vertex of a positive tet, wound outward.
fn tet_face(t: &[usize; 4], f: usize) -> [usize; 3] {
    match f {
        0 => [t[1], t[2], t[3]],
        1 => [t[0], t[3], t[2]],
        2 => [t[0], t[1], t[3]],
        _ => [t[0], t[2], t[1]],
    }
}

fn sorted3(mut f: [usize; 3]) -> [usize; 3] {
    f.sort_unstable();
    f
}

fn find(p: &mut [usize], mut i: usize) -> usize {
    while p[i] != i {
        p[i] = p[p[i]];
        i = p[i];
    }
    i
}

/// Interior face pairs `(t1, f1, t2, f2)` (face `f1` of tet `t1` = face `f2` of `t2`), in tet order.
fn face_pairs(mesh: &TetMesh) -> Vec<(usize, usize, usize, usize)> {
    let mut open: HashMap<[usize; 3], (usize, usize)> = HashMap::with_capacity(mesh.tets.len() * 2);
    let mut pairs = Vec::new();
    for (ti, t) in mesh.tets.iter().enumerate() {
        for f in 0..4 {
            let key = sorted3(tet_face(t, f));
            if let Some((t1, f1)) = open.remove(&key) {
                pairs.push((t1, f1, ti, f));
            } else {
                open.insert(key, (ti, f));
            }
        }
    }
    pairs
}

/// Crack `mesh` (positively oriented tets, mm) along `blade`: an interior face is a crack face
/// when the segment between its two tets' centroids crosses the blade and the two centroids lie
/// on opposite sides of it (side of the closest blade point). Crack nodes are then moved onto the
/// blade where that keeps every incident tet's min dihedral ≥ [`CRACK_SNAP_MIN_DIHEDRAL_DEG`]
/// (the only positions that change). Crack nodes whose tet fan falls
/// into several components across the crack are duplicated, one copy per component; crack-front
/// nodes keep one fan and stay shared.
pub fn cut(mesh: &TetMesh, blade: &Blade) -> Result<CutMesh> {
    blade.validate()?;
    for (i, t) in mesh.tets.iter().enumerate() {
        if tet_signed_volume(&t.map(|k| mesh.vertices[k])) <= 0.0 {
            return Err(FemError::bad("tet mesh", format!("tet {i} {t:?} is not positively oriented")));
        }
    }
    let bs = blade.surface();
    let tris: Vec<[V3; 3]> = bs.faces.iter().map(|f| f.map(|k| bs.vertices[k])).collect();
    let normals: Vec<V3> = tris.iter().map(|p| (p[1] - p[0]).cross(&(p[2] - p[0])).normalize()).collect();
    let (blo, bhi) = bs.bounding_box().ok_or_else(|| FemError::bad("blade", "empty"))?;
    let centroid = |t: usize| -> V3 { mesh.tets[t].iter().map(|&k| mesh.vertices[k]).sum::<V3>() / 4.0 };
    let pairs = face_pairs(mesh);
    // Side of a point: sign of (p − closest blade point) · normal of that triangle.
    let side_of = |p: &V3| -> u8 {
        let mut best = (f64::INFINITY, 0u8);
        for (k, tri) in tris.iter().enumerate() {
            let q = closest_point_on_triangle(p, &tri[0], &tri[1], &tri[2]);
            let d = (p - q).norm_squared();
            if d < best.0 {
                best = (d, if (p - q).dot(&normals[k]) >= 0.0 { 0 } else { 1 });
            }
        }
        best.1
    };
    let crack: Vec<bool> = pairs
        .par_iter()
        .map(|&(t1, _, t2, _)| {
            let (c1, c2) = (centroid(t1), centroid(t2));
            let (lo, hi) = (c1.inf(&c2), c1.sup(&c2));
            if (0..3).any(|d| hi[d] < blo[d] || lo[d] > bhi[d]) {
                return false;
            }
            let dir = c2 - c1;
            let hit = tris
                .iter()
                .any(|p| ray_triangle(&c1, &dir, &p[0], &p[1], &p[2]).is_some_and(|t| (0.0..=1.0).contains(&t)));
            hit && side_of(&c1) != side_of(&c2)
        })
        .collect();
    let crack_pairs: Vec<(usize, usize, usize, usize)> =
        pairs.iter().zip(&crack).filter(|(_, &c)| c).map(|(p, _)| *p).collect();
    if crack_pairs.is_empty() {
        return Err(FemError::bad("incision", "the blade misses the mesh: no interior tet face crosses it"));
    }
    // Tet neighbours and crack flags per (tet, face).
    let nt = mesh.tets.len();
    let mut neigh = vec![[usize::MAX; 4]; nt];
    let mut is_crack = vec![[false; 4]; nt];
    for (&(t1, f1, t2, f2), &c) in pairs.iter().zip(&crack) {
        neigh[t1][f1] = t2;
        neigh[t2][f2] = t1;
        is_crack[t1][f1] = c;
        is_crack[t2][f2] = c;
    }
    let mut side = vec![u8::MAX; nt];
    for &(t1, _, t2, _) in &crack_pairs {
        side[t1] = side_of(&centroid(t1));
        side[t2] = side_of(&centroid(t2));
    }
    // Split the fans of crack nodes.
    let crack_nodes: BTreeSet<usize> =
        crack_pairs.iter().flat_map(|&(t1, f1, _, _)| tet_face(&mesh.tets[t1], f1)).collect();
    let (off, idx) = node_tets(mesh);
    let mut vertices = mesh.vertices.clone();
    // Snap crack nodes onto the blade (full, 3/4, 1/2 or 1/4 of the move) when every incident tet
    // keeps a min dihedral ≥ CRACK_SNAP_MIN_DIHEDRAL_DEG: the crack then follows the blade instead
    // of zigzagging along lattice faces.
    for _ in 0..3 {
        for &v in &crack_nodes {
            let x = vertices[v];
            let target = tris
                .iter()
                .map(|t| closest_point_on_triangle(&x, &t[0], &t[1], &t[2]))
                .min_by(|a, b| (a - x).norm_squared().total_cmp(&(b - x).norm_squared()))
                .unwrap_or(x);
            for frac in [1.0, 0.75, 0.5, 0.25] {
                vertices[v] = x + (target - x) * frac;
                let ok = idx[off[v]..off[v + 1]]
                    .iter()
                    .all(|&t| tet_min_dihedral_deg(&mesh.tets[t].map(|k| vertices[k])) >= CRACK_SNAP_MIN_DIHEDRAL_DEG);
                if ok {
                    break;
                }
                vertices[v] = x;
            }
        }
    }
    let mut original_node: Vec<usize> = (0..mesh.vertices.len()).collect();
    let mut replace: Vec<(usize, usize, usize)> = Vec::new(); // (tet, old node, new node)
    for &v in &crack_nodes {
        let fan = &idx[off[v]..off[v + 1]];
        let local: HashMap<usize, usize> = fan.iter().enumerate().map(|(i, &t)| (t, i)).collect();
        let mut parent: Vec<usize> = (0..fan.len()).collect();
        for (i, &t) in fan.iter().enumerate() {
            let pos_v = mesh.tets[t].iter().position(|&k| k == v).unwrap_or(0);
            for f in 0..4 {
                if f == pos_v || is_crack[t][f] {
                    continue; // the face opposite v does not contain v
                }
                let u = neigh[t][f];
                if u == usize::MAX {
                    continue;
                }
                if let Some(&j) = local.get(&u) {
                    let (a, b) = (find(&mut parent, i), find(&mut parent, j));
                    if a != b {
                        parent[a.max(b)] = a.min(b);
                    }
                }
            }
        }
        let mut new_id: BTreeMap<usize, usize> = BTreeMap::new();
        for (i, &ti) in fan.iter().enumerate() {
            let r = find(&mut parent, i);
            if r == 0 {
                continue; // the component of the first tet keeps the node
            }
            let id = *new_id.entry(r).or_insert_with(|| {
                vertices.push(vertices[v]);
                original_node.push(v);
                vertices.len() - 1
            });
            replace.push((ti, v, id));
        }
    }
    let mut tets = mesh.tets.clone();
    for &(t, old, new) in &replace {
        for k in tets[t].iter_mut() {
            if *k == old {
                *k = new;
            }
        }
    }
    let mut crack_faces: [Vec<[usize; 3]>; 2] = [Vec::new(), Vec::new()];
    for &(t1, f1, t2, f2) in &crack_pairs {
        crack_faces[side[t1] as usize].push(tet_face(&tets[t1], f1));
        crack_faces[side[t2] as usize].push(tet_face(&tets[t2], f2));
    }
    let tet_side: Vec<u8> = side.iter().map(|&s| if s == u8::MAX { 0 } else { s + 1 }).collect();
    let cut_mesh = TetMesh { vertices, tets };
    // Lips: crack-face edges of each side that are also edges of outer (non-crack) boundary faces.
    let crack_keys: BTreeSet<[usize; 3]> = crack_faces.iter().flatten().map(|&f| sorted3(f)).collect();
    let mut outer_edges: BTreeSet<(usize, usize)> = BTreeSet::new();
    for f in cut_mesh.boundary().faces {
        if crack_keys.contains(&sorted3(f)) {
            continue;
        }
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            outer_edges.insert((a.min(b), a.max(b)));
        }
    }
    let mut lips: [Vec<usize>; 2] = [Vec::new(), Vec::new()];
    for s in 0..2 {
        let mut edges: BTreeSet<(usize, usize)> = BTreeSet::new();
        for f in &crack_faces[s] {
            for k in 0..3 {
                let (a, b) = (f[k], f[(k + 1) % 3]);
                let e = (a.min(b), a.max(b));
                if outer_edges.contains(&e) {
                    edges.insert(e);
                }
            }
        }
        let mut chain = longest_chain(&edges);
        if chain.len() < 2 {
            return Err(FemError::bad(
                "incision",
                format!("the crack of side {} does not reach the outer surface (no lip)", ["A", "B"][s]),
            ));
        }
        let start = blade.mouth[0];
        let first = (cut_mesh.vertices[chain[0]] - start).norm();
        let last = (cut_mesh.vertices[*chain.last().unwrap_or(&chain[0])] - start).norm();
        if last < first {
            chain.reverse();
        }
        lips[s] = chain;
    }
    let a_nodes: BTreeSet<usize> = crack_faces[0].iter().flatten().copied().collect();
    let front_nodes: Vec<usize> = crack_faces[1]
        .iter()
        .flatten()
        .copied()
        .filter(|k| a_nodes.contains(k))
        .collect::<BTreeSet<_>>()
        .into_iter()
        .collect();
    Ok(CutMesh { mesh: cut_mesh, tet_side, crack_faces, original_node, lips, front_nodes, blade: bs })
}

/// The longest simple path through an edge set (walked from a degree-1 node when there is one,
/// choosing the smallest unvisited neighbour at branches), as node ids.
fn longest_chain(edges: &BTreeSet<(usize, usize)>) -> Vec<usize> {
    let mut adj: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
    for &(a, b) in edges {
        adj.entry(a).or_default().push(b);
        adj.entry(b).or_default().push(a);
    }
    let mut best: Vec<usize> = Vec::new();
    let mut starts: Vec<usize> = adj.iter().filter(|(_, n)| n.len() == 1).map(|(&k, _)| k).collect();
    if starts.is_empty() {
        starts = adj.keys().copied().take(1).collect();
    }
    for &s in &starts {
        let mut visited: BTreeSet<usize> = BTreeSet::new();
        let mut path = vec![s];
        visited.insert(s);
        let mut cur = s;
        while let Some(&next) = adj[&cur].iter().find(|k| !visited.contains(k)) {
            visited.insert(next);
            path.push(next);
            cur = next;
        }
        // A closed loop: come back to the start.
        if path.len() > 2 && adj[&cur].contains(&s) && adj[&s].len() == 2 {
            path.push(s);
        }
        if path.len() > best.len() {
            best = path;
        }
    }
    best
}

/// `n_total` landmarks, `n_total / 2` per lip, at arc lengths (k + ½) L / (n_total / 2) along each lip
/// (ordered node ids) measured in `positions` (mm); each a material point (a, b, t) of the lip polyline.
pub fn lip_landmarks(lips: &[Vec<usize>; 2], positions: &[V3], n_total: usize) -> Result<Landmarks> {
    if n_total < 2 || !n_total.is_multiple_of(2) {
        return Err(FemError::param("landmarks", n_total as f64, "must be an even count ≥ 2"));
    }
    let per = n_total / 2;
    let mut items = Vec::with_capacity(n_total);
    for (s, lip) in lips.iter().enumerate() {
        if lip.len() < 2 || lip.iter().any(|&k| k >= positions.len()) {
            return Err(FemError::bad(format!("lip {s}"), format!("{} nodes (need ≥ 2 valid ids)", lip.len())));
        }
        let p: Vec<V3> = lip.iter().map(|&k| positions[k]).collect();
        let mut cum = vec![0.0];
        for w in p.windows(2) {
            cum.push(cum.last().unwrap_or(&0.0) + (w[1] - w[0]).norm());
        }
        let total = *cum.last().unwrap_or(&0.0);
        if total.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            return Err(FemError::bad(format!("lip {s}"), "has zero length"));
        }
        let mut seg = 0;
        for k in 0..per {
            let target = (k as f64 + 0.5) * total / per as f64;
            while seg + 2 < cum.len() && cum[seg + 1] < target {
                seg += 1;
            }
            let len = cum[seg + 1] - cum[seg];
            let t = if len > 0.0 { ((target - cum[seg]) / len).clamp(0.0, 1.0) } else { 0.0 };
            items.push(Landmark { side: s as u8, a: lip[seg], b: lip[seg + 1], t });
        }
    }
    Ok(Landmarks { items })
}

impl CutMesh {
    /// Equal and opposite pressure `p_kpa` on the two lips' crack faces, each pushing into its own
    /// side (thesis §5.4.2: the forces that open the incision), as reference-configuration tractions.
    pub fn crack_pressure(&self, p_kpa: f64) -> Vec<crate::solid::FaceTraction> {
        let x = &self.mesh.vertices;
        self.crack_faces
            .iter()
            .flatten()
            .map(|f| {
                let n = (x[f[1]] - x[f[0]]).cross(&(x[f[2]] - x[f[0]])).normalize();
                crate::solid::FaceTraction { face: *f, traction_kpa: -n * p_kpa }
            })
            .collect()
    }

    /// Positions of lip `side` (0 = A, 1 = B) in a configuration `positions` (mm).
    pub fn lip_positions(&self, side: usize, positions: &[V3]) -> Vec<V3> {
        self.lips[side].iter().map(|&k| positions[k]).collect()
    }

    /// Length of lip `side` in the rest configuration (mm).
    pub fn lip_length(&self, side: usize) -> f64 {
        self.lip_positions(side, &self.mesh.vertices).windows(2).map(|w| (w[1] - w[0]).norm()).sum()
    }

    /// `n_total` landmarks, `n_total / 2` per lip, at arc lengths (k + ½) L / (n_total / 2) along
    /// each lip in the rest configuration ([`lip_landmarks`]).
    pub fn landmarks(&self, n_total: usize) -> Result<Landmarks> {
        lip_landmarks(&self.lips, &self.mesh.vertices, n_total)
    }

    /// Connected components of the tets over shared faces (crack faces are no longer shared).
    pub fn components(&self) -> Vec<usize> {
        let pairs = face_pairs(&self.mesh);
        let mut parent: Vec<usize> = (0..self.mesh.tets.len()).collect();
        for (t1, _, t2, _) in pairs {
            let (a, b) = (find(&mut parent, t1), find(&mut parent, t2));
            if a != b {
                parent[a.max(b)] = a.min(b);
            }
        }
        (0..parent.len()).map(|i| find(&mut parent, i)).collect()
    }

    /// Write the cut mesh as legacy VTK (ASCII) with cell data `side` (0/1/2, see
    /// [`CutMesh::tet_side`]) and point data `original_node`, atomically.
    pub fn write_vtk(&self, path: &Path) -> Result<()> {
        use laparo_core::mesh::{write_vtk_fields, VtkField, VtkValues};
        let side: Vec<i64> = self.tet_side.iter().map(|&k| i64::from(k)).collect();
        let original: Vec<i64> = self.original_node.iter().map(|&k| k as i64).collect();
        write_vtk_fields(
            path,
            "laparo cut tetrahedral mesh (mm)",
            &self.mesh.vertices,
            &self.mesh.tets,
            &[VtkField::new("original_node", VtkValues::Int(&original))],
            &[VtkField::new("side", VtkValues::Int(&side))],
        )?;
        Ok(())
    }
}
