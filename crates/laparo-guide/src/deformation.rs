//! The ground-truth deformation of the scenario (thesis §5.4.3, the incision benchmark): a cut
//! tetrahedral mesh at rest (nodes duplicated along the crack), the deformed node positions, the two
//! lip curves (node ids) and the tumour. The real scenario takes it from laparo-fem's FEM of the cut
//! liver (files `rest.vtk` + `deformation.json`); [`synthetic_incision`] is a small stand-in used by
//! the tests and the demo until then: a planar cut along grid faces opened by an analytic smooth
//! field — it is NOT a mechanical simulation.
use crate::error::{GuideError, Result};
use crate::tetmesh::GridTetMesh;
use laparo_core::atomic::write_atomic;
use laparo_core::mesh::{TetMesh, TriMesh};
use laparo_register::baselines::TetLocator;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use std::collections::{HashMap, HashSet};
use std::path::Path;

/// A ground-truth deformation of a cut organ (mm).
#[derive(Clone, Debug)]
pub struct Deformation {
    /// Rest (past) tetrahedral mesh, nodes duplicated along the crack (mm).
    pub rest: TetMesh,
    /// Deformed (present) position of every node (mm).
    pub deformed: Vec<Vector3<f64>>,
    /// Node ids of the two lip curves on the organ surface, ordered along the incision.
    pub lips: [Vec<usize>; 2],
    /// Tumour centre at rest (mm).
    pub tumour_centre_mm: Vector3<f64>,
    /// Tumour radius (mm).
    pub tumour_radius_mm: f64,
}

#[derive(Serialize, Deserialize)]
struct DeformationFile {
    /// `displacement` of every node (mm), deformed = rest + displacement.
    displacement_mm: Vec<[f64; 3]>,
    lips: [Vec<usize>; 2],
    tumour_centre_mm: [f64; 3],
    tumour_radius_mm: f64,
}

impl Deformation {
    /// Validate sizes and ids.
    pub fn validate(&self, input: &str) -> Result<()> {
        let bad = |m: String| GuideError::stage("scenario", input, m);
        self.rest.validate().map_err(|e| bad(e.to_string()))?;
        if self.deformed.len() != self.rest.vertices.len() {
            return Err(bad(format!(
                "{} deformed nodes for {} rest nodes",
                self.deformed.len(),
                self.rest.vertices.len()
            )));
        }
        for (l, lip) in self.lips.iter().enumerate() {
            if lip.len() < 2 || lip.iter().any(|&i| i >= self.rest.vertices.len()) {
                return Err(bad(format!("lip {l}: {} node ids, need ≥ 2 valid ids", lip.len())));
            }
        }
        if !(self.tumour_radius_mm > 0.0) {
            return Err(bad(format!("tumour radius {} mm", self.tumour_radius_mm)));
        }
        Ok(())
    }

    /// Write `dir/rest.vtk` and `dir/deformation.json` (displacements, lips, tumour).
    pub fn write(&self, dir: &Path) -> Result<()> {
        std::fs::create_dir_all(dir).map_err(|e| laparo_core::CoreError::io(dir, e))?;
        laparo_core::mesh::write_vtk(dir.join("rest.vtk"), &self.rest)?;
        let f = DeformationFile {
            displacement_mm: self
                .deformed
                .iter()
                .zip(&self.rest.vertices)
                .map(|(d, r)| {
                    let u = d - r;
                    [u[0], u[1], u[2]]
                })
                .collect(),
            lips: self.lips.clone(),
            tumour_centre_mm: [self.tumour_centre_mm[0], self.tumour_centre_mm[1], self.tumour_centre_mm[2]],
            tumour_radius_mm: self.tumour_radius_mm,
        };
        let text =
            serde_json::to_string(&f).map_err(|e| GuideError::stage("scenario", "deformation.json", e.to_string()))?;
        write_atomic(&dir.join("deformation.json"), text.as_bytes())?;
        Ok(())
    }

