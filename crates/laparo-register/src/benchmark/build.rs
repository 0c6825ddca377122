//! Build a benchmark case from a closed organ surface (thesis §5.4.2): tetrahedralise it, cut it (one of the
//! two scenarios of `laparo-fem`), open the incision with equal and opposite pressures on the two crack
//! faces in a quasi-static TET10 Neo-Hookean FEM (the ground truth, never `laparo-mpm`), the pressure
//! calibrated so that the largest lip gap reaches the scenario's target, and choose the region of
//! interest RODS-MPM simulates so that the ground-truth displacement on its boundary stays small.
use super::case::BenchmarkCase;
use crate::error::{RegisterError, Result};
use crate::organ::Roi;
use laparo_fem::material::NeoHookean;
use laparo_fem::mesh::incision::CutMesh;
use laparo_fem::mesh::scenario::Scenario;
use laparo_fem::solid::{LoadPath, Loads, Quadrature, SolidProblem, Solution, SolverSettings, Tet10Mesh};
use nalgebra::Vector3;

/// How to make the ground truth.
#[derive(Clone, Debug, serde::Serialize)]
pub struct GroundTruthConfig {
    /// Young's modulus (kPa), thesis 4.1.
    pub youngs_modulus_kpa: f64,
    /// Poisson's ratio, thesis 0.49.
    pub poisson_ratio: f64,
    /// Largest lip gap to reach (mm): the calibration stops inside [lo, hi].
    pub target_gap_mm: [f64; 2],
    /// First pressure tried (kPa).
    pub initial_pressure_kpa: f64,
    /// Most FEM solves of the calibration.
    pub max_solves: usize,
    /// Load increments per solve.
    pub steps: usize,
    /// Newton tolerance, relative to the applied load.
    pub rel_tol: f64,
}

impl GroundTruthConfig {
    /// register.md §4: the gap reaches 10–15 mm (non-anatomical) or 20–30 mm (anatomical).
    pub fn for_scenario(name: &str) -> Self {
        let target_gap_mm = if name == "anatomical" { [20.0, 30.0] } else { [10.0, 15.0] };
        GroundTruthConfig {
            youngs_modulus_kpa: 4.1,
            poisson_ratio: 0.49,
            target_gap_mm,
            initial_pressure_kpa: 0.05,
            max_solves: 6,
            steps: 20,
            rel_tol: 1e-8,
        }
    }
}

/// What the calibration did.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct GroundTruthReport {
    /// Pressure on each crack face (kPa) of the accepted solve.
    pub pressure_kpa: f64,
    /// Largest distance between the two copies of a crack node (mm).
    pub max_gap_mm: f64,
    /// (pressure kPa, gap mm) of every solve, in order.
    pub calibration: Vec<[f64; 2]>,
    /// Smallest det F over the quadrature points.
    pub min_j: f64,
    /// Largest node displacement (mm).
    pub max_displacement_mm: f64,
    /// Largest displacement of a node farther than 60 mm from every crack node (mm).
    pub far_displacement_mm: f64,
    /// 95th percentile (nearest rank) of the displacement over the nodes farther than 60 mm from every
    /// crack node (mm; 0 in reports written before it was recorded).
    #[serde(default)]
    pub far_displacement_p95_mm: f64,
    /// Share of the nodes farther than 60 mm from every crack node that move more than 1 mm
    /// (0 in reports written before it was recorded).
    #[serde(default)]
    pub far_share_over_1mm: f64,
    /// Free DOFs of the TET10 problem.
    pub free_dofs: usize,
    /// Newton iterations of the accepted solve.
    pub newton_iterations: usize,
    /// Largest final relative residual of the accepted solve.
    pub max_relative_residual: f64,
    /// Wall time of all solves (s).
    pub seconds: f64,
    /// Accepted solve: solver of the Newton directions (`direct` or `two-level`; empty in reports
    /// written before it was recorded: direct).
    #[serde(default)]
    pub linear_solver: String,
    /// Accepted solve: numeric Cholesky factorisations (of the coarse level for the two-level solver).
    #[serde(default)]
    pub factorizations: usize,
    /// Accepted solve: time of the factorisations (s).
    #[serde(default)]
    pub factorization_s: f64,
    /// Accepted solve: conjugate-gradient iterations (preconditioned by a reused factor or the two-level cycle).
    #[serde(default)]
    pub pcg_iterations: usize,
    /// Accepted solve: time of all triangular solves and CG iterations (s).
    #[serde(default)]
    pub solve_s: f64,
    /// Accepted solve: element evaluation and assembly (s).
    #[serde(default)]
    pub assembly_s: f64,
    /// Accepted solve: the mouth's opening profile along lip A (mm), see [`lip_opening_profile_mm`].
    #[serde(default)]
    pub lip_opening_mm: Vec<f64>,
}

