//! Tetrahedralisation of a closed surface: body-centred cubic (BCC) lattice tetrahedra kept when
//! their centroid is inside, then boundary nodes snapped onto the surface under a dihedral-angle
//! guard (the lattice part of isosurface stuffing, Labelle & Shewchuk 2007, without its stencils).
use super::geom::{dihedral_angles_deg, tet_min_dihedral_deg, tet_signed_volume, Surface};
use crate::error::{FemError, Result};
use laparo_core::mesh::{TetMesh, TriMesh};
use nalgebra::Vector3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::collections::HashSet;

type V3 = Vector3<f64>;

/// Parameters of [`tetrahedralize`].
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(default)]
pub struct TetraParams {
    /// Target edge length (mm) = BCC lattice spacing: axis-parallel edges have this length, the
    /// corner–centre edges √3/2 of it (mean edge ≈ 0.92 × `edge_mm`).
    pub edge_mm: f64,
    /// Smallest dihedral angle (deg) a snapping move may leave in any tetrahedron; lattice
    /// tetrahedra have 60° and 90°, so the output's min dihedral is ≥ min(this, 60°).
    pub min_dihedral_deg: f64,
    /// Passes of boundary snapping (each tries full, 3/4, 1/2 and 1/4 of the move to the surface).
    pub snap_passes: usize,
}

impl Default for TetraParams {
    fn default() -> Self {
        TetraParams { edge_mm: 6.0, min_dihedral_deg: 10.0, snap_passes: 4 }
    }
}

/// A percentile of a distribution.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Percentile {
    /// Percent (0–100).
    pub pct: f64,
    /// Value at that percent.
    pub value: f64,
}

/// Quality of a tetrahedral mesh against the surface it was built from.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct QualityReport {
    /// Number of nodes.
    pub nodes: usize,
    /// Number of tetrahedra.
    pub tets: usize,
    /// Tetrahedra with volume ≤ 0 (must be 0).
    pub inverted: usize,
    /// Smallest tetrahedron volume (mm³).
    pub min_tet_volume_mm3: f64,
    /// Smallest dihedral angle over all tetrahedra (deg).
    pub min_dihedral_deg: f64,
    /// Largest dihedral angle over all tetrahedra (deg).
    pub max_dihedral_deg: f64,
    /// Percentiles of the per-tetrahedron smallest dihedral angle (deg).
    pub min_dihedral_percentiles_deg: Vec<Percentile>,
    /// Histogram of all dihedral angles in 10° bins, [0, 10), [10, 20), …, [170, 180].
    pub dihedral_histogram_10deg: Vec<usize>,
    /// Mean, smallest and largest edge length (mm).
    pub edge_mean_mm: f64,
    /// Smallest edge length (mm).
    pub edge_min_mm: f64,
    /// Largest edge length (mm).
    pub edge_max_mm: f64,
    /// Sum of tetrahedron volumes (mm³).
    pub volume_mm3: f64,
    /// Volume enclosed by the input surface (mm³), if given.
    pub surface_volume_mm3: Option<f64>,
    /// (volume − surface volume) / surface volume, if the surface is given.
    pub volume_rel_error: Option<f64>,
    /// Nodes on boundary faces.
    pub boundary_nodes: usize,
    /// Boundary faces.
    pub boundary_faces: usize,
    /// Largest distance of a boundary node to the input surface (mm), if given.
    pub max_boundary_distance_mm: Option<f64>,
    /// Mean distance of boundary nodes to the input surface (mm), if given.
    pub mean_boundary_distance_mm: Option<f64>,
    /// Faces of the input surface that [`tetrahedralize_surface`] flipped to orient it consistently and
    /// outward (0: it already was).
    #[serde(default)]
    pub orientation_flipped_faces: usize,
    /// What the caller should tell the user: a re-oriented surface, a tet volume far from the surface
    /// volume, an organ only a few elements across (units?).
    #[serde(default)]
    pub warnings: Vec<String>,
}

fn corners(m: &TetMesh, t: &[usize; 4]) -> [V3; 4] {
    t.map(|k| m.vertices[k])
}