    /// Read `dir/rest.vtk` (or `rest.msh`) and `dir/deformation.json`.
    pub fn read(dir: &Path) -> Result<Self> {
        let vtk = dir.join("rest.vtk");
        let rest = if vtk.exists() {
            laparo_core::mesh::read_vtk(&vtk)?
        } else {
            laparo_core::mesh::read_msh(dir.join("rest.msh"))?
        };
        let jp = dir.join("deformation.json");
        let text = std::fs::read_to_string(&jp).map_err(|e| laparo_core::CoreError::io(&jp, e))?;
        let f: DeformationFile = serde_json::from_str(&text)
            .map_err(|e| GuideError::stage("scenario", jp.display().to_string(), e.to_string()))?;
        if f.displacement_mm.len() != rest.vertices.len() {
            return Err(GuideError::stage(
                "scenario",
                jp.display().to_string(),
                format!("{} displacements for {} nodes of rest.vtk", f.displacement_mm.len(), rest.vertices.len()),
            ));
        }
        let deformed =
            rest.vertices.iter().zip(&f.displacement_mm).map(|(r, u)| r + Vector3::new(u[0], u[1], u[2])).collect();
        let d = Deformation {
            rest,
            deformed,
            lips: f.lips,
            tumour_centre_mm: Vector3::new(f.tumour_centre_mm[0], f.tumour_centre_mm[1], f.tumour_centre_mm[2]),
            tumour_radius_mm: f.tumour_radius_mm,
        };
        d.validate(&jp.display().to_string())?;
        Ok(d)
    }

    /// Boundary surface of the cut mesh at rest (past) — crack faces included (coincident pairs).
    pub fn rest_surface(&self) -> TriMesh {
        self.rest.boundary()
    }

    /// The preoperative organ surface: the boundary of the rest mesh with the duplicated nodes merged
    /// (by position), i.e. of the uncut mesh; `.1[i]` = the rest node of vertex i
    /// (one of the copies), `.2[i]` = all copies.
    pub fn preoperative_surface(&self) -> (TriMesh, Vec<usize>, Vec<Vec<usize>>) {
        let key = |p: &Vector3<f64>| [p[0].to_bits(), p[1].to_bits(), p[2].to_bits()];
        let mut rep: HashMap<[u64; 3], usize> = HashMap::new();
        let mut merged = vec![0usize; self.rest.vertices.len()];
        for (i, p) in self.rest.vertices.iter().enumerate() {
            merged[i] = *rep.entry(key(p)).or_insert(i);
        }
        // the uncut mesh: every tetrahedron on the representatives of its nodes
        let uncut = TetMesh {
            vertices: self.rest.vertices.clone(),
            tets: self.rest.tets.iter().map(|t| [merged[t[0]], merged[t[1]], merged[t[2]], merged[t[3]]]).collect(),
        };
        let kept = uncut.boundary().faces;
        // compact
        let mut new_id: HashMap<usize, usize> = HashMap::new();
        let mut node = Vec::new();
        for f in &kept {
            for &v in f {
                new_id.entry(v).or_insert_with(|| {
                    node.push(v);
                    node.len() - 1
                });
            }
        }
        let faces = kept.iter().map(|f| [new_id[&f[0]], new_id[&f[1]], new_id[&f[2]]]).collect();
        let vertices = node.iter().map(|&v| self.rest.vertices[v]).collect();
        let mut copies: HashMap<usize, Vec<usize>> = HashMap::new();
        for (i, &m) in merged.iter().enumerate() {
            copies.entry(m).or_default().push(i);
        }
        let all = node.iter().map(|v| copies[v].clone()).collect();
        (TriMesh { vertices, faces }, node, all)
    }

    /// The uncut rest tetrahedral mesh (duplicated nodes merged by position, unused nodes dropped):
    /// the preoperative volume model.
    pub fn uncut_tets(&self) -> TetMesh {
        let key = |p: &Vector3<f64>| [p[0].to_bits(), p[1].to_bits(), p[2].to_bits()];
        let mut rep: HashMap<[u64; 3], usize> = HashMap::new();
        let mut new_id = vec![usize::MAX; self.rest.vertices.len()];
        let mut vertices = Vec::new();
        for (i, p) in self.rest.vertices.iter().enumerate() {
            let r = *rep.entry(key(p)).or_insert(i);
            if r == i {
                new_id[i] = vertices.len();
                vertices.push(*p);
            } else {
                new_id[i] = new_id[r];
            }
        }
        let tets = self.rest.tets.iter().map(|t| [new_id[t[0]], new_id[t[1]], new_id[t[2]], new_id[t[3]]]).collect();
        TetMesh { vertices, tets }
    }

