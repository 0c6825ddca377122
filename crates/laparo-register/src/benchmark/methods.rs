//! The mesh-based baselines as benchmark [`Method`]s. ARAP, DRBC and LDDMM do not know the incision: they
//! deform the **uncut** mesh (the two copies of each crack node merged), as a surgeon's preoperative model
//! would be, and every cut node takes the position of its uncut node. François et al. [2021] cut the source
//! mesh along the surface swept from the source lip polylines to an assumed depth (the true depth is not
//! known intraoperatively) and run DRBC on that cut mesh. All methods get the same landmarks, the same
//! eq. 5.10 distances (each lip against its own target polyline) and the same fixed posterior nodes as the
//! ground truth; with `hold_outside_roi`, also RODS-MPM's region of interest (nodes outside it at rest).
use super::case::{BenchmarkCase, LandmarkSet, Method, MethodOutput};
use crate::baselines::{
    arap, drbc, lddmm, ArapConfig, BaselineProblem, DrbcConfig, LddmmConfig, MaterialPoint, MeshLandmarkGroup,
};
use crate::distance::Polyline;
use crate::error::{RegisterError, Result};
use crate::loss::GroupTarget;
use laparo_core::mesh::TetMesh;
use laparo_fem::mesh::incision::{cut, Blade};
use nalgebra::Vector3;
use std::sync::Arc;

/// Which baseline.
#[derive(Clone, Debug)]
pub enum Baseline {
    /// Volumetric ARAP.
    Arap(ArapConfig),
    /// DRBC: landmarks + Neo-Hookean regularisation.
    Drbc(DrbcConfig),
    /// Landmark LDDMM (geodesic shooting, Gaussian kernel).
    Lddmm(LddmmConfig),
    /// François et al.: cut along the source lips to `assumed_depth_mm`, then DRBC.
    Francois {
        /// DRBC settings.
        drbc: DrbcConfig,
        /// Depth of the assumed cut (mm) below the lip polyline.
        assumed_depth_mm: f64,
        /// Which way the assumed cut leaves the lip.
        direction: CutDirection,
    },
}

/// Which way an assumed cut leaves the source lip polyline.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CutDirection {
    /// Along the uncut surface's inward normal.
    #[default]
    SurfaceNormal,
    /// Inward in the plane the lips open across: the inward normal with its components along the mean
    /// separation of the two target lips and along the lip removed (the targets are every method's input).
    LipSeparation,
}

/// A baseline with a display name (e.g. `LDDMM` or `LDDMM σ 30` in a width sweep).
#[derive(Clone, Debug)]
pub struct BaselineMethod {
    /// Name in the tables.
    pub name: String,
    /// The method and its settings.
    pub baseline: Baseline,
    /// Hold the nodes outside the case's region of interest at rest, as RODS-MPM does (`--methods
    /// arap-roi,drbc-roi,francois-roi`): the same information about where the tissue does not move.
    pub hold_outside_roi: bool,
}

fn groups_for(landmarks: &[LandmarkSet], node_map: &dyn Fn(usize, u8) -> usize) -> Vec<MeshLandmarkGroup> {
    landmarks
        .iter()
        .map(|l| MeshLandmarkGroup {
            name: l.name.clone(),
            points: l
                .points
                .iter()
                .map(|p| {
                    MaterialPoint::combination(
                        &p.nodes.iter().map(|&(i, w)| (node_map(i, l.side), w)).collect::<Vec<_>>(),
                    )
                })
                .collect(),
            target: GroupTarget::Shared(Arc::new(Polyline::open(l.targets.clone()))),
            weight: 1.0,
        })
        .collect()
}

fn run(b: &Baseline, problem: &BaselineProblem) -> Result<crate::baselines::BaselineResult> {
    match b {
        Baseline::Arap(c) => arap(problem, c),
        Baseline::Drbc(c) | Baseline::Francois { drbc: c, .. } => drbc(problem, c),
        Baseline::Lddmm(c) => lddmm(problem, c),
    }
}

/// For every node of the case's cut mesh, a (tetrahedron, corner) that holds it: meshes derived from the same
/// uncut tetrahedra in the same order hold "the same" node copy at the same corner.
fn corners(case: &BenchmarkCase) -> Vec<(usize, usize)> {
    let mut c = vec![(usize::MAX, 0); case.rest.len()];
    for (t, tet) in case.tets.iter().enumerate() {
        for (k, &i) in tet.iter().enumerate() {
            if c[i].0 == usize::MAX {
                c[i] = (t, k);
            }
        }
    }
    c
}

