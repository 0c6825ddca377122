//! A benchmark case (one scenario on one mesh): the cut rest mesh, its FEM ground-truth deformation and the
//! incision lips; landmarks sampled on the lips; the [`Method`] interface every registration method
//! implements; scoring of one run; and the resumable protocol loop over methods × columns × seeds.
use super::points::EvalPoints;
use super::protocol::{noisy_targets, Column};
use super::store::{Provenance, ResultStore, RunKey, RunResult};
use super::tre::PointScores;
use super::tre::{binned, distance_to_nearest, node_errors, Stats, DISTANCE_BIN_EDGES_MM};
use crate::error::{RegisterError, Result};
use crate::organ::Roi;
use nalgebra::Vector3;
use std::sync::Arc;

/// One scenario on one mesh, with its ground truth (mm).
#[derive(Clone, Debug)]
pub struct BenchmarkCase {
    /// Scenario name (`non-anatomical`, `anatomical`).
    pub scenario: String,
    /// Rest node positions of the cut mesh (the source: cut but undeformed).
    pub rest: Vec<Vector3<f64>>,
    /// Tetrahedra of the cut mesh (crack nodes duplicated).
    pub tets: Vec<[usize; 4]>,
    /// Boundary triangles of the cut mesh (outer surface and crack faces), for surface TRE and pictures.
    pub surface: Vec<[usize; 3]>,
    /// 0 away from the crack, 1 or 2 for the copies of a duplicated crack node.
    pub node_side: Vec<u8>,
    /// Ground-truth deformed node positions (FEM).
    pub ground_truth: Vec<Vector3<f64>>,
    /// Per node, the node of the uncut mesh it comes from (the two copies of a crack node share one).
    pub original_node: Vec<usize>,
    /// Ordered node ids along each lip's mouth (where the crack meets the outer surface), side 1 then side 2.
    pub lips: [Vec<usize>; 2],
    /// Nodes held fixed by the ground truth (they are known to the methods as fixed too).
    pub fixed: Vec<usize>,
    /// Region of interest RODS-MPM simulates (None = the whole organ).
    pub roi: Option<Roi>,
    /// The ground truth's full TET10 displacement field (mm): every node of
    /// `laparo_fem::solid::Tet10Mesh::from_linear` of the rest mesh (vertices first). None: the ground truth is
    /// known at the vertices only and read between them linearly.
    pub ground_truth_p2: Option<Vec<Vector3<f64>>>,
    /// The common evaluation points every method is scored at ([`BenchmarkCase::with_points`]); None: scored at
    /// the mesh nodes only (the v1 protocol).
    pub points: Option<Arc<EvalPoints>>,
}

pub use crate::baselines::MaterialPoint;

/// The landmarks of one lip: material points, their rest (source) positions and the observed target
/// positions (ground truth at the same material points, plus noise).
#[derive(Clone, Debug)]
pub struct LandmarkSet {
    /// `lip 1`, `lip 2`.
    pub name: String,
    /// Incision side (1 or 2).
    pub side: u8,
    /// The material points.
    pub points: Vec<MaterialPoint>,
    /// Source positions (rest, mm).
    pub sources: Vec<Vector3<f64>>,
    /// Target positions (mm): the target polyline's vertices, in order along the lip.
    pub targets: Vec<Vector3<f64>>,
}

/// What a method returns.
#[derive(Clone, Debug)]
pub struct MethodOutput {
    /// Registered node positions (mm), one per node of the case.
    pub nodes: Vec<Vector3<f64>>,
    /// Mean landmark distance to the targets after registration (mm, eq. 5.10).
    pub landmark_distance_mm: f64,
    /// Findings worth reporting.
    pub notes: Vec<String>,
    /// Registered positions of the case's evaluation points (mm), when the method reads its own field there
    /// (RODS-MPM: the particle→point transfer); None: the nodes are interpolated linearly in each point's
    /// element ([`EvalPoints::p1`], how every mesh method is read).
    pub points: Option<Vec<Vector3<f64>>>,
    /// Energy audit of a simulating method (None for mesh methods).
    pub energy: Option<crate::optimize::EnergyAudit>,
}