/// Distance between every two deformed copies of one duplicated crack node (mm), unordered.
pub fn crack_pair_gaps_mm(cut: &CutMesh, deformed: &[Vector3<f64>]) -> Vec<f64> {
    let copies = copies_of_crack_nodes(cut);
    copies.values().flat_map(|c| copy_gaps(c, deformed)).collect()
}

/// The distances between every two deformed copies in `copies` (mm).
fn copy_gaps<'a>(copies: &'a [usize], deformed: &'a [Vector3<f64>]) -> impl Iterator<Item = f64> + 'a {
    copies
        .iter()
        .enumerate()
        .flat_map(move |(k, &i)| copies[k + 1..].iter().map(move |&j| (deformed[i] - deformed[j]).norm()))
}

/// The copies (cut-mesh indices) of every crack node the cut duplicated, by uncut-mesh node.
fn copies_of_crack_nodes(cut: &CutMesh) -> std::collections::HashMap<usize, Vec<usize>> {
    let mut copies: std::collections::HashMap<usize, Vec<usize>> = std::collections::HashMap::new();
    for (i, &o) in cut.original_node.iter().enumerate() {
        copies.entry(o).or_default().push(i);
    }
    copies.retain(|_, c| c.len() > 1);
    copies
}

/// The crack's opening field: for every duplicated crack node (by its index in the uncut mesh,
/// `cut.original_node`), the largest distance between two of its deformed copies (mm). Crack-front nodes
/// are not duplicated and are absent (they cannot open).
pub fn crack_gap_by_node_mm(cut: &CutMesh, deformed: &[Vector3<f64>]) -> std::collections::HashMap<usize, f64> {
    copies_of_crack_nodes(cut).into_iter().map(|(o, c)| (o, copy_gaps(&c, deformed).fold(0.0, f64::max))).collect()
}

/// The blade unrolled flat, per mouth sample: (mm across the rulings from the first sample, mm below the
/// first sample along the rulings). The mouth's climbs along the rulings (a ridge, a fold) are heights, not
/// width, so a planar blade unrolls to its own plane exactly.
pub fn blade_chart_mm(blade: &laparo_fem::mesh::Blade) -> Vec<(f64, f64)> {
    let m = &blade.mouth;
    let mut chart = vec![(0.0, 0.0); m.len()];
    for i in 1..m.len() {
        let step = m[i] - m[i - 1];
        let d = (blade.directions[i].normalize() + blade.directions[i - 1].normalize()).normalize();
        let (across, level) = chart[i - 1];
        chart[i] = (across + (step - d * d.dot(&step)).norm(), level + d.dot(&step));
    }
    chart
}

/// Where `p` lies on the blade unrolled flat ([`blade_chart_mm`]): measured on the ruling (mouth sample +
/// direction) nearest to `p`, (mm across the rulings, mm below the first mouth sample).
pub fn blade_coordinates_mm(blade: &laparo_fem::mesh::Blade, chart: &[(f64, f64)], p: &Vector3<f64>) -> (f64, f64) {
    let m = &blade.mouth;
    let dir = |i: usize| blade.directions[i].normalize();
    let off_ruling = |i: usize| {
        let r = p - m[i];
        (r - dir(i) * r.dot(&dir(i))).norm()
    };
    let i = (0..m.len()).min_by(|&a, &b| off_ruling(a).total_cmp(&off_ruling(b))).unwrap_or(0);
    let (r, d) = (p - m[i], dir(i));
    // across: the offset along the local tangent (its ruling component removed), within half a step of sample i
    let (prev, next) = (i.saturating_sub(1), (i + 1).min(m.len() - 1));
    let tangent = m[next] - m[prev];
    let tangent = tangent - d * d.dot(&tangent);
    let offset = if tangent.norm() > 0.0 {
        let lo = -(chart[i].0 - chart[prev].0) / 2.0;
        let hi = (chart[next].0 - chart[i].0) / 2.0;
        r.dot(&tangent.normalize()).clamp(lo, hi)
    } else {
        0.0
    };
    (chart[i].0 + offset, chart[i].1 + r.dot(&d))
}

