//! RODS-MPM on a cut tetrahedral mesh for the benchmark: particles on a lattice inside the mesh (each
//! carrying the incision side of its tetrahedron), landmarks on their own side, registration through
//! `laparo-mpm` (§5.3, eqs. 5.8–5.10), and the node positions read back from the registered particles —
//! by the barycentric lattice transfer of §5.4.3 away from the incision, and by a local affine fit to the
//! particles of the node's own side for the duplicated crack nodes (the two lips of a crack coincide at
//! rest, so a side-blind interpolation would give both lips the same displacement).
use crate::distance::{build_tree, Polyline};
use crate::error::{RegisterError, Result};
use crate::loss::{GroupTarget, LandmarkGroup, RegistrationLoss};
use crate::optimize::{register, register_sided, IterationRecord, OptimizerConfig};
use crate::organ::{organ_from_points, OrganConfig};
use crate::transfer::Transfer;
use kiddo::SquaredEuclidean;
use nalgebra::{Matrix4, Vector3, Vector4};
use std::collections::HashMap;
use std::sync::Arc;

/// One landmark group: source material points with their incision side (0 = none, 1, 2) and the target
/// polyline of that group (mm).
#[derive(Clone, Debug)]
pub struct SideGroup {
    /// Name (e.g. `lip A`).
    pub name: String,
    /// Source landmarks at rest (mm) and the side each lies on.
    pub sources: Vec<(Vector3<f64>, u8)>,
    /// Target polyline vertices (mm).
    pub target: Vec<Vector3<f64>>,
}

/// A registration problem on a (cut) tetrahedral mesh.
#[derive(Clone, Debug)]
pub struct RodsProblem<'a> {
    /// Rest node positions (mm).
    pub nodes: &'a [Vector3<f64>],
    /// Tetrahedra.
    pub tets: &'a [[usize; 4]],
    /// Incision side of every node: 0 away from the crack, 1 or 2 for the copies of a duplicated crack node.
    pub node_side: &'a [u8],
    /// Nodes held fixed (the ground truth's attached region): a particle whose interpolated fixed
    /// indicator (barycentric in its tetrahedron) is ≥ 1/2 is held at rest. Empty = none.
    pub fixed_nodes: &'a [usize],
    /// Landmark groups.
    pub groups: Vec<SideGroup>,
    /// Organ set-up (spacing, ROI, material, horizon).
    pub organ: OrganConfig,
    /// Optimiser.
    pub optimizer: OptimizerConfig,
    /// A crack the simulation separates along with laparo-mpm's two-field grid (`Scene::crack_side`);
    /// None = the one-field MLS-MPM of the thesis.
    pub crack: Option<CrackSurface>,
    /// Score each landmark at its own material point (its particle plus the rest offset,
    /// `RegistrationLoss::offsets`) instead of at the nearest particle (the thesis).
    pub landmark_offsets: bool,
}

pub use crate::crack::{crack_sides, CrackSurface};

/// The registered node positions and how the run went.
#[derive(Clone, Debug)]
pub struct RodsOutput {
    /// Registered node positions (mm); nodes outside the region of interest keep their rest position.
    pub nodes: Vec<Vector3<f64>>,
    /// Particles simulated.
    pub particles: usize,
    /// Mean landmark distance before and after (eq. 5.10, mm).
    pub landmark_distance_mm: [f64; 2],
    /// Iterations run.
    pub iterations: usize,
    /// Findings (horizon, extrapolated nodes, optimiser stop reason, energy audit).
    pub notes: Vec<String>,
    /// Energy audit of the simulated run (None for the read-back floor, which does not simulate).
    pub energy: Option<crate::optimize::EnergyAudit>,
    /// Registered positions (mm) of the query points of [`run_rods_at`] / [`run_rods_oracle_at`], read by the
    /// same particle→point transfer as the nodes (empty without queries).
    pub points: Vec<Vector3<f64>>,
}

/// Query points of a run: (rest position mm, incision side 0/1/2), read back like the nodes.
pub type Queries<'a> = &'a [(Vector3<f64>, u8)];

/// The ground truth's deformed positions (mm) at particles given as (rest position, case tetrahedron), for
/// the oracles and the read-back floor (e.g. the TET10 field; default: P1 of the nodal ground truth).
pub type TruthAt<'a> = &'a dyn Fn(&[(Vector3<f64>, usize)]) -> Result<Vec<Vector3<f64>>>;

/// Lattice points (spacing `s`, origin `origin`) inside the tetrahedra, each with the index of the first
/// tetrahedron (in mesh order) that contains it: deterministic.
pub fn sample_lattice(
    nodes: &[Vector3<f64>],
    tets: &[[usize; 4]],
    origin: &Vector3<f64>,
    s: f64,
) -> Vec<(Vector3<f64>, usize)> {
    let mut seen: HashMap<[i64; 3], usize> = HashMap::new();
    let mut out = Vec::new();
    for (t, tet) in tets.iter().enumerate() {
        let p = tet.map(|i| nodes[i]);
        let m = nalgebra::Matrix3::from_columns(&[p[1] - p[0], p[2] - p[0], p[3] - p[0]]);
        let Some(mi) = m.try_inverse() else { continue };
        let lo = p.iter().fold(p[0], |a, b| a.inf(b));
        let hi = p.iter().fold(p[0], |a, b| a.sup(b));
        let a = ((lo - origin) / s).map(|x| x.ceil() as i64);
        let b = ((hi - origin) / s).map(|x| x.floor() as i64);
        for i in a[0]..=b[0] {
            for j in a[1]..=b[1] {
                for k in a[2]..=b[2] {
                    let key = [i, j, k];
                    if seen.contains_key(&key) {
                        continue;
                    }
                    let x = origin + Vector3::new(i as f64, j as f64, k as f64) * s;
                    let l = mi * (x - p[0]);
                    let eps = -1e-9;
                    if l[0] >= eps && l[1] >= eps && l[2] >= eps && l.sum() <= 1.0 - eps {
                        seen.insert(key, out.len());
                        out.push((x, t));
                    }
                }
            }
        }
    }
    out
}