/// A registration method under test.
pub trait Method {
    /// Name in the tables (`ARAP`, `DRBC`, `Francois`, `LDDMM`, `RODS-MPM`).
    fn name(&self) -> String;
    /// Every setting that changes the result, as text (a stored run is resumed only under the same settings).
    fn settings(&self) -> String;
    /// Register the case's rest mesh to the landmark targets.
    fn register(&self, case: &BenchmarkCase, landmarks: &[LandmarkSet]) -> Result<MethodOutput>;
    /// Whether the method runs on `case` at all ([`run_protocol`] skips it otherwise; e.g. a baseline that
    /// borrows RODS-MPM's region of interest on a whole-organ case).
    fn applies_to(&self, _case: &BenchmarkCase) -> bool {
        true
    }
    /// The name of the floor row that bounds this method's representation (the ground truth pushed through it
    /// and read back); None for a row that is itself a floor or has no representation ("none").
    fn floor(&self) -> Option<String> {
        None
    }
    /// Whether the result depends on the landmarks (false: run once per column, seed 0, e.g. a floor).
    fn uses_landmarks(&self) -> bool {
        true
    }
}

/// 64-bit FNV-1a (hex) of a method's settings text: the configuration hash every stored run records, so two
/// runs with any hyperparameter different never share a hash.
pub fn config_hash(settings: &str) -> String {
    laparo_core::atomic::fnv1a64_hex(settings.as_bytes())
}

impl BenchmarkCase {
    /// A 64-bit FNV-1a fingerprint (hex) of everything a run reads from the case: scenario, rest nodes,
    /// tetrahedra, node sides, ground truth, lips, fixed nodes and region of interest (coordinates bit-exact).
    pub fn fingerprint(&self) -> String {
        let mut b: Vec<u8> = self.scenario.as_bytes().to_vec();
        for p in self.rest.iter().chain(&self.ground_truth) {
            p.iter().for_each(|c| b.extend(c.to_bits().to_le_bytes()));
        }
        let lists =
            [&self.tets.iter().flatten().copied().collect::<Vec<_>>(), &self.lips[0], &self.lips[1], &self.fixed];
        for l in lists {
            b.extend((l.len() as u64).to_le_bytes());
            l.iter().for_each(|&i| b.extend((i as u64).to_le_bytes()));
        }
        b.extend(&self.node_side);
        b.extend(format!("{:?}", self.roi).as_bytes());
        if let Some(u) = &self.ground_truth_p2 {
            b.extend(b"p2");
            u.iter().for_each(|p| p.iter().for_each(|c| b.extend(c.to_bits().to_le_bytes())));
        }
        if let Some(p) = &self.points {
            b.extend(format!("points {} {}", p.spacing_mm.to_bits(), p.len()).as_bytes());
        }
        laparo_core::atomic::fnv1a64_hex(&b)
    }

    /// Check sizes and finiteness; a clear error naming the field.
    pub fn validate(&self) -> Result<()> {
        let n = self.rest.len();
        let bad = |f: &str, r: String| Err(RegisterError::bad(format!("benchmark case `{}`: {f}", self.scenario), r));
        if n == 0 || self.tets.is_empty() {
            return bad("mesh", "empty".into());
        }
        if self.ground_truth.len() != n || self.node_side.len() != n {
            return bad(
                "ground truth / sides",
                format!("{} / {} values for {n} nodes", self.ground_truth.len(), self.node_side.len()),
            );
        }
        if self.rest.iter().chain(&self.ground_truth).any(|p| !p.iter().all(|v| v.is_finite())) {
            return bad("positions", "non-finite value".into());
        }
        if self.tets.iter().flatten().chain(self.surface.iter().flatten()).chain(self.fixed.iter()).any(|&i| i >= n) {
            return bad("connectivity", format!("a node index >= {n}"));
        }
        for (k, lip) in self.lips.iter().enumerate() {
            if lip.len() < 2 || lip.iter().any(|&i| i >= n) {
                return bad(&format!("lip {}", k + 1), format!("{} nodes (need ≥ 2 valid ids)", lip.len()));
            }
        }
        Ok(())
    }