/// Largest distance between two deformed copies of one duplicated crack node (mm), over all pairs of copies.
pub fn max_gap_mm(cut: &CutMesh, deformed: &[Vector3<f64>]) -> f64 {
    crack_pair_gaps_mm(cut, deformed).into_iter().fold(0.0, f64::max)
}

/// Rest distance of every node of the cut mesh to the nearest crack-face node (mm): the far-field measure.
pub fn distance_to_crack_mm(cut: &CutMesh) -> Result<Vec<f64>> {
    let x = &cut.mesh.vertices;
    let crack: Vec<Vector3<f64>> = cut.crack_faces.iter().flatten().flatten().map(|&i| x[i]).collect();
    super::tre::distance_to_nearest(x, &crack)
}

/// Opening of the incision mouth: for each lip-A node whose node also has a copy on lip B, the distance
/// between the two deformed copies (mm), in lip-A order (zero at the crack ends, the opening profile).
pub fn lip_opening_profile_mm(cut: &CutMesh, deformed: &[Vector3<f64>]) -> Vec<f64> {
    let on_b: std::collections::HashMap<usize, usize> =
        cut.lips[1].iter().map(|&i| (cut.original_node[i], i)).collect();
    cut.lips[0]
        .iter()
        .filter_map(|&i| on_b.get(&cut.original_node[i]).map(|&j| (deformed[i] - deformed[j]).norm()))
        .collect()
}

/// How finely a mesh resolves the blade: the crack it cut against the blade it was cut with.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct CrackResolution {
    /// Area of the crack faces of side A and B (mm²).
    pub crack_area_mm2: [f64; 2],
    /// Area of the blade inside the organ's input surface (mm²), sampled at 78 points per blade triangle.
    pub blade_area_inside_mm2: f64,
    /// Crack nodes split into two copies (the nodes that can open).
    pub duplicated_nodes: usize,
    /// Lip nodes with a copy on both lips (samples of the mouth's opening profile).
    pub lip_pairs: usize,
}

impl CrackResolution {
    /// The crack of `scn` against its blade inside `organ` (the surface the blade was traced on).
    pub fn of(scn: &Scenario, organ: &laparo_fem::mesh::Surface) -> Self {
        let x = &scn.cut.mesh.vertices;
        let area = |f: &[usize; 3]| 0.5 * (x[f[1]] - x[f[0]]).cross(&(x[f[2]] - x[f[0]])).norm();
        let crack_area_mm2 = [0, 1].map(|k| scn.cut.crack_faces[k].iter().map(area).sum::<f64>());
        let bs = scn.blade.surface();
        const N: usize = 12;
        let mut inside = 0.0;
        for f in &bs.faces {
            let q = f.map(|k| bs.vertices[k]);
            let a = 0.5 * (q[1] - q[0]).cross(&(q[2] - q[0])).norm();
            let (mut hit, mut all) = (0usize, 0usize);
            for i in 0..N {
                for j in 0..N - i {
                    let (u, v) = ((i as f64 + 1.0 / 3.0) / N as f64, (j as f64 + 1.0 / 3.0) / N as f64);
                    all += 1;
                    if organ.contains(&(q[0] + (q[1] - q[0]) * u + (q[2] - q[0]) * v)) {
                        hit += 1;
                    }
                }
            }
            inside += a * hit as f64 / all as f64;
        }
        let mut seen = std::collections::HashSet::new();
        let duplicated_nodes = scn.cut.original_node.iter().filter(|&&o| !seen.insert(o)).count();
        let rest = &scn.cut.mesh.vertices;
        let lip_pairs = lip_opening_profile_mm(&scn.cut, rest).len();
        CrackResolution { crack_area_mm2, blade_area_inside_mm2: inside, duplicated_nodes, lip_pairs }
    }

    /// Smaller crack side over the blade area inside the organ.
    pub fn area_fraction(&self) -> f64 {
        self.crack_area_mm2[0].min(self.crack_area_mm2[1]) / self.blade_area_inside_mm2.max(1e-12)
    }