/// Side of each tetrahedron: the side of its duplicated crack nodes (0 when it has none).
pub fn tet_sides(tets: &[[usize; 4]], node_side: &[u8]) -> Vec<u8> {
    tets.iter().map(|t| t.iter().map(|&i| node_side[i]).max().unwrap_or(0)).collect()
}

/// A RODS-MPM problem made ready to simulate: the organ's particles (simulation frame: model mm +
/// `organ.offset`), their rest positions, incision sides and tetrahedra, and the landmark loss.
struct Prepared {
    organ: crate::organ::Organ,
    points: Vec<Vector3<f64>>,
    side: Vec<u8>,
    samples: Vec<(Vector3<f64>, usize)>,
    loss: RegistrationLoss<3>,
    notes: Vec<String>,
}

fn prepare(problem: &RodsProblem, kerf_mm: f64) -> Result<Prepared> {
    let n = problem.nodes.len();
    if problem.node_side.len() != n {
        return Err(RegisterError::bad("node sides", format!("{} sides for {n} nodes", problem.node_side.len())));
    }
    if problem.tets.is_empty() || n == 0 {
        return Err(RegisterError::bad("mesh", "no tetrahedron"));
    }
    let s = problem.organ.spacing_mm;
    let origin = problem.nodes.iter().fold(problem.nodes[0], |a, b| a.inf(b));
    let tside = tet_sides(problem.tets, problem.node_side);
    let mut samples = sample_lattice(problem.nodes, problem.tets, &origin, s);
    if let Some(roi) = &problem.organ.roi {
        samples.retain(|(x, _)| roi.inside(x));
    }
    let mut kerf_removed = 0;
    if kerf_mm > 0.0 {
        let c = true_crack(problem.nodes, problem.tets, problem.node_side);
        let crack = crate::distance::TriangleSurface::new(c.vertices, c.faces);
        if crate::distance::ClosestPoint::len(&crack) == 0 {
            return Err(RegisterError::param("kerf_mm", kerf_mm, "the mesh has no crack faces to cut a kerf along"));
        }
        let before = samples.len();
        samples.retain(|(x, _)| (crate::distance::ClosestPoint::closest(&crack, x).0 - x).norm() > 0.5 * kerf_mm);
        kerf_removed = before - samples.len();
    }
    if samples.len() < 8 {
        return Err(RegisterError::param("spacing_mm", s, format!("only {} particles inside the mesh", samples.len())));
    }
    let points: Vec<Vector3<f64>> = samples.iter().map(|(x, _)| *x).collect();
    let side: Vec<u8> = samples.iter().map(|&(_, t)| tside[t]).collect();
    let mut organ = organ_from_points(points.clone(), &problem.organ, "benchmark mesh")?;
    debug_assert_eq!(organ.scene.n_particles(), points.len());
    let mut notes = organ.warnings.clone();
    if let Some(crack) = &problem.crack {
        let centroids: Vec<Vector3<f64>> = samples
            .iter()
            .map(|(_, t)| problem.tets[*t].iter().map(|&i| problem.nodes[i]).sum::<Vector3<f64>>() / 4.0)
            .collect();
        notes.push(crate::crack::label_organ(&mut organ, crack, &points, &centroids)?.note());
    }
    if kerf_mm > 0.0 {
        notes.push(format!(
            "kerf {kerf_mm} mm: {kerf_removed} particles within {} mm of the crack removed",
            0.5 * kerf_mm
        ));
    }
    let held = fixed_particles(problem, &samples)?;
    if held.iter().any(|&h| h) {
        if organ.scene.fixed.is_empty() {
            organ.scene.fixed = vec![false; points.len()];
        }
        let before = organ.scene.fixed.iter().filter(|&&f| f).count();
        for (f, h) in organ.scene.fixed.iter_mut().zip(&held) {
            *f |= *h;
        }
        let added = organ.scene.fixed.iter().filter(|&&f| f).count() - before;
        notes.push(format!("{added} particles held in the fixed region"));
    }
    // landmark particles: nearest particle of the landmark's own side (side 0 landmarks: any particle)
    let trees: Vec<Option<(crate::distance::Tree<3>, Vec<usize>)>> = (0..3u8)
        .map(|sd| {
            let idx: Vec<usize> = (0..points.len()).filter(|&p| sd == 0 || side[p] == sd).collect();
            if idx.is_empty() {
                None
            } else {
                let pts: Vec<Vector3<f64>> = idx.iter().map(|&p| points[p]).collect();
                Some((build_tree(&pts), idx))
            }
        })
        .collect();
    let off = organ.offset;
    let mut groups = Vec::new();
    let mut offsets = Vec::new();
    for g in &problem.groups {
        if g.target.is_empty() {
            return Err(RegisterError::bad(format!("group `{}`", g.name), "empty target polyline"));
        }
        let mut particles = Vec::with_capacity(g.sources.len());
        for (k, (x, sd)) in g.sources.iter().enumerate() {
            let sd = (*sd).min(2) as usize;
            let (tree, idx) = trees[sd].as_ref().or(trees[0].as_ref()).ok_or_else(|| {
                RegisterError::bad(format!("group `{}` landmark {k}", g.name), "no particle on its side")
            })?;
            let nn = tree.nearest_one::<SquaredEuclidean>(&[x[0], x[1], x[2]]);
            particles.push(idx[nn.item as usize]);
        }
        offsets.push(if problem.landmark_offsets {
            g.sources.iter().zip(&particles).map(|((x, _), &p)| x - points[p]).collect()
        } else {
            Vec::new()
        });
        let target: Vec<Vector3<f64>> = g.target.iter().map(|p| p + off).collect();
        groups.push(LandmarkGroup {
            name: g.name.clone(),
            particles,
            target: GroupTarget::Shared(Arc::new(Polyline::open(target))),
            weight: 1.0,
        });
    }
    let mut loss = RegistrationLoss::new(groups);
    loss.offsets = offsets;
    let horizon = organ.horizon(&loss.landmark_particles());
    if horizon.unreachable_fraction > 0.0 {
        notes.push(format!(
            "{:.1} % of the particles are beyond the P-wave reach ({:.1} mm) of every landmark",
            100.0 * horizon.unreachable_fraction,
            horizon.p_reach_mm
        ));
    }
    Ok(Prepared { organ, points, side, samples, loss, notes })
}