    /// The uncut mesh the methods that do not know the incision start from: one node per original node (at
    /// the rest position of its first copy), the tetrahedra re-indexed; and the map cut node → uncut node.
    pub fn uncut(&self) -> (Vec<Vector3<f64>>, Vec<[usize; 4]>, Vec<usize>) {
        let mut index = std::collections::HashMap::new();
        let mut nodes = Vec::new();
        let map: Vec<usize> = (0..self.rest.len())
            .map(|i| {
                *index.entry(self.original_node[i]).or_insert_with(|| {
                    nodes.push(self.rest[i]);
                    nodes.len() - 1
                })
            })
            .collect();
        let tets = self.tets.iter().map(|t| t.map(|i| map[i])).collect();
        (nodes, tets, map)
    }

    /// This case with its common evaluation points at `spacing_mm` ([`EvalPoints::build`]).
    pub fn with_points(mut self, spacing_mm: f64) -> Result<Self> {
        self.points = Some(Arc::new(EvalPoints::build(&self, spacing_mm)?));
        Ok(self)
    }

    /// Nodes on the boundary surface, sorted.
    pub fn surface_nodes(&self) -> Vec<usize> {
        let mut v: Vec<usize> = self.surface.iter().flatten().copied().collect();
        v.sort_unstable();
        v.dedup();
        v
    }

    /// Largest ground-truth displacement (mm).
    pub fn max_displacement_mm(&self) -> f64 {
        self.rest.iter().zip(&self.ground_truth).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max)
    }

    /// `n_total` landmarks, half on each lip, equally spaced by rest arc length along the lip (at (k + ½) L / (N/2),
    /// `laparo_fem::mesh::incision::lip_landmarks`), with noiseless targets at the same material points in the
    /// ground truth.
    pub fn lip_landmarks(&self, n_total: usize) -> Result<Vec<LandmarkSet>> {
        let lm = laparo_fem::mesh::incision::lip_landmarks(&self.lips, &self.rest, n_total)
            .map_err(|e| RegisterError::bad(format!("benchmark case `{}`: landmarks", self.scenario), e.to_string()))?;
        Ok((0..2u8)
            .map(|side| {
                let points: Vec<MaterialPoint> = lm
                    .items
                    .iter()
                    .filter(|l| l.side == side)
                    .map(|l| MaterialPoint::combination(&[(l.a, 1.0 - l.t), (l.b, l.t)]))
                    .collect();
                let sources = points.iter().map(|p| p.position(&self.rest)).collect();
                let targets = points.iter().map(|p| p.position(&self.ground_truth)).collect();
                LandmarkSet { name: format!("lip {}", side + 1), side: side + 1, points, sources, targets }
            })
            .collect())
    }
}

/// Landmarks of `column` for `seed`: `column.landmarks` lip landmarks with N(0, σ²I) noise on the targets.
pub fn column_landmarks(case: &BenchmarkCase, column: &Column, seed: u64) -> Result<Vec<LandmarkSet>> {
    let mut lm = case.lip_landmarks(column.landmarks)?;
    let t: Vec<Vec<Vector3<f64>>> = lm.iter().map(|l| l.targets.clone()).collect();
    for (l, noisy) in lm.iter_mut().zip(noisy_targets(&t, column.noise_sigma_mm, seed)) {
        l.targets = noisy;
    }
    Ok(lm)
}