/// Tetrahedralise the closed surface `surface` (mm) on a BCC lattice of spacing `edge_mm`.
/// Every output tetrahedron is positively oriented with min dihedral ≥ min(`min_dihedral_deg`, 60°).
pub fn tetrahedralize(surface: &Surface, params: &TetraParams) -> Result<TetMesh> {
    let h = params.edge_mm;
    let (lo, hi) = surface.mesh.bounding_box().ok_or_else(|| FemError::bad("surface", "empty"))?;
    if !(h.is_finite() && h > 0.0) {
        return Err(FemError::param("edge_mm", h, "must be a positive length in mm"));
    }
    let diag = (hi - lo).norm();
    if h > diag {
        return Err(FemError::param(
            "edge_mm",
            h,
            format!("larger than the surface's bounding-box diagonal {diag:.3} mm"),
        ));
    }
    if diag / h > 1000.0 {
        return Err(FemError::param("edge_mm", h, format!("more than 1000 lattice cells across {diag:.3} mm")));
    }
    if !(0.0..60.0).contains(&params.min_dihedral_deg) {
        return Err(FemError::param("min_dihedral_deg", params.min_dihedral_deg, "must be in [0, 60)"));
    }
    // A small fixed offset keeps lattice planes off axis-aligned input faces (deterministic).
    let origin = lo - V3::from_element(h) + V3::new(0.0137, 0.0291, 0.0419) * h;
    let n: [usize; 3] = std::array::from_fn(|d| ((hi[d] - lo[d]) / h).ceil() as usize + 2);
    let ncorner = (n[0] + 1) * (n[1] + 1) * (n[2] + 1);
    let corner_id = |i: [usize; 3]| (i[0] * (n[1] + 1) + i[1]) * (n[2] + 1) + i[2];
    let centre_id = |i: [usize; 3]| ncorner + (i[0] * n[1] + i[1]) * n[2] + i[2];
    let pos = |id: usize| -> V3 {
        if id < ncorner {
            let k = id % (n[2] + 1);
            let j = (id / (n[2] + 1)) % (n[1] + 1);
            let i = id / ((n[2] + 1) * (n[1] + 1));
            origin + V3::new(i as f64, j as f64, k as f64) * h
        } else {
            let c = id - ncorner;
            let k = c % n[2];
            let j = (c / n[2]) % n[1];
            let i = c / (n[2] * n[1]);
            origin + V3::new(i as f64 + 0.5, j as f64 + 0.5, k as f64 + 0.5) * h
        }
    };
    // Candidate tetrahedra: for each pair of face-adjacent cells, the 4 tets (centre, centre,
    // edge of the shared face).
    let ncell = n[0] * n[1] * n[2];
    let kept: Vec<Vec<[usize; 4]>> = (0..ncell)
        .into_par_iter()
        .map(|c| {
            let i = [c / (n[1] * n[2]), (c / n[2]) % n[1], c % n[2]];
            let mut out = Vec::new();
            for d in 0..3 {
                if i[d] + 1 >= n[d] {
                    continue;
                }
                let mut j = i;
                j[d] += 1;
                let (d1, d2) = ((d + 1) % 3, (d + 2) % 3);
                let q: [usize; 4] = [(0, 0), (1, 0), (1, 1), (0, 1)].map(|(a, b)| {
                    let mut k = i;
                    k[d] += 1;
                    k[d1] += a;
                    k[d2] += b;
                    corner_id(k)
                });
                for m in 0..4 {
                    let mut t = [centre_id(i), centre_id(j), q[m], q[(m + 1) % 4]];
                    let p = t.map(pos);
                    let centroid = (p[0] + p[1] + p[2] + p[3]) / 4.0;
                    if surface.contains(&centroid) {
                        if tet_signed_volume(&p) < 0.0 {
                            t.swap(2, 3);
                        }
                        out.push(t);
                    }
                }
            }
            out
        })
        .collect();
    let mut tets: Vec<[usize; 4]> = kept.into_iter().flatten().collect();
    if tets.is_empty() {
        return Err(FemError::param(
            "edge_mm",
            h,
            "no lattice tetrahedron lies inside the surface: use a smaller edge",
        ));
    }
    // Compact the node numbering (lattice order).
    let mut map = vec![usize::MAX; ncorner + ncell];
    let mut used: Vec<usize> = tets.iter().flatten().copied().collect();
    used.sort_unstable();
    used.dedup();
    for (k, &id) in used.iter().enumerate() {
        map[id] = k;
    }
    for t in &mut tets {
        *t = t.map(|id| map[id]);
    }
    let vertices: Vec<V3> = used.iter().map(|&id| pos(id)).collect();
    let mut mesh = TetMesh { vertices, tets };
    snap_boundary(&mut mesh, surface, params);
    Ok(mesh)
}