/// Register `problem` with RODS-MPM; `progress` sees every accepted iteration.
pub fn run_rods(problem: &RodsProblem, progress: &mut dyn FnMut(&IterationRecord)) -> Result<RodsOutput> {
    run_rods_at(problem, &[], progress)
}

/// [`run_rods`], also reading the registered field at `queries` (the benchmark's evaluation points).
pub fn run_rods_at(
    problem: &RodsProblem,
    queries: Queries,
    progress: &mut dyn FnMut(&IterationRecord),
) -> Result<RodsOutput> {
    run_rods_kerfed(problem, queries, 0.0, progress)
}

/// [`run_rods_at`] on a source whose particles within `kerf_mm / 2` of the case's true crack faces are
/// removed first (a cut the simulator can see: it uses the true crack, so it is a fidelity row, never a
/// headline method).
pub fn run_rods_kerfed(
    problem: &RodsProblem,
    queries: Queries,
    kerf_mm: f64,
    progress: &mut dyn FnMut(&IterationRecord),
) -> Result<RodsOutput> {
    if !(kerf_mm >= 0.0 && kerf_mm.is_finite()) {
        return Err(RegisterError::param("kerf_mm", kerf_mm, "must be finite and >= 0"));
    }
    let Prepared { organ, points, side, loss, mut notes, .. } = prepare(problem, kerf_mm)?;
    let off = organ.offset;
    let before = loss.mean_distance(&organ.scene.positions);
    let mut obs = |r: &IterationRecord, _: &[Vector3<f64>]| {
        progress(r);
        true
    };
    let reg = register_sided(&organ.scene, &loss, &problem.optimizer, None, &organ.smoothing_sides, &mut obs)?;
    let after = loss.mean_distance(&reg.final_state.x);
    notes.push(format!("optimiser: {}", reg.stop_reason));
    notes.push(reg.energy.note());
    let deformed: Vec<Vector3<f64>> = reg.final_state.x.iter().map(|p| p - off).collect();
    let (nodes, read) = transfer_nodes(problem, queries, &points, &side, &deformed, kerf_mm, &mut notes)?;
    Ok(RodsOutput {
        nodes,
        points: read,
        particles: points.len(),
        landmark_distance_mm: [before, after],
        iterations: reg.history.last().map(|r| r.iteration).unwrap_or(0),
        notes,
        energy: Some(reg.energy),
    })
}

/// What a RODS-MPM oracle may see of the ground truth (a diagnostic of the simulator, not a method).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OracleMode {
    /// v₀ = u_GT / (T Δt) at every particle (ground-truth displacement interpolated in the particle's
    /// tetrahedron, so each lip takes its own side's copy), one forward run: the ballistic guess.
    Ballistic,
    /// RODS-MPM's optimiser with every free particle a landmark paired to its ground-truth position (eq.
    /// 5.10 over all particles): how close an MLS-MPM trajectory from rest can come to the ground truth
    /// on this grid when nothing is under-determined.
    Dense,
    /// No simulation: every particle placed at its ground-truth position, then read back to the nodes —
    /// the error floor of the particle-to-node transfer itself.
    Readback,
}

/// Run a RODS-MPM oracle on `problem` against the ground-truth node positions `truth` (mm): the lip
/// landmarks of `problem` are only scored, never used. Isolates what the simulator can represent
/// (grid coupling across the unopened crack, horizon) from what sparse landmarks determine.
/// `kerf_mm` > 0 first removes the particles within `kerf_mm / 2` of the ground truth's crack faces (a cut
/// of that width the simulator can see; 0 = the uncut particle set RODS-MPM simulates).
pub fn run_rods_oracle(
    problem: &RodsProblem,
    truth: &[Vector3<f64>],
    mode: OracleMode,
    kerf_mm: f64,
) -> Result<RodsOutput> {
    run_rods_oracle_at(problem, truth, None, mode, kerf_mm, &[])
}