    /// Deformed boundary surface (present), crack faces included (now exposed).
    pub fn deformed_surface(&self) -> TriMesh {
        let b = self.rest.boundary();
        TriMesh { vertices: self.deformed.clone(), faces: b.faces }
    }

    /// Map rest points through the deformation (barycentric in their rest tetrahedron; points outside
    /// the mesh use the nearest tetrahedron, extrapolated). Returns the deformed points.
    pub fn map_points(&self, pts: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
        let loc = TetLocator::new(&self.rest);
        pts.iter()
            .map(|p| {
                let Some((t, w)) = loc.nearest_tet(p) else { return *p }; // no tetrahedron: nothing moves
                let tet = self.rest.tets[t];
                (0..4).map(|k| self.deformed[tet[k]] * w[k]).sum()
            })
            .collect()
    }
}

/// Parameters of the stand-in incision (model mm).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct IncisionSpec {
    /// Axis of the crack-plane normal (0, 1, 2).
    pub normal_axis: usize,
    /// Axis along which the incision runs on the surface.
    pub span_axis: usize,
    /// Axis pointing out of the cut surface (towards the camera); the crack reaches from the surface
    /// down to `depth_mm` below the highest crack node.
    pub up_axis: usize,
    /// Crack plane position along the normal axis (mm; snapped to the nearest grid plane).
    pub plane_mm: f64,
    /// Span interval (mm).
    pub span_mm: [f64; 2],
    /// Crack depth from the surface (mm).
    pub depth_mm: f64,
    /// Half-opening of the lips at the surface (mm).
    pub opening_mm: f64,
    /// Decay length of the opening away from the plane (mm).
    pub decay_mm: f64,
    /// Tumour: depth below the surface (mm), offset from the plane along the normal (mm), radius (mm).
    pub tumour_depth_mm: f64,
    /// Tumour offset from the crack plane (mm).
    pub tumour_offset_mm: f64,
    /// Tumour radius (mm).
    pub tumour_radius_mm: f64,
}