/// The cut a method may assume (François et al., and RODS-MPM's two-field grid): the blade is the first
/// lip's source polyline, swept inward (`direction`) to `depth_mm` (the true depth is not known
/// intraoperatively). The result's tetrahedra are the uncut mesh's, in the same order.
pub fn assumed_cut(
    uncut: &TetMesh,
    landmarks: &[LandmarkSet],
    depth_mm: f64,
    direction: CutDirection,
) -> Result<laparo_fem::mesh::incision::CutMesh> {
    if !(depth_mm > 0.0 && depth_mm.is_finite()) {
        return Err(RegisterError::param("assumed cut depth (mm)", depth_mm, "must be finite and > 0"));
    }
    let mouth: Vec<Vector3<f64>> = landmarks.first().map(|l| l.sources.clone()).unwrap_or_default();
    let normals = crate::crack::outward_normals(&uncut.boundary(), &mouth, 10.0);
    let mut directions: Vec<Vector3<f64>> = normals.iter().map(|n| -n).collect();
    if direction == CutDirection::LipSeparation {
        let mean = |v: &[Vector3<f64>]| v.iter().sum::<Vector3<f64>>() / v.len().max(1) as f64;
        let [a, b] = match landmarks {
            [a, b, ..] if !a.targets.is_empty() && !b.targets.is_empty() => [a, b],
            _ => return Err(RegisterError::bad("assumed cut", "the lip-separation direction needs two target lips")),
        };
        let sep = (mean(&b.targets) - mean(&a.targets)).try_normalize(1e-9).ok_or_else(|| {
            RegisterError::bad("assumed cut", "the two target lips coincide: no separation direction")
        })?;
        let n = mouth.len();
        for k in 0..n {
            let t = (mouth[(k + 1).min(n - 1)] - mouth[k.saturating_sub(1)]).try_normalize(1e-12);
            let mut d = directions[k] - sep * directions[k].dot(&sep);
            if let Some(t) = t {
                d -= t * d.dot(&t);
            }
            if let Some(d) = d.try_normalize(1e-6) {
                directions[k] = d;
            }
        }
    }
    let blade = Blade { depths: vec![depth_mm; mouth.len()], mouth, directions, overshoot_mm: 5.0 };
    cut(uncut, &blade).map_err(|e| RegisterError::bad("assumed cut of the source mesh", e.to_string()))
}

impl Method for BaselineMethod {
    fn name(&self) -> String {
        self.name.clone()
    }
    fn settings(&self) -> String {
        if self.hold_outside_roi {
            format!("{:?}, nodes outside the region of interest held at rest", self.baseline)
        } else {
            format!("{:?}", self.baseline)
        }
    }

    fn applies_to(&self, case: &BenchmarkCase) -> bool {
        !self.hold_outside_roi || case.roi.is_some()
    }

    fn register(&self, case: &BenchmarkCase, landmarks: &[LandmarkSet]) -> Result<MethodOutput> {
        let (nodes, tets, map) = case.uncut();
        let uncut = TetMesh { vertices: nodes, tets };
        let mut notes = Vec::new();
        let (mesh, to_case): (TetMesh, Vec<usize>) = match &self.baseline {
            Baseline::Francois { assumed_depth_mm, direction, .. } => {
                let f = assumed_cut(&uncut, landmarks, *assumed_depth_mm, *direction)?;
                // case node i sits at corner (t, k): François' copy is f.mesh.tets[t][k]
                let to_case = corners(case).iter().map(|&(t, k)| f.mesh.tets[t][k]).collect();
                notes.push(format!(
                    "assumed cut: {} crack faces per lip, depth {assumed_depth_mm} mm",
                    f.crack_faces[0].len()
                ));
                (f.mesh, to_case)
            }
            _ => (uncut, map.clone()),
        };
        // landmark material points: case node → method node (its own side's copy where the method has one)
        let node_map = |i: usize, _side: u8| to_case[i];
        let mut problem = BaselineProblem::new(mesh, groups_for(landmarks, &node_map));
        let fixed: Vec<usize> = {
            let mut f: Vec<usize> = case.fixed.iter().map(|&i| to_case[i]).collect();
            if self.hold_outside_roi {
                let roi = case.roi.as_ref().ok_or_else(|| {
                    RegisterError::bad(
                        &self.name,
                        "holds the nodes outside the region of interest, but this case has none (whole organ)",
                    )
                })?;
                let outside: Vec<usize> = (0..case.rest.len()).filter(|&i| !roi.inside(&case.rest[i])).collect();
                notes.push(format!("{} nodes outside the region of interest held at rest", outside.len()));
                f.extend(outside.iter().map(|&i| to_case[i]));
            }
            f.sort_unstable();
            f.dedup();
            f
        };
        problem.fix_at_rest(&fixed);
        let r = run(&self.baseline, &problem)?;
        if !r.report.converged {
            notes.push(format!(
                "{} stopped after {} iterations without meeting its tolerance",
                self.name, r.report.iterations
            ));
        }
        Ok(MethodOutput {
            nodes: to_case.iter().map(|&j| r.positions[j]).collect(),
            landmark_distance_mm: r.report.mean_distance_mm,
            notes,
            points: None,
            energy: None,
        })
    }
    fn floor(&self) -> Option<String> {
        Some(P1_FLOOR_NAME.into())
    }
}

/// The floor row of every mesh method: the name in the tables.
pub const P1_FLOOR_NAME: &str = "floor: P1 mesh (u_GT at the nodes)";