/// [`run_rods_oracle`] with the ground truth at the particles from `truth_at` (None: P1 of `truth`), also
/// reading the result at `queries`.
pub fn run_rods_oracle_at(
    problem: &RodsProblem,
    truth: &[Vector3<f64>],
    truth_at: Option<TruthAt>,
    mode: OracleMode,
    kerf_mm: f64,
    queries: Queries,
) -> Result<RodsOutput> {
    if truth.len() != problem.nodes.len() {
        return Err(RegisterError::bad(
            "ground truth",
            format!("{} positions for {} nodes", truth.len(), problem.nodes.len()),
        ));
    }
    if !(kerf_mm >= 0.0 && kerf_mm.is_finite()) {
        return Err(RegisterError::param("kerf_mm", kerf_mm, "must be finite and >= 0"));
    }
    let Prepared { mut organ, points, side, samples, loss, mut notes } = prepare(problem, kerf_mm)?;
    let off = organ.offset;
    // ground-truth displacement at every particle, barycentric in its tetrahedron
    let u: Vec<Vector3<f64>> = match truth_at {
        Some(f) => {
            let y = f(&samples)?;
            if y.len() != samples.len() {
                return Err(RegisterError::bad(
                    "ground truth at the particles",
                    format!("{} for {} particles", y.len(), samples.len()),
                ));
            }
            y.iter().zip(&samples).map(|(y, (x, _))| y - x).collect()
        }
        None => samples.iter().map(|(x, t)| interpolate(problem, x, *t, |i| truth[i] - problem.nodes[i])).collect(),
    };
    let held = |p: usize| organ.scene.fixed.get(p).copied().unwrap_or(false);
    let before = loss.mean_distance(&organ.scene.positions);
    let (final_x, iterations, energy) = match mode {
        OracleMode::Ballistic => {
            let t = organ.scene.steps as f64 * organ.scene.dt;
            organ.scene.velocities =
                (0..points.len()).map(|p| if held(p) { Vector3::zeros() } else { u[p] / t }).collect();
            let sim = laparo_mpm::simulate(&organ.scene)?;
            notes.push("oracle: ballistic v₀ = u_GT / (T Δt)".into());
            let energy = crate::optimize::EnergyAudit::of(&organ.scene, &sim.final_state);
            (sim.final_state.x, 0, Some(energy))
        }
        OracleMode::Readback => {
            notes.push("oracle: particles at their ground-truth positions, no simulation".into());
            (points.iter().zip(&u).map(|(x, u)| x + u + off).collect(), 0, None)
        }
        OracleMode::Dense => {
            let particles: Vec<usize> = (0..points.len()).filter(|&p| !held(p)).collect();
            let targets = particles.iter().map(|&p| points[p] + u[p] + off).collect();
            let dense = RegistrationLoss::new(vec![LandmarkGroup {
                name: "every particle".into(),
                particles,
                target: GroupTarget::Paired(targets),
                weight: 1.0,
            }]);
            let reg = register(&organ.scene, &dense, &problem.optimizer, None, &mut |_, _| true)?;
            notes.push(format!(
                "oracle: dense targets, mean particle distance {:.3} → {:.3} mm ({})",
                dense.mean_distance(&organ.scene.positions),
                dense.mean_distance(&reg.final_state.x),
                reg.stop_reason
            ));
            let it = reg.history.last().map(|r| r.iteration).unwrap_or(0);
            (reg.final_state.x, it, Some(reg.energy))
        }
    };
    let after = loss.mean_distance(&final_x);
    let deformed: Vec<Vector3<f64>> = final_x.iter().map(|p| p - off).collect();
    let (nodes, read) = transfer_nodes(problem, queries, &points, &side, &deformed, kerf_mm, &mut notes)?;
    Ok(RodsOutput {
        nodes,
        points: read,
        particles: points.len(),
        landmark_distance_mm: [before, after],
        iterations,
        notes,
        energy,
    })
}

/// A nodal field `f` interpolated at `x` by its barycentric coordinates in tetrahedron `t` (sampled
/// tetrahedra are invertible: `sample_lattice` skips the others).
fn interpolate<T>(problem: &RodsProblem, x: &Vector3<f64>, t: usize, f: impl Fn(usize) -> T) -> T
where
    T: std::ops::Mul<f64, Output = T> + std::iter::Sum<T>,
{
    let tet = problem.tets[t];
    let p = tet.map(|i| problem.nodes[i]);
    let m = nalgebra::Matrix3::from_columns(&[p[1] - p[0], p[2] - p[0], p[3] - p[0]]);
    let l = m.try_inverse().map(|mi| mi * (x - p[0])).unwrap_or_default();
    let w = [1.0 - l.sum(), l[0], l[1], l[2]];
    tet.iter().zip(w).map(|(&i, w)| f(i) * w).sum()
}

/// Per lattice sample, whether the fixed-node indicator interpolated in its tetrahedron is ≥ 1/2.
fn fixed_particles(problem: &RodsProblem, samples: &[(Vector3<f64>, usize)]) -> Result<Vec<bool>> {
    if problem.fixed_nodes.is_empty() {
        return Ok(vec![false; samples.len()]);
    }
    let n = problem.nodes.len();
    let mut ind = vec![0.0; n];
    for &i in problem.fixed_nodes {
        if i >= n {
            return Err(RegisterError::bad("fixed nodes", format!("node {i} of {n}")));
        }
        ind[i] = 1.0;
    }
    Ok(samples.iter().map(|(x, t)| interpolate(problem, x, *t, |i| ind[i]) >= 0.5).collect())
}

/// The crack a read-back must not reach across: the case's crack faces (side-1 faces wound towards side 2), a
/// k-d tree over their centroids for segment tests, and the closest-point structure.
struct CrackGuard {
    surface: crate::distance::TriangleSurface,
    centroids: crate::distance::Tree<3>,
    r_max: f64,
}

impl CrackGuard {
    fn new(problem: &RodsProblem) -> Option<CrackGuard> {
        let c = true_crack(problem.nodes, problem.tets, problem.node_side);
        if c.faces.is_empty() {
            return None;
        }
        let cent: Vec<Vector3<f64>> =
            c.faces.iter().map(|f| (c.vertices[f[0]] + c.vertices[f[1]] + c.vertices[f[2]]) / 3.0).collect();
        let r_max = c
            .faces
            .iter()
            .zip(&cent)
            .map(|(f, m)| f.iter().map(|&i| (c.vertices[i] - m).norm()).fold(0.0, f64::max))
            .fold(0.0, f64::max);
        Some(CrackGuard {
            surface: crate::distance::TriangleSurface::new(c.vertices, c.faces),
            centroids: build_tree(&cent),
            r_max,
        })
    }

    /// Distance (mm) from `x` to the crack, and `x` moved 1e-6 mm off it towards `side` (1: against the
    /// faces' normals, 2: along them) when it lies on it, so a segment from it starts on its own side.
    fn locate(&self, x: &Vector3<f64>, side: u8) -> (f64, Vector3<f64>) {
        use crate::distance::ClosestPoint;
        let (c, f) = self.surface.closest(x);
        let d = (c - x).norm();
        if d > 1e-6 || side == 0 {
            return (d, *x);
        }
        let t = self.surface.faces[f].map(|i| self.surface.vertices[i]);
        let n = (t[1] - t[0]).cross(&(t[2] - t[0])).normalize();
        (d, if side == 1 { x - n * 1e-6 } else { x + n * 1e-6 })
    }