/// Node → incident tetrahedra (CSR: offsets, tet indices).
pub(crate) fn node_tets(mesh: &TetMesh) -> (Vec<usize>, Vec<usize>) {
    let mut off = vec![0usize; mesh.vertices.len() + 1];
    for t in &mesh.tets {
        for &v in t {
            off[v + 1] += 1;
        }
    }
    for i in 0..mesh.vertices.len() {
        off[i + 1] += off[i];
    }
    let mut fill = off.clone();
    let mut idx = vec![0usize; off[mesh.vertices.len()]];
    for (ti, t) in mesh.tets.iter().enumerate() {
        for &v in t {
            idx[fill[v]] = ti;
            fill[v] += 1;
        }
    }
    (off, idx)
}

/// Move boundary nodes towards their closest surface point, accepting a move only if every
/// incident tetrahedron keeps a min dihedral ≥ `min_dihedral_deg`.
fn snap_boundary(mesh: &mut TetMesh, surface: &Surface, params: &TetraParams) {
    let boundary = mesh.boundary();
    let mut nodes: Vec<usize> = boundary.faces.iter().flatten().copied().collect();
    nodes.sort_unstable();
    nodes.dedup();
    let (off, idx) = node_tets(mesh);
    let floor = params.min_dihedral_deg;
    let mut done = vec![false; nodes.len()];
    for _ in 0..params.snap_passes {
        let targets: Vec<V3> = nodes.par_iter().map(|&v| surface.closest_point(&mesh.vertices[v]).0).collect();
        for (k, &v) in nodes.iter().enumerate() {
            if done[k] {
                continue;
            }
            let x = mesh.vertices[v];
            for frac in [1.0, 0.75, 0.5, 0.25] {
                let trial = x + (targets[k] - x) * frac;
                mesh.vertices[v] = trial;
                let ok = idx[off[v]..off[v + 1]]
                    .iter()
                    .all(|&t| tet_min_dihedral_deg(&corners(mesh, &mesh.tets[t])) >= floor);
                if ok {
                    if frac == 1.0 {
                        done[k] = true;
                    }
                    break;
                }
                mesh.vertices[v] = x;
            }
        }
    }
}