/// Score registered node positions against the ground truth.
pub fn score(
    case: &BenchmarkCase,
    landmarks: &[LandmarkSet],
    out: &MethodOutput,
    key: RunKey,
    provenance: Provenance,
    seconds: f64,
) -> Result<RunResult> {
    let e = node_errors(&out.nodes, &case.ground_truth)?;
    let src: Vec<Vector3<f64>> = landmarks.iter().flat_map(|l| l.sources.iter().copied()).collect();
    let d = distance_to_nearest(&case.rest, &src)?;
    let surf: Vec<f64> = case.surface_nodes().iter().map(|&i| e[i]).collect();
    let points = match (&case.points, registered_points(case, out)) {
        (Some(p), Some(x)) => Some(PointScores::of(p, &x)?),
        _ => None,
    };
    Ok(RunResult {
        key,
        tre_volume: Stats::of(&e),
        tre_surface: Stats::of(&surf),
        bins: binned(&e, &d, &DISTANCE_BIN_EDGES_MM),
        max_gt_displacement_mm: case.max_displacement_mm(),
        landmark_distance_mm: out.landmark_distance_mm,
        seconds,
        notes: out.notes.clone(),
        config_hash: config_hash(&provenance.settings),
        provenance,
        points,
        floor: None,
        energy: out.energy,
    })
}

/// One finished (or resumed) run, as [`run_protocol`] reports it.
pub struct RunEvent<'a> {
    /// Runs done so far (this one included).
    pub done: usize,
    /// Runs in all.
    pub total: usize,
    /// The case of the run.
    pub case: &'a BenchmarkCase,
    /// The run's result.
    pub result: &'a RunResult,
    /// The registered node positions (None when the result was resumed from the store).
    pub registered: Option<&'a [Vector3<f64>]>,
    /// The registered positions of the case's evaluation points (None when resumed or without points).
    pub registered_points: Option<&'a [Vector3<f64>]>,
}

/// The registered positions of `case`'s evaluation points from a method's output: its own reading when it
/// gave one, else the P1 interpolation of its nodes (None without points).
pub fn registered_points(case: &BenchmarkCase, out: &MethodOutput) -> Option<Vec<Vector3<f64>>> {
    let p = case.points.as_ref()?;
    Some(match &out.points {
        Some(x) => x.clone(),
        None => p.p1(&out.nodes, &case.tets),
    })
}

/// Progress callback of [`run_protocol`].
pub type Progress<'a> = dyn FnMut(&RunEvent) + 'a;