    /// Whether the segment a → b crosses a crack face after leaving `a` (a `b` lying on the crack counts as
    /// across it: a particle on the crack plane belongs to the side its tetrahedron gave it).
    fn crosses(&self, a: &Vector3<f64>, b: &Vector3<f64>) -> bool {
        let m = 0.5 * (a + b);
        let r = 0.5 * (b - a).norm() + self.r_max;
        let d = b - a;
        self.centroids.within_unsorted::<SquaredEuclidean>(&[m.x, m.y, m.z], r * r).iter().any(|hit| {
            let f = self.surface.faces[hit.item as usize];
            let v = f.map(|i| self.surface.vertices[i]);
            laparo_core::geometry::ray_triangle(a, &d, &v[0], &v[1], &v[2]).is_some_and(|t| t > 1e-9 && t <= 1.0 + 1e-9)
        })
    }
}

/// Registered node positions and query-point positions (mm).
type NodesAndPoints = (Vec<Vector3<f64>>, Vec<Vector3<f64>>);

/// Node positions, and positions of the `queries`, from the registered particles: one particle→point
/// transfer for every point (see the module docs). A point on an incision side (side ≠ 0), and any point
/// within reach (2.5 spacings, plus half the kerf) of the crack, takes a moving-least-squares affine fit of the
/// particles it sees through material: its own side's particles and the unlabelled ones the segment to which
/// crosses no crack face (never the other lip's), the reach widened until 4 non-coplanar particles are found,
/// else the nearest such particle's displacement; every other point the §5.4.3 lattice transfer. Points
/// outside the region of interest stay at rest. (The particles' side labels come from the case's tetrahedra, as
/// RODS-MPM's landmark particles do.)
fn transfer_nodes(
    problem: &RodsProblem,
    queries: Queries,
    rest: &[Vector3<f64>],
    side: &[u8],
    deformed: &[Vector3<f64>],
    kerf_mm: f64,
    notes: &mut Vec<String>,
) -> Result<NodesAndPoints> {
    let s = problem.organ.spacing_mm;
    let reach = 2.5 * s + 0.5 * kerf_mm;
    let transfer = Transfer::new(rest, s)?;
    let tree = build_tree(rest);
    let guard = CrackGuard::new(problem);
    let read = |x: &Vector3<f64>, sd: u8| -> Result<(Vector3<f64>, bool)> {
        if let Some(roi) = &problem.organ.roi {
            if !roi.inside(x) {
                return Ok((*x, false));
            }
        }
        let (d_crack, from) = guard.as_ref().map_or((f64::INFINITY, *x), |g| g.locate(x, sd));
        if sd != 0 || d_crack < reach {
            let other = match sd {
                1 => 2,
                2 => 1,
                _ => u8::MAX,
            };
            let seen = |p: usize| {
                side[p] == sd && sd != 0
                    || side[p] != other && !guard.as_ref().is_some_and(|g| g.crosses(&from, &rest[p]))
            };
            let mut nearest: Option<(f64, usize)> = None;
            for grow in [1.0, 1.6, 2.4] {
                let near = tree.within::<SquaredEuclidean>(&[x[0], x[1], x[2]], (grow * reach).powi(2));
                let own: Vec<(f64, usize)> =
                    near.iter().map(|n| (n.distance, n.item as usize)).filter(|&(_, p)| seen(p)).collect();
                let idx: Vec<usize> = own.iter().map(|o| o.1).collect();
                if let Some(p) = affine_fit(x, &idx, rest, deformed) {
                    return Ok((p, false));
                }
                nearest = own.into_iter().min_by(|a, b| a.0.total_cmp(&b.0));
                if nearest.is_some() && grow > 1.0 {
                    break;
                }
            }
            if let Some((_, p)) = nearest {
                return Ok((x + (deformed[p] - rest[p]), true));
            }
        }
        let t = transfer.apply(x, deformed)?;
        Ok((t.position, t.extrapolated))
    };
    let mut extrapolated = [0usize; 2];
    let mut nodes = Vec::with_capacity(problem.nodes.len());
    for (x, &sd) in problem.nodes.iter().zip(problem.node_side) {
        let (p, e) = read(x, sd)?;
        extrapolated[0] += e as usize;
        nodes.push(p);
    }
    let mut points = Vec::with_capacity(queries.len());
    for (x, sd) in queries {
        let (p, e) = read(x, *sd)?;
        extrapolated[1] += e as usize;
        points.push(p);
    }
    if extrapolated[0] > 0 {
        notes.push(format!("{} nodes extrapolated (lattice cell or nearest visible particle)", extrapolated[0]));
    }
    if extrapolated[1] > 0 {
        notes.push(format!(
            "{} evaluation points extrapolated (lattice cell or nearest visible particle)",
            extrapolated[1]
        ));
    }
    Ok((nodes, points))
}