/// Quality of `mesh`; with `surface`, also the volume error and boundary-node distances.
pub fn quality_report(mesh: &TetMesh, surface: Option<&Surface>) -> QualityReport {
    let per: Vec<(f64, f64, [f64; 6])> = mesh
        .tets
        .par_iter()
        .map(|t| {
            let p = corners(mesh, t);
            (tet_signed_volume(&p), tet_min_dihedral_deg(&p), dihedral_angles_deg(&p))
        })
        .collect();
    let inverted = per.iter().filter(|x| x.0 <= 0.0).count();
    let min_vol = per.iter().map(|x| x.0).fold(f64::INFINITY, f64::min);
    let mut hist = vec![0usize; 18];
    let (mut dmin, mut dmax) = (f64::INFINITY, f64::NEG_INFINITY);
    let mut mins: Vec<f64> = Vec::with_capacity(per.len());
    for (_, _, a) in &per {
        let mut m = f64::INFINITY;
        for &x in a {
            hist[((x / 10.0).floor() as usize).min(17)] += 1;
            dmin = dmin.min(x);
            dmax = dmax.max(x);
            m = m.min(x);
        }
        mins.push(m);
    }
    mins.sort_by(f64::total_cmp);
    let pct = |p: f64| -> f64 {
        if mins.is_empty() {
            return f64::NAN;
        }
        mins[((p / 100.0 * (mins.len() - 1) as f64).round() as usize).min(mins.len() - 1)]
    };
    let percentiles = [0.1, 1.0, 5.0, 50.0].iter().map(|&p| Percentile { pct: p, value: pct(p) }).collect();
    let mut edges: HashSet<(usize, usize)> = HashSet::new();
    for t in &mesh.tets {
        for a in 0..4 {
            for b in a + 1..4 {
                edges.insert((t[a].min(t[b]), t[a].max(t[b])));
            }
        }
    }
    let mut edges: Vec<(usize, usize)> = edges.into_iter().collect();
    edges.sort_unstable();
    let lens: Vec<f64> = edges.iter().map(|&(a, b)| (mesh.vertices[a] - mesh.vertices[b]).norm()).collect();
    let volume: f64 = per.iter().map(|x| x.0).sum();
    let boundary: TriMesh = mesh.boundary();
    let mut bnodes: Vec<usize> = boundary.faces.iter().flatten().copied().collect();
    bnodes.sort_unstable();
    bnodes.dedup();
    let (sv, err, dmaxb, dmeanb) = match surface {
        Some(s) => {
            let sv = s.volume();
            let d: Vec<f64> = bnodes.par_iter().map(|&v| s.closest_point(&mesh.vertices[v]).1).collect();
            let mx = d.iter().copied().fold(0.0, f64::max);
            let mean = d.iter().sum::<f64>() / d.len().max(1) as f64;
            (Some(sv), Some((volume - sv) / sv), Some(mx), Some(mean))
        }
        None => (None, None, None, None),
    };
    QualityReport {
        nodes: mesh.vertices.len(),
        tets: mesh.tets.len(),
        inverted,
        min_tet_volume_mm3: min_vol,
        min_dihedral_deg: dmin,
        max_dihedral_deg: dmax,
        min_dihedral_percentiles_deg: percentiles,
        dihedral_histogram_10deg: hist,
        edge_mean_mm: lens.iter().sum::<f64>() / lens.len().max(1) as f64,
        edge_min_mm: lens.iter().copied().fold(f64::INFINITY, f64::min),
        edge_max_mm: lens.iter().copied().fold(0.0, f64::max),
        volume_mm3: volume,
        surface_volume_mm3: sv,
        volume_rel_error: err,
        boundary_nodes: bnodes.len(),
        boundary_faces: boundary.faces.len(),
        max_boundary_distance_mm: dmaxb,
        mean_boundary_distance_mm: dmeanb,
        orientation_flipped_faces: 0,
        warnings: Vec::new(),
    }
}

/// Re-orient the faces of the closed surface `mesh` consistently (neighbouring faces traverse their
/// shared edge in opposite directions), each connected piece outward (positive enclosed volume).
/// Returns the number of faces flipped, or `None` when no consistent orientation exists (a
/// non-orientable or non-manifold surface; `mesh` is then left as it was).
pub fn orient_outward(mesh: &mut TriMesh) -> Option<usize> {
    use std::collections::HashMap;
    let mut by_edge: HashMap<(usize, usize), Vec<usize>> = HashMap::with_capacity(mesh.faces.len() * 3 / 2);
    for (fi, f) in mesh.faces.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            by_edge.entry((a.min(b), a.max(b))).or_default().push(fi);
        }
    }
    // +1 when face `f` (as given) runs a → b, −1 when it runs b → a
    let dir = |f: &[usize; 3], a: usize, b: usize| -> f64 {
        if (0..3).any(|k| f[k] == a && f[(k + 1) % 3] == b) {
            1.0
        } else {
            -1.0
        }
    };
    let n = mesh.faces.len();
    let mut sign = vec![0.0f64; n];
    for seed in 0..n {
        if sign[seed] != 0.0 {
            continue;
        }
        sign[seed] = 1.0;
        let mut component = vec![seed];
        let mut queue = std::collections::VecDeque::from([seed]);
        while let Some(fi) = queue.pop_front() {
            let f = mesh.faces[fi];
            for k in 0..3 {
                let (a, b) = (f[k], f[(k + 1) % 3]);
                let nb = &by_edge[&(a.min(b), a.max(b))];
                if nb.len() != 2 {
                    return None;
                }
                for &g in nb.iter().filter(|&&g| g != fi) {
                    // the two faces must run their shared edge in opposite directions
                    let want = -dir(&f, a, b) * sign[fi] * dir(&mesh.faces[g], a, b);
                    if sign[g] == 0.0 {
                        sign[g] = want;
                        component.push(g);
                        queue.push_back(g);
                    } else if sign[g] != want {
                        return None;
                    }
                }
            }
        }
        // outward: the piece encloses a positive volume
        let vol: f64 = component
            .iter()
            .map(|&fi| {
                let f = mesh.faces[fi];
                let (p, q, r) = (mesh.vertices[f[0]], mesh.vertices[f[1]], mesh.vertices[f[2]]);
                sign[fi] * p.dot(&q.cross(&r)) / 6.0
            })
            .sum();
        if vol < 0.0 {
            for &fi in &component {
                sign[fi] = -sign[fi];
            }
        }
    }
    let mut flipped = 0;
    for (f, s) in mesh.faces.iter_mut().zip(&sign) {
        if *s < 0.0 {
            f.swap(1, 2);
            flipped += 1;
        }
    }
    Some(flipped)
}