/// Run every (case, method, column, seed) not yet in `store`, saving each result as soon as it is scored;
/// returns all results in loop order. A method's error stops the protocol with the run named (a table
/// silently missing cells is worse); the runs before it stay stored.
pub fn run_protocol(
    cases: &[BenchmarkCase],
    methods: &[&dyn Method],
    columns: &[Column],
    n_seeds: usize,
    store: &ResultStore,
    progress: &mut Progress,
) -> Result<Vec<RunResult>> {
    let mut jobs = Vec::new();
    for case in cases {
        case.validate()?;
        let fingerprint = case.fingerprint();
        for c in columns {
            for seed in c.seeds(n_seeds) {
                for m in methods.iter().filter(|m| m.applies_to(case) && (seed == 0 || m.uses_landmarks())) {
                    jobs.push((case, fingerprint.clone(), *m, *c, seed));
                }
            }
        }
    }
    let total = jobs.len();
    let mut results = Vec::with_capacity(total);
    for (done, (case, fingerprint, m, column, seed)) in jobs.into_iter().enumerate() {
        let key = RunKey { scenario: case.scenario.clone(), method: m.name(), column, seed };
        let provenance = Provenance { case: fingerprint, settings: m.settings() };
        if let Some(r) = store.load(&key, &provenance)? {
            progress(&RunEvent { done: done + 1, total, case, result: &r, registered: None, registered_points: None });
            results.push(r);
            continue;
        }
        let lm = column_landmarks(case, &column, seed)?;
        let t0 = std::time::Instant::now();
        let out = m.register(case, &lm).map_err(|e| {
            RegisterError::bad(
                format!("{} / {} / {} seed {}", key.scenario, key.method, column.key(), seed),
                e.to_string(),
            )
        })?;
        let mut r = score(case, &lm, &out, key.clone(), provenance, t0.elapsed().as_secs_f64())?;
        r.floor = m.floor();
        store.save(&r)?;
        let pts = registered_points(case, &out);
        progress(&RunEvent {
            done: done + 1,
            total,
            case,
            result: &r,
            registered: Some(&out.nodes),
            registered_points: pts.as_deref(),
        });
        results.push(r);
    }
    Ok(results)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A slab of two tetrahedra per side whose crack nodes are duplicated; the ground truth opens the crack.
    pub(crate) fn toy_case() -> BenchmarkCase {
        // nodes 0..4 base (shared), 4/5 = the crack node pair at x=0 (sides 1 and 2), 6 apex
        let rest = vec![
            Vector3::new(-10.0, 0.0, 0.0),
            Vector3::new(10.0, 0.0, 0.0),
            Vector3::new(0.0, 10.0, 0.0),
            Vector3::new(0.0, -10.0, 0.0),
            Vector3::new(0.0, 0.0, 10.0),
            Vector3::new(0.0, 0.0, 10.0),
            Vector3::new(0.0, 0.0, -10.0),
        ];
        let tets = vec![[0, 2, 3, 4], [1, 3, 2, 5], [0, 3, 2, 6], [1, 2, 3, 6]];
        let mut gt = rest.clone();
        gt[4] += Vector3::new(-3.0, 0.0, 0.0);
        gt[5] += Vector3::new(4.0, 0.0, 0.0);
        BenchmarkCase {
            scenario: "toy".into(),
            surface: vec![[0, 2, 4], [1, 5, 2]],
            node_side: vec![0, 0, 0, 0, 1, 2, 0],
            original_node: vec![0, 1, 2, 3, 4, 4, 5],
            ground_truth: gt,
            lips: [vec![2, 4, 3], vec![2, 5, 3]],
            fixed: vec![6],
            roi: None,
            rest,
            tets,
            ground_truth_p2: None,
            points: None,
        }
    }

    struct Identity;
    impl Method for Identity {
        fn name(&self) -> String {
            "identity".into()
        }
        fn settings(&self) -> String {
            String::new()
        }
        fn register(&self, case: &BenchmarkCase, _: &[LandmarkSet]) -> Result<MethodOutput> {
            Ok(MethodOutput {
                nodes: case.rest.clone(),
                landmark_distance_mm: 0.0,
                notes: vec![],
                points: None,
                energy: None,
            })
        }
    }
    struct Oracle;
    impl Method for Oracle {
        fn name(&self) -> String {
            "oracle".into()
        }
        fn settings(&self) -> String {
            String::new()
        }
        fn register(&self, case: &BenchmarkCase, _: &[LandmarkSet]) -> Result<MethodOutput> {
            Ok(MethodOutput {
                nodes: case.ground_truth.clone(),
                landmark_distance_mm: 0.0,
                notes: vec![],
                points: None,
                energy: None,
            })
        }
    }

    #[test]
    fn landmarks_by_arc_length_by_hand() {
        let c = toy_case();
        c.validate().unwrap();
        let lm = c.lip_landmarks(6).unwrap();
        assert_eq!(lm.len(), 2);
        // lip 1: (0,10,0) → (0,0,10) → (0,-10,0), length L; 3 points at L/6, L/2 (the crack node), 5L/6
        assert!((lm[0].sources[1] - Vector3::new(0.0, 0.0, 10.0)).norm() < 1e-12);
        assert!((lm[0].targets[1] - Vector3::new(-3.0, 0.0, 10.0)).norm() < 1e-12);
        assert!((lm[1].targets[1] - Vector3::new(4.0, 0.0, 10.0)).norm() < 1e-12);
        let first = Vector3::new(0.0, 10.0, 0.0) * (2.0 / 3.0) + Vector3::new(0.0, 0.0, 10.0) * (1.0 / 3.0);
        assert!((lm[0].sources[0] - first).norm() < 1e-12);
        assert!(c.lip_landmarks(5).is_err());
        let lm = c.lip_landmarks(8).unwrap(); // 4 per lip: the second at 3L/8, ¾ along the first segment
        let expect = Vector3::new(0.0, 10.0, 0.0) * 0.25 + Vector3::new(0.0, 0.0, 10.0) * 0.75;
        assert!((lm[0].sources[1] - expect).norm() < 1e-12);
    }

    #[test]
    fn identity_scores_the_ground_truth_displacement_and_the_oracle_zero() {
        let c = toy_case();
        let dir = tempfile::tempdir().unwrap();
        let store = ResultStore::new(dir.path());
        let cols = [Column { landmarks: 4, noise_sigma_mm: 0.0 }, Column { landmarks: 4, noise_sigma_mm: 1.0 }];
        let mut seen = Vec::new();
        let r = run_protocol(std::slice::from_ref(&c), &[&Identity, &Oracle], &cols, 2, &store, &mut |e| {
            seen.push((e.done, e.total, e.result.key.method.clone(), e.registered.is_none()))
        })
        .unwrap();
        assert_eq!(r.len(), 2 + 2 * 2);
        let id = &r[0];
        assert_eq!(id.key.method, "identity");
        // node errors: 3 and 4 at the crack pair, 0 elsewhere (7 nodes)
        assert!((id.tre_volume.mean - 1.0).abs() < 1e-12);
        assert_eq!(id.tre_volume.max, 4.0);
        assert_eq!(id.max_gt_displacement_mm, 4.0);
        assert_eq!(r[1].tre_volume.max, 0.0);
        // 2 landmarks per lip sit mid-segment at (0, ±5, 5): nodes 2, 3 and the crack pair are √50 ≈ 7.1 mm from
        // them (5–10 mm bin, errors 0, 0, 3, 4); the base nodes 0, 1, 6 are 12.2–15.8 mm away (10–20 mm, error 0)
        assert_eq!(id.bins[0].stats.n, 0);
        assert_eq!((id.bins[1].stats.n, id.bins[1].stats.max), (4, 4.0));
        assert_eq!((id.bins[2].stats.n, id.bins[2].stats.max), (3, 0.0));
        // resumed on a second call
        let mut resumed = 0;
        run_protocol(std::slice::from_ref(&c), &[&Identity, &Oracle], &cols, 2, &store, &mut |e| {
            resumed += e.registered.is_none() as usize
        })
        .unwrap();
        assert_eq!(resumed, 6);
        assert!(seen.iter().all(|s| !s.3) && seen.len() == 6 && seen[5].0 == 6);
        // another ground truth (one node moved by 1e-9 mm) is another case: its stored runs are not reused
        let mut other = c.clone();
        other.ground_truth[6].x += 1e-9;
        assert_ne!(other.fingerprint(), c.fingerprint());
        assert_eq!(c.clone().fingerprint(), c.fingerprint());
        let e = run_protocol(&[other], &[&Identity], &cols, 2, &store, &mut |_| {}).unwrap_err().to_string();
        assert!(e.contains("another case") && e.contains("identity"), "{e}");
    }

    #[test]
    fn the_uncut_mesh_merges_crack_copies() {
        let c = toy_case();
        let (n, t, map) = c.uncut();
        assert_eq!(n.len(), 6);
        assert_eq!(map, vec![0, 1, 2, 3, 4, 4, 5]);
        assert_eq!(t[1], [1, 3, 2, 4]);
    }

    #[test]
    fn noisy_columns_perturb_targets_only() {
        let c = toy_case();
        let a = column_landmarks(&c, &Column { landmarks: 6, noise_sigma_mm: 2.0 }, 1).unwrap();
        let b = column_landmarks(&c, &Column { landmarks: 6, noise_sigma_mm: 0.0 }, 1).unwrap();
        assert_eq!(a[0].sources, b[0].sources);
        assert_ne!(a[0].targets, b[0].targets);
        assert_eq!(
            a[0].targets,
            column_landmarks(&c, &Column { landmarks: 6, noise_sigma_mm: 2.0 }, 1).unwrap()[0].targets
        );
    }
}