/// Least-squares affine map of the particles `idx` (rest → deformed) evaluated at `x`; None with fewer than
/// 4 particles or a degenerate (coplanar) set.
fn affine_fit(
    x: &Vector3<f64>,
    idx: &[usize],
    rest: &[Vector3<f64>],
    deformed: &[Vector3<f64>],
) -> Option<Vector3<f64>> {
    if idx.len() < 4 {
        return None;
    }
    let mut ata = Matrix4::<f64>::zeros();
    let mut atb = [Vector4::<f64>::zeros(); 3];
    // moving least squares: a smooth compact weight (1 − r²/R²)² over the particles' reach R, so the fit is the
    // field's local affine part at x, not an average over the whole ball
    let r2max = idx.iter().map(|&p| (rest[p] - x).norm_squared()).fold(0.0, f64::max) * 1.0001 + 1e-12;
    for &p in idx {
        let r = rest[p] - x;
        let w = (1.0 - r.norm_squared() / r2max).powi(2);
        let a = Vector4::new(1.0, r[0], r[1], r[2]);
        ata += a * a.transpose() * w;
        for d in 0..3 {
            atb[d] += a * deformed[p][d] * w;
        }
    }
    // reject near-coplanar sets: the centred scatter must not be (nearly) rank-deficient
    let c = idx.iter().map(|&p| rest[p]).sum::<Vector3<f64>>() / idx.len() as f64;
    let scatter = idx.iter().map(|&p| (rest[p] - c) * (rest[p] - c).transpose()).sum::<nalgebra::Matrix3<f64>>();
    let eig = scatter.symmetric_eigenvalues();
    if !(eig.min() > 1e-6 * eig.max()) {
        return None;
    }
    let inv = ata.try_inverse()?;
    Some(Vector3::new((inv * atb[0])[0], (inv * atb[1])[0], (inv * atb[2])[0]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lattice_sampling_of_a_unit_cube_by_hand() {
        let v: Vec<Vector3<f64>> =
            (0..8).map(|i| Vector3::new((i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64)).collect();
        let tets = [[0, 1, 2, 4], [1, 3, 2, 7], [1, 4, 5, 7], [2, 6, 4, 7], [1, 2, 4, 7]];
        let origin = Vector3::zeros();
        let pts = sample_lattice(&v, &tets, &origin, 0.25);
        // a closed unit cube at spacing 0.25 holds 5³ lattice points, each sampled once
        assert_eq!(pts.len(), 125);
        let mut keys: Vec<[i64; 3]> = pts.iter().map(|(x, _)| x.map(|v| (v / 0.25).round() as i64).into()).collect();
        keys.sort();
        keys.dedup();
        assert_eq!(keys.len(), 125);
    }

    #[test]
    fn affine_fit_reproduces_an_affine_motion() {
        let rest: Vec<Vector3<f64>> =
            (0..20).map(|i| Vector3::new((i % 3) as f64, ((i / 3) % 3) as f64, (i / 9) as f64)).collect();
        let a = nalgebra::Matrix3::new(1.1, 0.1, 0.0, -0.05, 0.9, 0.2, 0.0, 0.03, 1.2);
        let t = Vector3::new(3.0, -1.0, 2.0);
        let def: Vec<Vector3<f64>> = rest.iter().map(|p| a * p + t).collect();
        let idx: Vec<usize> = (0..20).collect();
        let x = Vector3::new(0.5, 0.7, 1.3);
        let y = affine_fit(&x, &idx, &rest, &def).unwrap();
        assert!((y - (a * x + t)).norm() < 1e-10);
        // coplanar particles are refused
        let flat: Vec<usize> = (0..9).collect();
        assert!(affine_fit(&x, &flat, &rest, &def).is_none());
    }
}

/// RODS-MPM as a benchmark [`Method`](super::case::Method): each lip's landmarks form one group scored
/// against that lip's target polyline; the case's region of interest overrides `organ.roi`, and the case's
/// fixed nodes (known to every method) hold the particles of that region at rest.
#[derive(Clone, Debug)]
pub struct RodsMethod {
    /// Organ set-up (spacing, material, horizon).
    pub organ: OrganConfig,
    /// Optimiser.
    pub optimizer: OptimizerConfig,
    /// Simulate with laparo-mpm's two-field grid along a known crack; None = the thesis' one-field MLS-MPM.
    pub two_field: Option<TwoField>,
    /// The rung of the method ladder this row stands for (named in the tables); None = a plain row named by
    /// its grid alone.
    pub rung: Option<Rung>,
}

/// The rungs of the RODS-MPM method ladder the benchmark compares (each a setting of the same method;
/// `laparo register benchmark --methods rods-l0,rods-l1,…`). Every rung uses only intraoperative
/// information: the lips' source and target polylines and the cut surface Σ François et al. also assume.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Rung {
    /// L0, the thesis: one field, v₀ only, Gaussian-preconditioned L-BFGS.
    L0,
    /// L1 ablation: two fields on Σ with the side-blind Gaussian of L0 (the lips' opposite pulls averaged).
    L1SideBlind,
    /// L1: two fields on Σ, side-aware preconditioner.
    L1,
    /// L2: L1 plus the at-rest prior on KE(T) (`OptimizerConfig::terminal_kinetic_weight`).
    L2,
    /// L3: L1 with loads as the unknown (a self-equilibrated force density on the band around Σ, v₀ = 0,
    /// mass-proportional damping [`L3_DAMPING_PER_HORIZON`] over the horizon: x_T an equilibrium).
    L3,
}

/// ζ T Δt of rung L3 ([`crate::optimize::DEFAULT_DAMPING_PER_HORIZON`], fixed a priori, not tuned).
pub const L3_DAMPING_PER_HORIZON: f64 = crate::optimize::DEFAULT_DAMPING_PER_HORIZON;

impl Rung {
    /// Every rung, in ladder order.
    pub const ALL: [Rung; 5] = [Rung::L0, Rung::L1SideBlind, Rung::L1, Rung::L2, Rung::L3];
    /// The `--methods` name (`rods-l0`, `rods-l1-blind`, `rods-l1`, `rods-l2`, `rods-l3`).
    pub fn method_name(self) -> &'static str {
        match self {
            Rung::L0 => "rods-l0",
            Rung::L1SideBlind => "rods-l1-blind",
            Rung::L1 => "rods-l1",
            Rung::L2 => "rods-l2",
            Rung::L3 => "rods-l3",
        }
    }
    /// The rung of a `--methods` name.
    pub fn from_method_name(name: &str) -> Option<Rung> {
        Rung::ALL.into_iter().find(|r| r.method_name() == name)
    }
    /// The label in the tables.
    pub fn label(self) -> &'static str {
        match self {
            Rung::L0 => "L0",
            Rung::L1SideBlind => "L1 side-blind",
            Rung::L1 => "L1",
            Rung::L2 => "L2",
            Rung::L3 => "L3 loads",
        }
    }
    /// Whether the rung simulates on two fields along Σ.
    pub fn two_field(self) -> bool {
        self != Rung::L0
    }
    /// The rung's optimiser from a base: the side-aware switch and the at-rest weight `at_rest` (used by L2
    /// only; the others run with 0).
    pub fn optimizer(self, base: &OptimizerConfig, at_rest: f64) -> OptimizerConfig {
        OptimizerConfig {
            side_aware_smoothing: self != Rung::L1SideBlind,
            terminal_kinetic_weight: if self == Rung::L2 { at_rest } else { 0.0 },
            unknown: if self == Rung::L3 {
                crate::optimize::Unknown::Loads { damping_per_horizon: L3_DAMPING_PER_HORIZON }
            } else {
                crate::optimize::Unknown::InitialVelocity
            },
            ..base.clone()
        }
    }
}