    /// Error (naming `edge_mm`) when the crack covers less than `min_fraction` of the blade inside the organ
    /// or the mouth has fewer than `min_lip_pairs` samples: the mesh is too coarse for the incision.
    pub fn check(&self, edge_mm: f64, min_fraction: f64, min_lip_pairs: usize) -> Result<()> {
        if self.area_fraction() < min_fraction || self.lip_pairs < min_lip_pairs {
            return Err(RegisterError::param(
                "edge_mm",
                edge_mm,
                format!(
                    "the mesh does not resolve the incision: its crack covers {:.0} / {:.0} mm² of the blade inside \
                     the organ ({:.0} %, need ≥ {:.0} %) with {} lip samples (need ≥ {min_lip_pairs}); use smaller tets",
                    self.crack_area_mm2[0].min(self.crack_area_mm2[1]),
                    self.blade_area_inside_mm2,
                    100.0 * self.area_fraction(),
                    100.0 * min_fraction,
                    self.lip_pairs
                ),
            ));
        }
        Ok(())
    }
}

/// The problem of `scn` with pressure `p_ref` (kPa) on the crack faces; a load factor f is the pressure f · `p_ref`.
fn crack_problem(scn: &Scenario, material: NeoHookean, p_ref: f64) -> laparo_fem::Result<SolidProblem> {
    let mesh = Tet10Mesh::from_linear(&scn.cut.mesh)?;
    let dirichlet = SolidProblem::fixed_vertices(&mesh, &scn.fixed_nodes)?;
    let loads = Loads { face_tractions: scn.cut.crack_pressure(p_ref), ..Default::default() };
    SolidProblem::new(mesh, material, &dirichlet, &loads, Quadrature::Degree2)
}

/// The ground truth of `scn`: node displacements of the cut mesh (mm) and the calibration report.
/// `progress` sees (solve index, pressure kPa, gap mm) after each solve.
pub fn fem_ground_truth(
    scn: &Scenario,
    cfg: &GroundTruthConfig,
    progress: &mut dyn FnMut(usize, f64, f64),
) -> Result<(Vec<Vector3<f64>>, GroundTruthReport)> {
    let material = NeoHookean::from_young_poisson(cfg.youngs_modulus_kpa, cfg.poisson_ratio)
        .map_err(|e| RegisterError::bad("ground-truth material", e.to_string()))?;
    let [lo, hi] = cfg.target_gap_mm;
    if !(lo > 0.0 && hi > lo) {
        return Err(RegisterError::param("target_gap_mm", lo, "need 0 < lo < hi"));
    }
    let target = 0.5 * (lo + hi);
    let t0 = std::time::Instant::now();
    let x0 = &scn.cut.mesh.vertices;
    let mut tried: Vec<[f64; 2]> = Vec::new();
    let mut p = cfg.initial_pressure_kpa;
    if !(p.is_finite() && p > 0.0) {
        return Err(RegisterError::param("initial_pressure_kpa", p, "must be finite and > 0"));
    }
    // One problem for every solve of the calibration: each starts from the nearest lower equilibrium
    // already reached (the pressures are load factors of the first).
    let fem = |e: laparo_fem::FemError| RegisterError::bad(format!("FEM ground truth ({})", scn.name), e.to_string());
    let problem = crack_problem(scn, material, p).map_err(fem)?;
    let settings = SolverSettings { steps: cfg.steps, rel_tol: cfg.rel_tol, ..Default::default() };
    let mut path = LoadPath::new(&problem, &settings).map_err(fem)?;
    let mut best: Option<(Solution, f64, f64)> = None;
    for k in 0..cfg.max_solves.max(1) {
        let sol = match path.solve_at(p / cfg.initial_pressure_kpa).map_err(fem) {
            Ok(s) => s,
            Err(e) if k > 0 => {
                // too much pressure (inversion): step back halfway towards the last good pressure
                let good = tried.last().map(|t| t[0]).unwrap_or(0.0);
                tried.push([p, f64::NAN]);
                p = 0.5 * (p + good);
                let _ = e;
                continue;
            }
            Err(e) => return Err(e),
        };
        let def: Vec<Vector3<f64>> = x0.iter().zip(sol.vertex_displacements()).map(|(a, u)| a + u).collect();
        let gap = max_gap_mm(&scn.cut, &def);
        tried.push([p, gap]);
        progress(k, p, gap);
        let done = gap >= lo && gap <= hi;
        best = Some((sol, p, gap));
        if done {
            break;
        }
        // secant on the last two good solves (gap ∝ p at first), else proportional scaling
        let good: Vec<[f64; 2]> = tried.iter().copied().filter(|t| t[1].is_finite()).collect();
        p = if good.len() >= 2 {
            let [p1, g1] = good[good.len() - 2];
            let [p2, g2] = good[good.len() - 1];
            if (g2 - g1).abs() > 1e-9 {
                (p2 + (target - g2) * (p2 - p1) / (g2 - g1)).clamp(0.25 * p2, 4.0 * p2)
            } else {
                p2 * target / g2.max(1e-9)
            }
        } else {
            p * (target / gap.max(1e-6)).clamp(0.1, 20.0)
        };
    }
    let (sol, p, gap) =
        best.ok_or_else(|| RegisterError::bad(format!("FEM ground truth ({})", scn.name), "no solve succeeded"))?;
    if !(gap >= lo && gap <= hi) {
        return Err(RegisterError::bad(
            format!("FEM ground truth ({})", scn.name),
            format!(
                "the lip gap reached {gap:.2} mm, not [{lo}, {hi}] mm, after {} solves (pressures {:?})",
                tried.len(),
                tried
            ),
        ));
    }
    let u = sol.vertex_displacements().to_vec();
    let deformed: Vec<Vector3<f64>> = x0.iter().zip(&u).map(|(a, b)| a + b).collect();
    let lip_opening_mm = lip_opening_profile_mm(&scn.cut, &deformed);
    // far field: nodes farther than 60 mm from every crack node
    let d = distance_to_crack_mm(&scn.cut)?;
    let far_u: Vec<f64> = u.iter().zip(&d).filter(|(_, &d)| d > 60.0).map(|(u, _)| u.norm()).collect();
    let far = super::tre::Stats::of(&far_u);
    let far_share = far_u.iter().filter(|&&m| m > 1.0).count() as f64 / far_u.len().max(1) as f64;
    let report = GroundTruthReport {
        pressure_kpa: p,
        max_gap_mm: gap,
        calibration: tried,
        min_j: sol.min_j,
        max_displacement_mm: sol.max_displacement_mm,
        far_displacement_mm: far.max,
        far_displacement_p95_mm: far.p95,
        far_share_over_1mm: far_share,
        free_dofs: sol.free_dofs,
        newton_iterations: sol.timings.newton_iterations,
        max_relative_residual: sol
            .steps
            .iter()
            .filter_map(|s| s.residual_history.last().map(|r| r / s.tolerance * cfg.rel_tol))
            .fold(0.0, f64::max),
        seconds: t0.elapsed().as_secs_f64(),
        linear_solver: sol.linear_solver.to_string(),
        factorizations: sol.timings.factorizations,
        factorization_s: sol.timings.factorization_s,
        pcg_iterations: sol.timings.pcg_iterations,
        solve_s: sol.timings.solve_s,
        assembly_s: sol.timings.assembly_s,
        lip_opening_mm,
    };
    Ok((u, report))
}