fn smoothstep(t: f64) -> f64 {
    let t = t.clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// The stand-in incision (see the module docs): duplicate the nodes of the grid faces lying in the
/// plane `normal_axis = plane` inside the span and the top `depth_mm` (nodes on the crack front stay
/// shared), then open it with `u = s · a · n · w_span · w_depth · exp(−(dist/σ)²)`, s = ±1 the side.
pub fn synthetic_incision(g: &GridTetMesh, spec: &IncisionSpec) -> Result<Deformation> {
    let bad = |m: String| GuideError::stage("scenario", "incision", m);
    let (a, s_ax, u_ax) = (spec.normal_axis, spec.span_axis, spec.up_axis);
    if a == s_ax || a == u_ax || s_ax == u_ax || a > 2 || s_ax > 2 || u_ax > 2 {
        return Err(bad("normal, span and up axes must be distinct axes 0..=2".into()));
    }
    let i0 = ((spec.plane_mm - g.origin[a]) / g.h).round() as i64;
    let x0 = g.origin[a] + i0 as f64 * g.h;
    let mesh = &g.mesh;
    let pos = &mesh.vertices;
    // faces of the plane (grid index on the normal axis = i0), between a tet on each side
    let side_of_tet = |t: &[usize; 4]| -> i64 { t.iter().map(|&v| g.grid[v][a] - i0).sum::<i64>().signum() };
    let mut plane_faces: HashMap<[usize; 3], usize> = HashMap::new();
    for t in &mesh.tets {
        let on: Vec<usize> = t.iter().copied().filter(|&v| g.grid[v][a] == i0).collect();
        if on.len() == 3 {
            let mut k = [on[0], on[1], on[2]];
            k.sort_unstable();
            *plane_faces.entry(k).or_insert(0) += 1;
        }
    }
    let plane_faces: Vec<[usize; 3]> = plane_faces.into_iter().filter(|(_, c)| *c == 2).map(|(k, _)| k).collect();
    if plane_faces.is_empty() {
        return Err(bad(format!("the plane at {x0:.1} mm does not cut the organ")));
    }
    let in_span = |v: usize| pos[v][s_ax] >= spec.span_mm[0] - 1e-9 && pos[v][s_ax] <= spec.span_mm[1] + 1e-9;
    let top =
        plane_faces.iter().flatten().filter(|&&v| in_span(v)).map(|&v| pos[v][u_ax]).fold(f64::NEG_INFINITY, f64::max);
    if !top.is_finite() {
        return Err(bad("no plane face inside the span".into()));
    }
    let cut_level = top - spec.depth_mm;
    let in_region = |v: usize| in_span(v) && pos[v][u_ax] >= cut_level - 1e-9;
    let crack: HashSet<[usize; 3]> = plane_faces.iter().copied().filter(|f| f.iter().all(|&v| in_region(v))).collect();
    if crack.is_empty() {
        return Err(bad("the crack region holds no plane face (span or depth too small for the grid)".into()));
    }
    let mut dup: HashSet<usize> = crack.iter().flatten().copied().collect();
    for f in &plane_faces {
        if !crack.contains(f) {
            for v in f {
                dup.remove(v);
            }
        }
    }
    let mut rest = mesh.clone();
    let mut copy: HashMap<usize, usize> = HashMap::new();
    let mut dups: Vec<usize> = dup.iter().copied().collect();
    dups.sort_unstable();
    for &v in &dups {
        copy.insert(v, rest.vertices.len());
        rest.vertices.push(pos[v]);
    }
    for t in rest.tets.iter_mut() {
        if side_of_tet(t) < 0 {
            for v in t.iter_mut() {
                if let Some(&c) = copy.get(v) {
                    *v = c;
                }
            }
        }
    }
    let mut side = vec![0.0f64; rest.vertices.len()];
    for (v, s) in side.iter_mut().enumerate().take(pos.len()) {
        *s = (g.grid[v][a] - i0).signum() as f64;
    }
    for &v in &dups {
        side[v] = 1.0;
        side[copy[&v]] = -1.0;
    }
    let span_len = spec.span_mm[1] - spec.span_mm[0];
    let deformed: Vec<Vector3<f64>> = rest
        .vertices
        .iter()
        .enumerate()
        .map(|(v, p)| {
            let ws = smoothstep((p[s_ax] - spec.span_mm[0]).min(spec.span_mm[1] - p[s_ax]) / (0.3 * span_len));
            let wd = smoothstep((p[u_ax] - cut_level) / spec.depth_mm).sqrt();
            let wn = (-((p[a] - x0) / spec.decay_mm).powi(2)).exp();
            let mut u = Vector3::zeros();
            u[a] = side[v] * spec.opening_mm * ws * wd * wn;
            // the lips also sag a little towards the inside (smooth, same on both sides)
            u[u_ax] = -0.25 * spec.opening_mm * ws * wd * wn;
            p + u
        })
        .collect();
    // lips: duplicated nodes on the outer surface, ordered along the span
    let b = rest.boundary();
    let mut on_surface = vec![false; rest.vertices.len()];
    let crack_keys: HashSet<[usize; 3]> = crack.clone();
    for f in &b.faces {
        let orig: Vec<usize> = f.iter().map(|&v| if v >= pos.len() { dups[v - pos.len()] } else { v }).collect();
        let mut k = [orig[0], orig[1], orig[2]];
        k.sort_unstable();
        if !crack_keys.contains(&k) {
            for &v in f {
                on_surface[v] = true;
            }
        }
    }
    // on the outer surface and at the top of the crack: the highest duplicated node per span position
    let mut by_span: HashMap<i64, usize> = HashMap::new();
    for &v in &dups {
        if on_surface[v] {
            let key = g.grid[v][s_ax];
            let e = by_span.entry(key).or_insert(v);
            if pos[v][u_ax] > pos[*e][u_ax] {
                *e = v;
            }
        }
    }
    let mut keys: Vec<i64> = by_span.keys().copied().collect();
    keys.sort_unstable();
    let lip1: Vec<usize> = keys.iter().map(|k| by_span[k]).collect();
    let lip0: Vec<usize> = lip1.iter().map(|v| copy[v]).collect();
    if lip1.len() < 2 {
        return Err(bad("the crack does not reach the surface".into()));
    }
    // tumour: below the middle of the lips, offset from the plane
    let mid = lip1[lip1.len() / 2];
    let mut c = pos[mid];
    c[u_ax] -= spec.tumour_depth_mm;
    c[a] += spec.tumour_offset_mm;
    let d = Deformation {
        rest,
        deformed,
        lips: [lip0, lip1],
        tumour_centre_mm: c,
        tumour_radius_mm: spec.tumour_radius_mm,
    };
    // the tumour must be inside the organ
    let inside = TetLocator::new(&d.rest).nearest_tet(&c).is_some_and(|(_, w)| w.iter().all(|&x| x >= -1e-9));
    if !inside {
        return Err(bad(format!("tumour centre {c:?} is outside the organ")));
    }
    d.validate("synthetic incision")?;
    Ok(d)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tetmesh::grid_tet_mesh;

    fn box_surface(lo: [f64; 3], hi: [f64; 3]) -> TriMesh {
        laparo_fem::mesh::shapes::box_surface(&Vector3::from(lo), &Vector3::from(hi))
    }

    fn spec() -> IncisionSpec {
        IncisionSpec {
            normal_axis: 0,
            span_axis: 1,
            up_axis: 2,
            plane_mm: 20.0,
            span_mm: [8.0, 32.0],
            depth_mm: 8.0,
            opening_mm: 2.0,
            decay_mm: 10.0,
            tumour_depth_mm: 10.0,
            tumour_offset_mm: 4.0,
            tumour_radius_mm: 3.0,
        }
    }

    #[test]
    fn the_stand_in_cut_duplicates_nodes_and_opens_by_the_analytic_field() {
        let g = grid_tet_mesh(&box_surface([0.0; 3], [40.0, 40.0, 20.0]), 2.0).unwrap();
        let d = synthetic_incision(&g, &spec()).unwrap();
        assert_eq!(d.rest.tets.len(), g.mesh.tets.len());
        assert!((0..d.rest.tets.len()).all(|i| d.rest.tet_volume(i) > 0.0));
        let n_dup = d.rest.vertices.len() - g.mesh.vertices.len();
        assert!(n_dup > 10, "{n_dup} duplicated nodes");
        // lip copies coincide at rest and lie on one grid plane, the nearest to x = 20 (grid
        // planes at −1 + 2i mm: the origin is half a cell below the surface's bounding box)
        let x0 = d.rest.vertices[d.lips[0][0]][0];
        assert!((x0 - 20.0).abs() <= 1.0 + 1e-9, "{x0}");
        for (a, b) in d.lips[0].iter().zip(&d.lips[1]) {
            assert_eq!(d.rest.vertices[*a], d.rest.vertices[*b]);
            assert!((d.rest.vertices[*a][0] - x0).abs() < 1e-9);
        }
        // the gap at the middle lip node: 2 a · w_span · w_depth (exp term = 1 on the plane)
        let i = d.lips[0].len() / 2;
        let p = d.rest.vertices[d.lips[0][i]];
        let s = |t: f64| {
            let t = t.clamp(0.0, 1.0);
            t * t * (3.0 - 2.0 * t)
        };
        let ws = s((p[1] - 8.0).min(32.0 - p[1]) / (0.3 * 24.0));
        let top = 20.0; // highest crack node (box top, the boundary nodes were snapped onto it)
        let wd = s((p[2] - (top - 8.0)) / 8.0).sqrt();
        let gap = (d.deformed[d.lips[1][i]] - d.deformed[d.lips[0][i]])[0];
        assert!((gap - 2.0 * 2.0 * ws * wd).abs() < 1e-9, "gap {gap}, expected {}", 4.0 * ws * wd);
        assert!(gap > 1.0);
        // the cut surface is closed; the preoperative surface drops exactly the crack-face pairs
        let b = d.rest.boundary();
        assert!(b.is_closed());
        let (pre, _, _) = d.preoperative_surface();
        assert!(pre.is_closed());
        let crack = crate::scenario::crack_faces(&d.rest.vertices, &b.faces);
        assert_eq!(pre.faces.len(), b.faces.len() - crack.iter().filter(|&&c| c).count());
        // a node far from the cut does not move; map_points reproduces node motion
        let far = d.rest.vertices.iter().position(|v| v[0] < 1.5 && v[2] < 1.5).unwrap();
        assert!((d.deformed[far] - d.rest.vertices[far]).norm() < 1e-12);
        let q = d.map_points(&[d.rest.vertices[far]]);
        assert!((q[0] - d.deformed[far]).norm() < 1e-9);
        // write / read round trip
        let dir = tempfile::tempdir().unwrap();
        d.write(dir.path()).unwrap();
        let r = Deformation::read(dir.path()).unwrap();
        assert_eq!(r.lips, d.lips);
        assert!(r.deformed.iter().zip(&d.deformed).all(|(a, b)| (a - b).norm() < 1e-9));
    }
}