/// Which crack RODS-MPM's two-field grid separates along.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TwoField {
    /// The cut François et al. assume: the first lip's source polyline swept inward to this depth (mm).
    AssumedCut {
        /// Depth (mm).
        depth_mm: f64,
        /// Which way it leaves the lip.
        direction: super::methods::CutDirection,
    },
    /// The ground truth's own crack faces (a diagnostic: the crack's extent is not known intraoperatively).
    TrueCrack,
}

/// The crack faces of side 1 of a cut mesh, wound outward from their tetrahedron (towards side 2): the
/// boundary faces that coincide with another boundary face (the two lips of a crack at rest), including
/// those on the crack front (whose front nodes are not duplicated), kept from the tetrahedron that holds
/// a side-1 node.
pub fn true_crack(nodes: &[Vector3<f64>], tets: &[[usize; 4]], node_side: &[u8]) -> CrackSurface {
    let mut count: HashMap<[usize; 3], usize> = HashMap::new();
    let face = |t: &[usize; 4], skip: usize| -> [usize; 3] {
        let f: Vec<usize> = (0..4).filter(|&k| k != skip).map(|k| t[k]).collect();
        [f[0], f[1], f[2]]
    };
    let sorted = |mut f: [usize; 3]| {
        f.sort_unstable();
        f
    };
    for t in tets {
        for skip in 0..4 {
            *count.entry(sorted(face(t, skip))).or_default() += 1;
        }
    }
    // boundary faces keyed by their vertex positions (bit patterns: the lips' copies are exact)
    let pos_key = |f: &[usize; 3]| {
        let mut k: Vec<[u64; 3]> = f.iter().map(|&i| nodes[i].map(f64::to_bits).into()).collect();
        k.sort_unstable();
        k
    };
    let mut by_pos: HashMap<Vec<[u64; 3]>, usize> = HashMap::new();
    for t in tets {
        for skip in 0..4 {
            let f = face(t, skip);
            if count[&sorted(f)] == 1 {
                *by_pos.entry(pos_key(&f)).or_default() += 1;
            }
        }
    }
    let mut faces = Vec::new();
    for t in tets {
        if !t.iter().any(|&i| node_side[i] == 1) {
            continue;
        }
        for skip in 0..4 {
            let f = face(t, skip);
            if count[&sorted(f)] == 1 && by_pos[&pos_key(&f)] == 2 {
                let (a, b, c) = (nodes[f[0]], nodes[f[1]], nodes[f[2]]);
                let out = (b - a).cross(&(c - a)).dot(&(a - nodes[t[skip]])) > 0.0;
                faces.push(if out { f } else { [f[0], f[2], f[1]] });
            }
        }
    }
    CrackSurface { vertices: nodes.to_vec(), faces, band_mm: None }
}

/// The name RODS-MPM's rows carry in the benchmark's tables.
pub const RODS_MPM_NAME: &str = "RODS-MPM";

impl RodsMethod {
    /// The problem of one benchmark run: each lip's landmarks form one group scored against that lip's
    /// target polyline; the case's region of interest overrides `organ.roi`.
    fn problem<'a>(
        &self,
        case: &'a super::case::BenchmarkCase,
        landmarks: &[super::case::LandmarkSet],
    ) -> Result<RodsProblem<'a>> {
        let crack = match self.two_field {
            Some(TwoField::AssumedCut { depth_mm, direction }) => {
                let (nodes, tets, _) = case.uncut();
                let uncut = laparo_core::mesh::TetMesh { vertices: nodes, tets };
                let f = super::methods::assumed_cut(&uncut, landmarks, depth_mm, direction)?;
                Some(CrackSurface { vertices: f.mesh.vertices, faces: f.crack_faces[0].clone(), band_mm: None })
            }
            Some(TwoField::TrueCrack) => Some(true_crack(&case.rest, &case.tets, &case.node_side)),
            None => None,
        };
        let groups = landmarks
            .iter()
            .map(|l| SideGroup {
                name: l.name.clone(),
                sources: l.sources.iter().map(|s| (*s, l.side)).collect(),
                target: l.targets.clone(),
            })
            .collect();
        let mut organ = self.organ.clone();
        if case.roi.is_some() {
            organ.roi = case.roi;
        }
        Ok(RodsProblem {
            nodes: &case.rest,
            tets: &case.tets,
            node_side: &case.node_side,
            fixed_nodes: &case.fixed,
            groups,
            organ,
            optimizer: self.optimizer.clone(),
            crack,
            landmark_offsets: self.rung.is_some(),
        })
    }
}

/// The name suffix of a two-field run (empty for the one-field grid).
fn two_field_label(t: Option<TwoField>, sep: &str) -> String {
    match t {
        Some(TwoField::AssumedCut { depth_mm, direction }) => match direction {
            super::methods::CutDirection::SurfaceNormal => format!("{sep}two-field (cut {depth_mm} mm)"),
            super::methods::CutDirection::LipSeparation => format!("{sep}two-field (cut {depth_mm} mm, lip plane)"),
        },
        Some(TwoField::TrueCrack) => format!("{sep}two-field (true crack)"),
        None => String::new(),
    }
}

/// A benchmark method output from a RODS-MPM run.
fn method_output(out: RodsOutput) -> super::case::MethodOutput {
    let mut notes = out.notes;
    notes.push(format!("{} particles, {} iterations", out.particles, out.iterations));
    let points = (!out.points.is_empty()).then_some(out.points);
    super::case::MethodOutput {
        nodes: out.nodes,
        landmark_distance_mm: out.landmark_distance_mm[1],
        notes,
        points,
        energy: out.energy,
    }
}