/// Remove the pieces of the cut mesh that the blade detached from the organ (connected through no node to
/// the fixed region): cut-free fragments of tissue, which no boundary condition holds and a resection would
/// remove. Returns the number of nodes removed. Every index of the scenario is renumbered.
pub fn drop_detached_fragments(scn: &mut Scenario) -> usize {
    let cut = &mut scn.cut;
    let n = cut.mesh.vertices.len();
    let mut parent: Vec<usize> = (0..n).collect();
    fn find(p: &mut [usize], mut i: usize) -> usize {
        while p[i] != i {
            p[i] = p[p[i]];
            i = p[i];
        }
        i
    }
    for t in &cut.mesh.tets {
        for k in 1..4 {
            let (a, b) = (find(&mut parent, t[0]), find(&mut parent, t[k]));
            if a != b {
                parent[a.max(b)] = a.min(b);
            }
        }
    }
    let mut fixed_count: std::collections::HashMap<usize, usize> = std::collections::HashMap::new();
    for &f in &scn.fixed_nodes {
        *fixed_count.entry(find(&mut parent, f)).or_default() += 1;
    }
    let Some((&keep, _)) = fixed_count.iter().max_by_key(|(root, c)| (**c, std::cmp::Reverse(**root))) else {
        return 0;
    };
    let kept: Vec<bool> = (0..n).map(|i| find(&mut parent, i) == keep).collect();
    let removed = kept.iter().filter(|k| !**k).count();
    if removed == 0 {
        return 0;
    }
    let mut new_id = vec![usize::MAX; n];
    let mut next = 0;
    for i in 0..n {
        if kept[i] {
            new_id[i] = next;
            next += 1;
        }
    }
    let keep_tet: Vec<bool> = cut.mesh.tets.iter().map(|t| kept[t[0]]).collect();
    cut.mesh.vertices = (0..n).filter(|&i| kept[i]).map(|i| cut.mesh.vertices[i]).collect();
    cut.original_node = (0..n).filter(|&i| kept[i]).map(|i| cut.original_node[i]).collect();
    cut.tet_side = cut.tet_side.iter().zip(&keep_tet).filter(|(_, k)| **k).map(|(s, _)| *s).collect();
    cut.mesh.tets = cut.mesh.tets.iter().filter(|t| kept[t[0]]).map(|t| t.map(|i| new_id[i])).collect();
    for faces in cut.crack_faces.iter_mut() {
        *faces = faces.iter().filter(|f| f.iter().all(|&i| kept[i])).map(|f| f.map(|i| new_id[i])).collect();
    }
    for lip in cut.lips.iter_mut() {
        *lip = lip.iter().filter(|&&i| kept[i]).map(|&i| new_id[i]).collect();
    }
    cut.front_nodes = cut.front_nodes.iter().filter(|&&i| kept[i]).map(|&i| new_id[i]).collect();
    scn.fixed_nodes = scn.fixed_nodes.iter().filter(|&&i| kept[i]).map(|&i| new_id[i]).collect();
    removed
}