/// The representation floor of the mesh methods: the ground truth at the mesh's nodes, read at the evaluation
/// points by the same P1 interpolation every mesh method is read by (what a perfect mesh registration scores
/// against the TET10 field). Reads the ground truth: a diagnostic row, not a method.
#[derive(Clone, Copy, Debug)]
pub struct P1Floor;

impl Method for P1Floor {
    fn name(&self) -> String {
        P1_FLOOR_NAME.into()
    }
    fn settings(&self) -> String {
        "P1 interpolation of the nodal ground truth".into()
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
    fn uses_landmarks(&self) -> bool {
        false
    }
}

/// The reference row: no registration (the rest mesh), whose TRE is the ground-truth displacement itself.
#[derive(Clone, Copy, Debug)]
pub struct NoRegistration;

impl Method for NoRegistration {
    fn name(&self) -> String {
        "none (rest)".into()
    }
    fn settings(&self) -> String {
        String::new()
    }
    fn register(&self, case: &BenchmarkCase, landmarks: &[LandmarkSet]) -> Result<MethodOutput> {
        let (mut sum, mut n) = (0.0, 0usize);
        for l in landmarks {
            let poly = Polyline::open(l.targets.clone());
            for s in &l.sources {
                sum += (s - crate::distance::ClosestPoint::closest(&poly, s).0).norm();
                n += 1;
            }
        }
        // "none" is read at the points as what it is: the rest positions themselves
        let points = case.points.as_ref().map(|p| p.rest.clone());
        Ok(MethodOutput {
            nodes: case.rest.clone(),
            landmark_distance_mm: sum / n.max(1) as f64,
            notes: vec![],
            points,
            energy: None,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::baselines::box_tet_mesh;
    use crate::organ::Roi;

    /// A 40 × 40 × 20 mm box (no crack), its bottom fixed, three top nodes near the centre pulled up 3 mm.
    fn pulled_box(roi: Option<Roi>) -> (BenchmarkCase, Vec<LandmarkSet>) {
        let m = box_tet_mesh([8, 8, 4], 5.0, Vector3::zeros());
        let n = m.vertices.len();
        let fixed: Vec<usize> = (0..n).filter(|&i| m.vertices[i].z == 0.0).collect();
        let top = |x: f64, y: f64| {
            (0..n).find(|&i| (m.vertices[i] - Vector3::new(x, y, 20.0)).norm() < 1e-9).expect("a lattice node")
        };
        let picked = [top(15.0, 20.0), top(20.0, 20.0), top(25.0, 20.0)];
        let lm = LandmarkSet {
            name: "lip 1".into(),
            side: 0,
            points: picked.iter().map(|&i| MaterialPoint::node(i)).collect(),
            sources: picked.iter().map(|&i| m.vertices[i]).collect(),
            targets: picked.iter().map(|&i| m.vertices[i] + Vector3::new(0.0, 0.0, 3.0)).collect(),
        };
        let case = BenchmarkCase {
            scenario: "box".into(),
            surface: vec![],
            node_side: vec![0; n],
            original_node: (0..n).collect(),
            ground_truth: m.vertices.clone(),
            lips: [vec![], vec![]],
            fixed,
            roi,
            rest: m.vertices.clone(),
            tets: m.tets.clone(),
            ground_truth_p2: None,
            points: None,
        };
        (case, vec![lm])
    }

    #[test]
    fn roi_variant_holds_every_node_outside_the_ball_at_rest() {
        let ball = Roi::Ball { center: [20.0, 20.0, 20.0], radius_mm: 12.0 };
        let (case, lms) = pulled_box(Some(ball));
        let method = |hold| BaselineMethod {
            name: "ARAP".into(),
            baseline: Baseline::Arap(ArapConfig::default()),
            hold_outside_roi: hold,
        };
        let free = method(false).register(&case, &lms).unwrap();
        let held = method(true).register(&case, &lms).unwrap();
        let outside: Vec<usize> = (0..case.rest.len()).filter(|&i| !ball.inside(&case.rest[i])).collect();
        let moved =
            |out: &MethodOutput| outside.iter().map(|&i| (out.nodes[i] - case.rest[i]).norm()).fold(0.0, f64::max);
        // without the ball ARAP moves tissue outside it; with it, not at all
        assert!(moved(&free) > 0.1, "free ARAP moved the outside by {} mm only", moved(&free));
        assert_eq!(moved(&held), 0.0);
        // the landmarks still move toward their targets inside the ball
        assert!(held.landmark_distance_mm < 0.5 * 3.0, "{}", held.landmark_distance_mm);
        assert!(held.notes.iter().any(|n| n.contains(&format!("{} nodes outside", outside.len()))), "{:?}", held.notes);
        // the two variants are different settings for the result store
        assert_ne!(method(false).settings(), method(true).settings());
        // a case without a region of interest: not run by the protocol, refused if called
        let (whole, lms) = pulled_box(None);
        assert!(method(true).applies_to(&case) && !method(true).applies_to(&whole) && method(false).applies_to(&whole));
        let e = method(true).register(&whole, &lms).unwrap_err().to_string();
        assert!(e.contains("ARAP") && e.contains("region of interest"), "{e}");
    }
}