/// A tet volume further than this from the surface volume (relative) is a warning.
pub const VOLUME_WARNING_FRACTION: f64 = 0.03;

/// An organ fewer elements across than this (its smallest bounding-box side / edge) gets a units hint.
pub const FEW_ELEMENTS_ACROSS: f64 = 4.0;

/// Check the closed surface `mesh` (named `input` in errors), orient it consistently and outward
/// ([`orient_outward`], said in the report's warnings when it flipped faces), tetrahedralise it and
/// report quality, with warnings when the tet volume is more than [`VOLUME_WARNING_FRACTION`] from
/// the surface volume or the organ is fewer than [`FEW_ELEMENTS_ACROSS`] elements across.
pub fn tetrahedralize_surface(
    mut mesh: TriMesh,
    input: &str,
    params: &TetraParams,
) -> Result<(TetMesh, QualityReport)> {
    mesh.validate().map_err(|e| FemError::bad(input, e.to_string()))?;
    super::geom::check_closed(&mesh, input)?;
    let mut warnings = Vec::new();
    let flipped = match orient_outward(&mut mesh) {
        Some(0) => 0,
        Some(k) => {
            warnings.push(format!(
                "{input}: {k} of {} faces were wound against their neighbours (or the surface was inside out); \
                 re-oriented consistently and outward before meshing (the enclosed volume is now {:.0} mm³)",
                mesh.faces.len(),
                mesh.signed_volume()
            ));
            k
        }
        None => {
            warnings.push(format!(
                "{input}: the faces cannot be oriented consistently (non-manifold or non-orientable surface): \
                 the surface volume below is unreliable"
            ));
            0
        }
    };
    let (lo, hi) = mesh.bounding_box().ok_or_else(|| FemError::bad(input, "empty surface"))?;
    let surface = Surface::new(mesh, input)?;
    let tets = tetrahedralize(&surface, params)?;
    let mut report = quality_report(&tets, Some(&surface));
    report.orientation_flipped_faces = flipped;
    if let (Some(err), Some(sv)) = (report.volume_rel_error, report.surface_volume_mm3) {
        if err.abs() > VOLUME_WARNING_FRACTION {
            warnings.push(format!(
                "{input}: the tetrahedra hold {:.0} mm³, the surface encloses {sv:.0} mm³ ({:+.1} %, more than \
                 {:.0} %): the mesh does not represent the organ (--edge-mm {} too coarse for it?)",
                report.volume_mm3,
                100.0 * err,
                100.0 * VOLUME_WARNING_FRACTION,
                params.edge_mm
            ));
        }
    }
    let ext = hi - lo;
    let across = ext.min() / params.edge_mm;
    if across < FEW_ELEMENTS_ACROSS {
        warnings.push(format!(
            "{input}: the organ is {:.1} x {:.1} x {:.1} (file units, read as mm), only {across:.1} elements of \
             --edge-mm {} across its thinnest side ({} tetrahedra): is the surface in cm or m? (the SOFA liver \
             is in cm: scale it by 10), or use a smaller --edge-mm",
            ext[0], ext[1], ext[2], params.edge_mm, report.tets
        ));
    }
    report.warnings = warnings;
    Ok((tets, report))
}