/// Incision side of every node of `cut`: 1 / 2 for nodes on the crack faces of side A / B only, 0 else
/// (crack-front nodes are on both and stay 0).
pub fn node_sides(cut: &CutMesh) -> Vec<u8> {
    let mut s = vec![0u8; cut.mesh.vertices.len()];
    for (k, faces) in cut.crack_faces.iter().enumerate() {
        for &i in faces.iter().flatten() {
            s[i] |= 1 << k;
        }
    }
    s.iter()
        .map(|&b| {
            if b == 1 {
                1
            } else if b == 2 {
                2
            } else {
                0
            }
        })
        .collect()
}

/// Smallest region of interest (a ball around the crack's centroid, radius from `r0_mm` in 10 mm steps
/// up to `r_max_mm`) such that every node a method holds at rest with it — its boundary shell (the nodes
/// within `shell_mm` inside it) and everything outside — has a ground-truth displacement below
/// `max_boundary_mm`; returns the ball and that largest held displacement (mm); None when even
/// `r_max_mm` fails (simulate the whole organ). Checking the shell alone would accept a ball that a deep
/// cut's mouth pokes out of (the mouth then held at rest).
pub fn choose_roi(
    rest: &[Vector3<f64>],
    displacement: &[Vector3<f64>],
    centre: Vector3<f64>,
    r0_mm: f64,
    r_max_mm: f64,
    shell_mm: f64,
    max_boundary_mm: f64,
) -> Option<(Roi, f64)> {
    let mut r = r0_mm;
    while r <= r_max_mm + 1e-9 {
        let worst = rest
            .iter()
            .zip(displacement)
            .filter(|(x, _)| (*x - centre).norm() > r - shell_mm)
            .map(|(_, u)| u.norm())
            .fold(0.0, f64::max);
        if worst < max_boundary_mm {
            return Some((Roi::Ball { center: [centre[0], centre[1], centre[2]], radius_mm: r }, worst));
        }
        r += 10.0;
    }
    None
}