impl super::case::Method for RodsMethod {
    fn name(&self) -> String {
        match self.rung {
            Some(r) => format!("{RODS_MPM_NAME} {}{}", r.label(), two_field_label(self.two_field, " ")),
            None => format!("{RODS_MPM_NAME}{}", two_field_label(self.two_field, " ")),
        }
    }
    fn settings(&self) -> String {
        // the memory budget only chooses how the adjoint is checkpointed, never the result
        let mut m = self.clone();
        m.organ.memory_limit_bytes = None;
        format!("{m:?}")
    }
    fn register(
        &self,
        case: &super::case::BenchmarkCase,
        landmarks: &[super::case::LandmarkSet],
    ) -> Result<super::case::MethodOutput> {
        let queries = case.points.as_ref().map(|p| p.queries()).unwrap_or_default();
        Ok(method_output(run_rods_at(&self.problem(case, landmarks)?, &queries, &mut |_| {})?))
    }
    fn floor(&self) -> Option<String> {
        Some(RodsOracle { inner: self.clone(), mode: OracleMode::Readback, kerf_mm: 0.0 }.name())
    }
}

/// A RODS-MPM oracle as a benchmark [`Method`](super::case::Method) (`laparo register benchmark --methods
/// rods-ballistic,rods-dense`): a diagnostic that reads the case's ground truth, never a registration
/// method; its rows say what the simulator can represent, not what RODS-MPM achieves.
#[derive(Clone, Debug)]
pub struct RodsOracle {
    /// The RODS-MPM set-up it diagnoses.
    pub inner: RodsMethod,
    /// What it may see.
    pub mode: OracleMode,
    /// Width (mm) of a kerf cut out of the particles along the ground truth's crack (0 = none).
    pub kerf_mm: f64,
}

impl super::case::Method for RodsOracle {
    fn name(&self) -> String {
        let kerf = if self.kerf_mm > 0.0 { format!(", kerf {} mm", self.kerf_mm) } else { String::new() };
        let grid = two_field_label(self.inner.two_field, ", ");
        match self.mode {
            OracleMode::Ballistic => format!("RODS-MPM oracle (ballistic v0{kerf}{grid})"),
            OracleMode::Dense => format!("RODS-MPM oracle (dense targets{kerf}{grid})"),
            OracleMode::Readback => {
                format!("floor: RODS-MPM particles ({} mm, read-back of u_GT{kerf})", self.inner.organ.spacing_mm)
            }
        }
    }
    fn settings(&self) -> String {
        if self.mode == OracleMode::Readback {
            // no simulation: only the particles (spacing, kerf) and the transfer enter the floor
            return format!(
                "read-back floor: spacing {:?} mm, kerf {:?} mm",
                self.inner.organ.spacing_mm, self.kerf_mm
            );
        }
        let mut m = self.clone();
        m.inner.organ.memory_limit_bytes = None;
        format!("{m:?}")
    }
    fn register(
        &self,
        case: &super::case::BenchmarkCase,
        landmarks: &[super::case::LandmarkSet],
    ) -> Result<super::case::MethodOutput> {
        let problem = self.inner.problem(case, landmarks)?;
        let queries = case.points.as_ref().map(|p| p.queries()).unwrap_or_default();
        // the ground truth at each particle in its own tetrahedron (TET10 when the case has it)
        let truth_at = |samples: &[(Vector3<f64>, usize)]| -> Result<Vec<Vector3<f64>>> {
            let element: Vec<(usize, [f64; 4])> = samples
                .iter()
                .map(|(x, t)| {
                    let c = case.tets[*t].map(|i| case.rest[i]);
                    let l = nalgebra::Matrix3::from_columns(&[c[1] - c[0], c[2] - c[0], c[3] - c[0]])
                        .try_inverse()
                        .map_or_else(Vector3::zeros, |m| m * (x - c[0]));
                    (*t, [1.0 - l.sum(), l.x, l.y, l.z])
                })
                .collect();
            super::points::ground_truth_at(case, &element)
        };
        let out = run_rods_oracle_at(&problem, &case.ground_truth, Some(&truth_at), self.mode, self.kerf_mm, &queries)?;
        Ok(method_output(out))
    }
    fn uses_landmarks(&self) -> bool {
        // the read-back places the particles at the ground truth: no landmark enters it
        self.mode != OracleMode::Readback
    }
}

/// The thesis' RODS-MPM as a fidelity row (always reported beside the methods): one field, v₀ only from
/// v₀ = 0, plain gradient descent ([`OptimizerConfig::thesis`]: 500 iterations, α halved whenever a step
/// would raise the loss); with `kerf_mm` > 0 on a source whose blade volume is removed (labelled "uses the
/// true crack").
#[derive(Clone, Debug)]
pub struct ThesisRods {
    /// The set-up (organ, horizon); its optimiser should be the thesis one.
    pub inner: RodsMethod,
    /// Kerf width (mm) removed along the true crack (0 = none).
    pub kerf_mm: f64,
}

impl super::case::Method for ThesisRods {
    fn name(&self) -> String {
        let it = self.inner.optimizer.iterations;
        if self.kerf_mm > 0.0 {
            format!("{RODS_MPM_NAME} thesis (GD {it} it, kerf {} mm: uses the true crack)", self.kerf_mm)
        } else {
            format!("{RODS_MPM_NAME} thesis (GD {it} it)")
        }
    }
    fn settings(&self) -> String {
        let mut m = self.clone();
        m.inner.organ.memory_limit_bytes = None;
        format!("{m:?}")
    }
    fn register(
        &self,
        case: &super::case::BenchmarkCase,
        landmarks: &[super::case::LandmarkSet],
    ) -> Result<super::case::MethodOutput> {
        let queries = case.points.as_ref().map(|p| p.queries()).unwrap_or_default();
        let problem = self.inner.problem(case, landmarks)?;
        Ok(method_output(run_rods_kerfed(&problem, &queries, self.kerf_mm, &mut |_| {})?))
    }
    fn floor(&self) -> Option<String> {
        super::case::Method::floor(&self.inner)
    }
}