/// A [`BenchmarkCase`] from a scenario and its ground-truth displacements.
pub fn case_from(scn: &Scenario, displacement: &[Vector3<f64>], roi: Option<Roi>) -> BenchmarkCase {
    let x = &scn.cut.mesh.vertices;
    BenchmarkCase {
        scenario: scn.name.clone(),
        rest: x.clone(),
        tets: scn.cut.mesh.tets.clone(),
        surface: scn.cut.mesh.boundary().faces,
        node_side: node_sides(&scn.cut),
        ground_truth: x.iter().zip(displacement).map(|(a, u)| a + u).collect(),
        original_node: scn.cut.original_node.clone(),
        lips: scn.cut.lips.clone(),
        fixed: scn.fixed_nodes.clone(),
        roi,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blade_coordinates_unroll_a_straight_a_climbing_and_a_curved_blade() {
        use laparo_fem::mesh::Blade;
        // straight mouth along x, blade straight down (−z), 50 mm deep: (across, below) = (x, −z)
        let mouth: Vec<Vector3<f64>> = (0..=20).map(|i| Vector3::new(5.0 * i as f64, 0.0, 0.0)).collect();
        let flat = Blade::uniform(mouth, -Vector3::z(), 50.0, 2.0);
        let chart = blade_chart_mm(&flat);
        let (s, d) = blade_coordinates_mm(&flat, &chart, &Vector3::new(32.5, 0.7, -21.0));
        assert!((s - 32.5).abs() < 1e-12 && (d - 21.0).abs() < 1e-12, "({s}, {d})");
        // a planar blade whose mouth climbs a 40 mm ridge (as on the P2ILF liver): still its own plane, the
        // mouth's height in `below`, the climb no width
        let ridge = |x: f64| if (30.0..50.0).contains(&x) { 40.0 } else { 0.0 };
        let mouth: Vec<Vector3<f64>> = (0..=80).map(|i| Vector3::new(i as f64, 0.0, ridge(i as f64))).collect();
        let climbing = Blade::uniform(mouth, -Vector3::z(), 60.0, 2.0);
        let chart = blade_chart_mm(&climbing);
        assert!((chart[80].0 - 80.0).abs() < 1e-12 && chart[80].1.abs() < 1e-12, "{:?}", chart[80]);
        assert!((chart[40].1 + 40.0).abs() < 1e-12, "the ridge top is 40 mm above the first sample");
        for p in [Vector3::new(40.2, 0.0, 12.0), Vector3::new(29.6, -0.5, -30.0), Vector3::new(70.0, 1.0, -7.5)] {
            let (s, d) = blade_coordinates_mm(&climbing, &chart, &p);
            assert!((s - p.x).abs() < 1e-9 && (d + p.z).abs() < 1e-9, "{p:?}: ({s}, {d})");
        }
        // a half circle of radius 30 mm (the wedge around a tumour), blade down: across = the arc to the point
        let r = 30.0;
        let n = 181;
        let arc: Vec<Vector3<f64>> = (0..n)
            .map(|i| {
                let t = std::f64::consts::PI * i as f64 / (n - 1) as f64;
                Vector3::new(r * t.cos(), r * t.sin(), 0.0)
            })
            .collect();
        let curved = Blade::uniform(arc, -Vector3::z(), 25.0, 2.0);
        let chart = blade_chart_mm(&curved);
        for theta in [0.3f64, 1.0, 2.2] {
            let p = Vector3::new(r * theta.cos(), r * theta.sin(), -12.0);
            let (s, d) = blade_coordinates_mm(&curved, &chart, &p);
            // the polyline's arc is a chord sum: shorter than r θ by at most r θ (Δθ)²/24
            assert!((s - r * theta).abs() < 1e-3, "θ {theta}: across {s} vs {}", r * theta);
            assert!((d - 12.0).abs() < 1e-12, "θ {theta}: below {d}");
        }
    }

    #[test]
    fn roi_holds_no_moving_node_even_outside_its_shell() {
        // nodes on a line from the centre; the ones at 10 and 75 mm move 5 mm, the rest stay
        let rest: Vec<Vector3<f64>> = (0..=100).map(|k| Vector3::new(k as f64, 0.0, 0.0)).collect();
        let u: Vec<Vector3<f64>> = (0..=100)
            .map(|k| if k == 10 || k == 75 { Vector3::new(0.0, 5.0, 0.0) } else { Vector3::zeros() })
            .collect();
        // a 50 mm ball's shell (44–50 mm) is still, but the node at 75 mm would be held at rest: the ball must reach it
        let (roi, worst) = choose_roi(&rest, &u, Vector3::zeros(), 50.0, 120.0, 6.0, 0.5).unwrap();
        let Roi::Ball { radius_mm, .. } = roi else { panic!("a ball") };
        assert_eq!(radius_mm, 90.0, "75 mm node inside, 6 mm shell clear of it");
        assert_eq!(worst, 0.0);
        // forced radius: the held displacement is reported
        let (_, worst) = choose_roi(&rest, &u, Vector3::zeros(), 50.0, 50.0, 6.0, f64::INFINITY).unwrap();
        assert_eq!(worst, 5.0);
        // nothing up to 70 mm qualifies
        assert!(choose_roi(&rest, &u, Vector3::zeros(), 50.0, 70.0, 6.0, 0.5).is_none());
    }
}
