//! Build a benchmark case from a closed organ surface (thesis §5.4.2): tetrahedralise it, cut it (one of the
//! two scenarios of `laparo-fem`), open the incision in a quasi-static TET10 Neo-Hookean FEM (the ground
//! truth, never `laparo-mpm`) — equal and opposite pressures on the two crack faces ([`Loading::CrackPressure`],
//! the thesis' loading) or two grasper patches pulling the lips apart ([`Loading::Grasper`]), optionally with a
//! stiffer inclusion ([`Inclusion`]) — the load calibrated so that the mouth's opening ([`Calibration`])
//! reaches the scenario's target, and choose the region of interest RODS-MPM simulates so that the
//! ground-truth displacement on its boundary stays small.
use super::case::BenchmarkCase;
use crate::error::{RegisterError, Result};
use crate::organ::Roi;
use laparo_fem::material::NeoHookean;
use laparo_fem::mesh::incision::CutMesh;
use laparo_fem::mesh::scenario::Scenario;
use laparo_fem::solid::{FaceTraction, LoadPath, Loads, Quadrature, SolidProblem, Solution, SolverSettings, Tet10Mesh};
use nalgebra::Vector3;

/// The quantity the load calibration drives into [`GroundTruthConfig::target_gap_mm`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Calibration {
    /// The largest distance between the two deformed copies of one crack node ([`max_gap_mm`]): one node
    /// pair, so it moves with the mesh (the thesis' "lip gap"; the calibration before incision benchmark v2).
    MaxGap,
    /// The mean opening of the middle 80 % of the mouth ([`mean_mouth_opening_mm`]): an integral over the lip,
    /// converged under mesh refinement where the largest gap of one node pair is not.
    #[default]
    MeanMouthOpening,
}

impl Calibration {
    /// `max-gap` or `mean-mouth-opening` (as in the report and in JSON).
    pub fn name(self) -> &'static str {
        match self {
            Calibration::MaxGap => "max-gap",
            Calibration::MeanMouthOpening => "mean-mouth-opening",
        }
    }

    /// The calibrated quantity (mm) of the deformed cut mesh `deformed` (one position per cut-mesh node).
    pub fn measure_mm(self, cut: &CutMesh, deformed: &[Vector3<f64>]) -> Result<f64> {
        match self {
            Calibration::MaxGap => Ok(max_gap_mm(cut, deformed)),
            Calibration::MeanMouthOpening => mean_mouth_opening_mm(cut, deformed),
        }
    }
}

/// Default target of the mean mouth opening ([`mean_mouth_opening_mm`]), non-anatomical scenario (mm): the
/// mean-opening equivalent of the thesis' largest lip gap of 10–15 mm. Measured on the quick tier (P2ILF liver,
/// 16 mm tets, 8 increments, 1720 nodes): the max-gap calibration accepted 0.0288 kPa with a largest gap of
/// 14.97 mm and a mean opening of 7.39 mm (ratio 2.03), so a 10–15 mm gap is a 4.9–7.4 mm mean opening.
pub const NON_ANATOMICAL_MEAN_OPENING_MM: [f64; 2] = [5.0, 7.5];

/// Default target of the mean mouth opening, anatomical scenario (mm): the equivalent of the thesis' largest
/// lip gap of 20–30 mm. Measured on the P2ILF liver at 16 mm tets (8 increments): the max-gap calibration
/// accepted 0.1066 kPa with a largest gap of 23.40 mm and a mean opening of 13.09 mm (ratio 1.79), so 20–30 mm
/// is an 11.2–16.8 mm mean opening.
pub const ANATOMICAL_MEAN_OPENING_MM: [f64; 2] = [11.0, 17.0];

/// Grasper patch radius of [`Loading::grasper`] (mm): patches at most 20 mm across, a laparoscopic jaw.
pub const GRASPER_PATCH_RADIUS_MM: f64 = 10.0;

/// The forces that open the incision (dead loads, reference configuration).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Loading {
    /// Equal and opposite pressure on the two crack faces (`CutMesh::crack_pressure`, traction −p n: each face
    /// pushed into its own side), thesis §5.4.2.
    #[default]
    CrackPressure,
    /// Grasper retraction: on each lip, the outer-surface faces of that lip's side whose centroids lie within
    /// `patch_radius_mm` of the lip's mouth midpoint (by rest arc length) carry a uniform traction pulling away
    /// from the other lip ([`grasper_patches`]); no load on the crack faces.
    Grasper {
        /// Radius (mm) around the mouth midpoint holding the patch's face centroids.
        patch_radius_mm: f64,
    },
}

impl Loading {
    /// The grasper loading with the default 10 mm patch radius.
    pub fn grasper() -> Self {
        Loading::Grasper { patch_radius_mm: GRASPER_PATCH_RADIUS_MM }
    }

    /// `crack-pressure` or `grasper`.
    pub fn name(&self) -> &'static str {
        match self {
            Loading::CrackPressure => "crack-pressure",
            Loading::Grasper { .. } => "grasper",
        }
    }
}

/// A ball of stiffer tissue: every tetrahedron whose centroid lies inside it gets the Lamé constants × `stiffness_factor`
/// (`SolidProblem::with_element_scale`; ν unchanged).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Inclusion {
    /// Centre (mm).
    pub centre_mm: [f64; 3],
    /// Radius (mm).
    pub radius_mm: f64,
    /// Factor on E (both Lamé constants), > 0.
    pub stiffness_factor: f64,
}

impl Inclusion {
    /// The benchmark's material-mismatch control for `scn`: its tumour enlarged to radius max(2 r, 20 mm), 5 ×
    /// stiffer (tumours are stiffer than parenchyma); a scenario without a tumour (anatomical) gets a ball of
    /// radius 25 mm, 5 × stiffer, centred 30 mm from the lips' centroid on side A, along the bisector of side A's
    /// pull direction (away from the crack, [`crack_pull_direction`]) and the blade's mean direction (into the
    /// organ) — so inside the organ, not on its surface. Errors if that centre is outside every tetrahedron.
    pub fn control(scn: &Scenario) -> Result<Self> {
        if let Some(t) = &scn.tumour {
            return Ok(Inclusion {
                centre_mm: [t.centre.x, t.centre.y, t.centre.z],
                radius_mm: (2.0 * t.radius_mm).max(20.0),
                stiffness_factor: 5.0,
            });
        }
        let cut = &scn.cut;
        let x = &cut.mesh.vertices;
        let lip_nodes: Vec<usize> = cut.lips.iter().flatten().copied().collect();
        if lip_nodes.is_empty() {
            return Err(RegisterError::bad("inclusion", format!("{}: the cut has no lips", scn.name)));
        }
        let c = lip_nodes.iter().map(|&i| x[i]).sum::<Vector3<f64>>() / lip_nodes.len() as f64;
        let pull = crack_pull_direction(cut, 0, None)?;
        let inward = scn.blade.directions.iter().map(|d| d.normalize()).sum::<Vector3<f64>>();
        let dir = (pull + inward.normalize()).normalize();
        let centre = c + dir * 30.0;
        if !(dir.iter().all(|v| v.is_finite()) && contains_point(&cut.mesh, &centre)) {
            return Err(RegisterError::bad(
                "inclusion",
                format!(
                    "{}: the inclusion centre {centre:?} (30 mm from the lips into side A) is outside the organ",
                    scn.name
                ),
            ));
        }
        Ok(Inclusion { centre_mm: [centre.x, centre.y, centre.z], radius_mm: 25.0, stiffness_factor: 5.0 })
    }

    /// Stiffness factor per tetrahedron of `mesh` (`stiffness_factor` inside the ball, by centroid, else 1);
    /// errors name `radius_mm`, `stiffness_factor` or `centre_mm` when not finite and > 0.
    pub fn element_scale(&self, mesh: &laparo_core::mesh::TetMesh) -> Result<Vec<f64>> {
        if !(self.radius_mm.is_finite() && self.radius_mm > 0.0) {
            return Err(RegisterError::param("radius_mm", self.radius_mm, "inclusion radius must be finite and > 0"));
        }
        if !(self.stiffness_factor.is_finite() && self.stiffness_factor > 0.0) {
            return Err(RegisterError::param("stiffness_factor", self.stiffness_factor, "must be finite and > 0"));
        }
        if let Some(&c) = self.centre_mm.iter().find(|c| !c.is_finite()) {
            return Err(RegisterError::param("centre_mm", c, "must be finite"));
        }
        let centre = Vector3::from(self.centre_mm);
        let x = &mesh.vertices;
        Ok(mesh
            .tets
            .iter()
            .map(|t| {
                let g = (x[t[0]] + x[t[1]] + x[t[2]] + x[t[3]]) / 4.0;
                if (g - centre).norm() <= self.radius_mm {
                    self.stiffness_factor
                } else {
                    1.0
                }
            })
            .collect())
    }
}

/// Whether `p` lies in a tetrahedron of `mesh` (barycentric coordinates ≥ −1e-9).
fn contains_point(mesh: &laparo_core::mesh::TetMesh, p: &Vector3<f64>) -> bool {
    let x = &mesh.vertices;
    mesh.tets.iter().any(|t| {
        let m = nalgebra::Matrix3::from_columns(&[x[t[1]] - x[t[0]], x[t[2]] - x[t[0]], x[t[3]] - x[t[0]]]);
        m.try_inverse().is_some_and(|mi| {
            let l = mi * (p - x[t[0]]);
            l.iter().all(|&v| v >= -1e-9) && l.sum() <= 1.0 + 1e-9
        })
    })
}

/// The three ground truths of incision benchmark v2, per scenario (all Neo-Hookean E 4.1 kPa, ν 0.49).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum GroundTruthKind {
    /// Crack pressure (the thesis' loading).
    Pressure,
    /// Grasper retraction of the two lips ([`Loading::grasper`]).
    Grasper,
    /// Crack pressure on an organ holding a stiffer inclusion ([`Inclusion::control`]): a material the methods
    /// (homogeneous) do not model.
    StiffInclusion,
}

impl GroundTruthKind {
    /// All three, in this order.
    pub const ALL: [GroundTruthKind; 3] =
        [GroundTruthKind::Pressure, GroundTruthKind::Grasper, GroundTruthKind::StiffInclusion];

    /// `pressure`, `grasper` or `stiff-inclusion`.
    pub fn name(self) -> &'static str {
        match self {
            GroundTruthKind::Pressure => "pressure",
            GroundTruthKind::Grasper => "grasper",
            GroundTruthKind::StiffInclusion => "stiff-inclusion",
        }
    }
}

impl std::fmt::Display for GroundTruthKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for GroundTruthKind {
    type Err = RegisterError;
    fn from_str(s: &str) -> Result<Self> {
        GroundTruthKind::ALL.into_iter().find(|k| k.name() == s).ok_or_else(|| {
            RegisterError::bad("ground-truth kind", format!("{s:?}: use pressure, grasper or stiff-inclusion"))
        })
    }
}

/// How to make the ground truth.
#[derive(Clone, Debug, serde::Serialize)]
pub struct GroundTruthConfig {
    /// Young's modulus (kPa), thesis 4.1.
    pub youngs_modulus_kpa: f64,
    /// Poisson's ratio, thesis 0.49.
    pub poisson_ratio: f64,
    /// Range (mm) of the calibrated quantity ([`Self::calibration`]: the mean mouth opening, or the largest
    /// lip gap) the calibration stops inside, [lo, hi].
    pub target_gap_mm: [f64; 2],
    /// What the calibration measures.
    pub calibration: Calibration,
    /// The forces that open the incision.
    pub loading: Loading,
    /// A stiffer ball of tissue (none: homogeneous).
    pub inclusion: Option<Inclusion>,
    /// First load tried (kPa): the crack pressure, or the grasper traction's magnitude.
    pub initial_pressure_kpa: f64,
    /// Most FEM solves of the calibration.
    pub max_solves: usize,
    /// Load increments per solve.
    pub steps: usize,
    /// Newton tolerance, relative to the applied load.
    pub rel_tol: f64,
}

impl GroundTruthConfig {
    /// The crack-pressure ground truth of scenario `name`, calibrated on the mean mouth opening
    /// ([`Calibration::MeanMouthOpening`]) to [`NON_ANATOMICAL_MEAN_OPENING_MM`] or
    /// [`ANATOMICAL_MEAN_OPENING_MM`] (anatomical).
    pub fn for_scenario(name: &str) -> Self {
        let target_gap_mm =
            if name == "anatomical" { ANATOMICAL_MEAN_OPENING_MM } else { NON_ANATOMICAL_MEAN_OPENING_MM };
        GroundTruthConfig {
            youngs_modulus_kpa: 4.1,
            poisson_ratio: 0.49,
            target_gap_mm,
            calibration: Calibration::MeanMouthOpening,
            loading: Loading::CrackPressure,
            inclusion: None,
            initial_pressure_kpa: 0.05,
            max_solves: 6,
            steps: 20,
            rel_tol: 1e-8,
        }
    }

    /// register.md §4 as the thesis calibrates it: the largest lip gap ([`Calibration::MaxGap`]) in 10–15 mm
    /// (non-anatomical) or 20–30 mm (anatomical), crack pressure.
    pub fn max_gap_for_scenario(name: &str) -> Self {
        let target_gap_mm = if name == "anatomical" { [20.0, 30.0] } else { [10.0, 15.0] };
        GroundTruthConfig { target_gap_mm, calibration: Calibration::MaxGap, ..Self::for_scenario(name) }
    }

    /// One of the three ground truths of incision benchmark v2 for `scn` (its name picks the targets of
    /// [`Self::for_scenario`]): [`GroundTruthKind::Pressure`] is [`Self::for_scenario`];
    /// [`GroundTruthKind::Grasper`] the same with [`Loading::grasper`] (10 mm patches); and
    /// [`GroundTruthKind::StiffInclusion`] the crack pressure with [`Inclusion::control`]. The same
    /// calibration and target for all three: they open the incision alike and differ in how.
    pub fn control(scn: &Scenario, kind: GroundTruthKind) -> Result<Self> {
        let base = Self::for_scenario(&scn.name);
        Ok(match kind {
            GroundTruthKind::Pressure => base,
            GroundTruthKind::Grasper => {
                GroundTruthConfig { loading: Loading::grasper(), initial_pressure_kpa: 0.03, ..base }
            }
            GroundTruthKind::StiffInclusion => GroundTruthConfig { inclusion: Some(Inclusion::control(scn)?), ..base },
        })
    }
}

/// What the calibration did.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct GroundTruthReport {
    /// Load of the accepted solve (kPa): the pressure on each crack face, or the grasper traction's
    /// magnitude ([`GroundTruthReport::loading`]).
    pub pressure_kpa: f64,
    /// Largest distance between the two copies of a crack node (mm).
    pub max_gap_mm: f64,
    /// Mean opening of the middle 80 % of the mouth (mm), [`mean_mouth_opening_mm`] (0 in reports written
    /// before it was recorded).
    #[serde(default)]
    pub mean_mouth_opening_mm: f64,
    /// The calibrated quantity ([`Calibration::name`]; empty in reports written before it was recorded: `max-gap`).
    #[serde(default)]
    pub calibration_quantity: String,
    /// The loading ([`Loading::name`]; empty in reports written before it was recorded: `crack-pressure`).
    #[serde(default)]
    pub loading: String,
    /// Grasper loading: outer faces in the patch of lip A and lip B (0 for the crack pressure).
    #[serde(default)]
    pub grasper_patch_faces: [usize; 2],
    /// Tetrahedra inside the stiff inclusion (0 without one).
    #[serde(default)]
    pub inclusion_elements: usize,
    /// (load kPa, calibrated quantity mm) of every solve, in order (the quantity NaN for a failed solve).
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

/// Mean opening of the incision's mouth (mm): the opening along lip A — at each lip-A node, the distance
/// between its deformed position and its own copy on lip B (the crack-mouth opening displacement of that
/// material point, as in [`lip_opening_profile_mm`]; 0 at a node on both lips, the crack front, which cannot
/// open) — as a piecewise-linear function of rest arc length s along lip A, averaged over the middle 80 %
/// of the lip (s ∈ [0.1 L, 0.9 L], the integral by the trapezoidal rule over 0.8 L). Lip-A nodes with no copy
/// on lip B are bridged linearly. An integral of the opening profile, it converges under mesh refinement where
/// the largest gap of one node pair does not. Errors if lip A has zero length or fewer than 2 opening samples.
pub fn mean_mouth_opening_mm(cut: &CutMesh, deformed: &[Vector3<f64>]) -> Result<f64> {
    let lip = &cut.lips[0];
    let x = &cut.mesh.vertices;
    if lip.iter().chain(&cut.lips[1]).any(|&i| i >= x.len() || i >= deformed.len()) {
        return Err(RegisterError::bad("mouth opening", "a lip node is out of range of the mesh or the deformation"));
    }
    let on_b: std::collections::HashMap<usize, usize> =
        cut.lips[1].iter().map(|&i| (cut.original_node[i], i)).collect();
    let mut s = 0.0;
    let mut samples: Vec<(f64, f64)> = Vec::with_capacity(lip.len());
    for (k, &i) in lip.iter().enumerate() {
        if k > 0 {
            s += (x[i] - x[lip[k - 1]]).norm();
        }
        if let Some(&j) = on_b.get(&cut.original_node[i]) {
            samples.push((s, (deformed[i] - deformed[j]).norm()));
        }
    }
    let total = s;
    if !(total > 0.0) || samples.len() < 2 {
        return Err(RegisterError::bad(
            "mouth opening",
            format!("lip A is {total:.3} mm long with {} opening samples (need > 0 mm and ≥ 2)", samples.len()),
        ));
    }
    Ok(profile_mean(&samples, 0.1 * total, 0.9 * total))
}

/// Mean over [a, b] of the piecewise-linear function through `samples` (s, value) sorted by s, held
/// constant beyond its first and last sample.
fn profile_mean(samples: &[(f64, f64)], a: f64, b: f64) -> f64 {
    let value_at = |t: f64| -> f64 {
        let k = samples.partition_point(|p| p.0 <= t);
        if k == 0 {
            return samples[0].1;
        }
        if k == samples.len() {
            return samples[k - 1].1;
        }
        let ((s0, v0), (s1, v1)) = (samples[k - 1], samples[k]);
        if s1 > s0 {
            v0 + (v1 - v0) * (t - s0) / (s1 - s0)
        } else {
            v1
        }
    };
    // breakpoints: a, the sample positions inside (a, b), b; the function is linear between them
    let mut knots = vec![a];
    knots.extend(samples.iter().map(|p| p.0).filter(|&t| t > a && t < b));
    knots.push(b);
    let integral: f64 = knots.windows(2).map(|w| 0.5 * (w[1] - w[0]) * (value_at(w[0]) + value_at(w[1]))).sum();
    integral / (b - a)
}

/// The rest position (mm) halfway along lip `side` by arc length.
fn lip_midpoint(cut: &CutMesh, side: usize) -> Result<Vector3<f64>> {
    let p = cut.lip_positions(side, &cut.mesh.vertices);
    let total: f64 = p.windows(2).map(|w| (w[1] - w[0]).norm()).sum();
    if p.len() < 2 || !(total > 0.0) {
        return Err(RegisterError::bad(format!("lip {}", ["A", "B"][side]), "has fewer than 2 nodes or zero length"));
    }
    let mut walked = 0.0;
    for w in p.windows(2) {
        let l = (w[1] - w[0]).norm();
        if walked + l >= 0.5 * total && l > 0.0 {
            return Ok(w[0] + (w[1] - w[0]) * ((0.5 * total - walked) / l));
        }
        walked += l;
    }
    Ok(p[p.len() - 1])
}

/// Unit direction pulling side `side`'s tissue away from the other lip: minus the area-weighted mean outward
/// normal of that side's crack faces (each is wound outward from its own side's tetrahedron, i.e. towards the
/// other side) — the direction of the crack pressure on that side. With `near = Some((p, r))` only the faces
/// whose centroids lie within r of p count (all of them if none does): the local normal of a curved crack.
pub fn crack_pull_direction(cut: &CutMesh, side: usize, near: Option<(Vector3<f64>, f64)>) -> Result<Vector3<f64>> {
    let x = &cut.mesh.vertices;
    let faces = &cut.crack_faces[side.min(1)];
    let sum = |only_near: bool| -> Vector3<f64> {
        faces
            .iter()
            .filter(|f| !only_near || near.is_some_and(|(p, r)| ((x[f[0]] + x[f[1]] + x[f[2]]) / 3.0 - p).norm() <= r))
            .map(|f| (x[f[1]] - x[f[0]]).cross(&(x[f[2]] - x[f[0]])))
            .sum()
    };
    let mut n = sum(true);
    if !(n.norm() > 0.0) {
        n = sum(false);
    }
    if !(n.norm() > 0.0 && n.iter().all(|v| v.is_finite())) {
        return Err(RegisterError::bad(
            format!("crack side {}", ["A", "B"][side.min(1)]),
            "has no crack face of non-zero area: no pull direction",
        ));
    }
    Ok(-n.normalize())
}

/// The two grasper patches of [`Loading::Grasper`].
#[derive(Clone, Debug, PartialEq)]
pub struct GrasperPatches {
    /// Outer-surface faces (cut-mesh vertex ids, outward) of lip A's and lip B's patch.
    pub faces: [Vec<[usize; 3]>; 2],
    /// Unit pull direction of each patch ([`crack_pull_direction`] near the lip's mouth midpoint).
    pub pull: [Vector3<f64>; 2],
    /// Mouth midpoint of each lip by rest arc length (mm): the patch centre.
    pub centre_mm: [Vector3<f64>; 2],
}

/// Grasper patches of `cut` with radius `patch_radius_mm`: for each lip, the outer boundary faces of the cut
/// mesh (crack faces excluded) whose centroids lie within `patch_radius_mm` of the lip's mouth midpoint (by rest
/// arc length), on that lip's side, so each patch is at most 2 × `patch_radius_mm` across (by centroids). A
/// face is on a side when it has a vertex on that side's crack faces only (the lip's own duplicated nodes);
/// else when its centroid lies on that side of the plane through the mouth midpoint normal to the pull
/// direction. The pull of a patch is its side's [`crack_pull_direction`] over the crack faces within 2 ×
/// `patch_radius_mm` of the midpoint: away from the other lip, the direction the crack pressure pushes that
/// side (no component along the surface normal: a grasper pulling the lip sideways, tangent to the organ
/// near a mouth cut normal to the surface). Errors name `patch_radius_mm` when it is not finite and > 0 or
/// when a patch holds no face.
pub fn grasper_patches(cut: &CutMesh, patch_radius_mm: f64) -> Result<GrasperPatches> {
    let r = patch_radius_mm;
    if !(r.is_finite() && r > 0.0) {
        return Err(RegisterError::param("patch_radius_mm", r, "must be finite and > 0"));
    }
    let x = &cut.mesh.vertices;
    let sorted = |f: &[usize; 3]| {
        let mut k = *f;
        k.sort_unstable();
        k
    };
    let crack: std::collections::HashSet<[usize; 3]> = cut.crack_faces.iter().flatten().map(sorted).collect();
    let sides = node_sides(cut);
    let centre_mm = [lip_midpoint(cut, 0)?, lip_midpoint(cut, 1)?];
    let pull = [
        crack_pull_direction(cut, 0, Some((centre_mm[0], 2.0 * r)))?,
        crack_pull_direction(cut, 1, Some((centre_mm[1], 2.0 * r)))?,
    ];
    let mut faces: [Vec<[usize; 3]>; 2] = [Vec::new(), Vec::new()];
    for f in cut.mesh.boundary().faces {
        if crack.contains(&sorted(&f)) {
            continue;
        }
        let c = (x[f[0]] + x[f[1]] + x[f[2]]) / 3.0;
        let touches = |s: u8| f.iter().any(|&i| sides[i] == s);
        let side = match (touches(1), touches(2)) {
            (true, false) => 0,
            (false, true) => 1,
            (true, true) => continue,
            (false, false) => {
                if (c - centre_mm[0]).dot(&pull[0]) >= 0.0 {
                    0
                } else {
                    1
                }
            }
        };
        if (c - centre_mm[side]).norm() <= r {
            faces[side].push(f);
        }
    }
    for (k, name) in ["A", "B"].iter().enumerate() {
        if faces[k].is_empty() {
            return Err(RegisterError::param(
                "patch_radius_mm",
                r,
                format!(
                    "no outer face of lip {name}'s side has its centroid within {r} mm of the mouth midpoint {:?}:                      use a larger patch (or smaller tets)",
                    centre_mm[k]
                ),
            ));
        }
    }
    Ok(GrasperPatches { faces, pull, centre_mm })
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

/// The ground-truth displacement field: one displacement (mm) per node of the quadratic mesh
/// `Tet10Mesh::from_linear(&scn.cut.mesh)` — the cut mesh's vertices first (same order as
/// `scn.cut.mesh.vertices`), then the mid-edge nodes as that call numbers them (deterministic: by first use
/// in element order) — so `Tet10Mesh::interpolate` evaluates the FEM's own P2 field anywhere in the organ.
#[derive(Clone, Debug, PartialEq)]
pub struct GroundTruthField {
    /// Displacement of every TET10 node (mm).
    pub p2_displacement_mm: Vec<Vector3<f64>>,
}

impl GroundTruthField {
    /// The displacements of the first `n_vertices` nodes: the linear mesh's vertices (clamped to the field's length).
    pub fn vertex_displacement_mm(&self, n_vertices: usize) -> &[Vector3<f64>] {
        &self.p2_displacement_mm[..n_vertices.min(self.p2_displacement_mm.len())]
    }
}

/// What a ground-truth problem was built with, for the report.
struct ProblemParts {
    problem: SolidProblem,
    patch_faces: [usize; 2],
    inclusion_elements: usize,
}

/// The problem of `scn` under `cfg`'s loading at reference load `load_ref_kpa` (a load factor f is the load
/// f · `load_ref_kpa`), with `cfg`'s inclusion.
fn ground_truth_problem(
    scn: &Scenario,
    cfg: &GroundTruthConfig,
    material: NeoHookean,
    load_ref_kpa: f64,
) -> Result<ProblemParts> {
    let fem = |e: laparo_fem::FemError| RegisterError::bad(format!("FEM ground truth ({})", scn.name), e.to_string());
    let mesh = Tet10Mesh::from_linear(&scn.cut.mesh).map_err(fem)?;
    let dirichlet = SolidProblem::fixed_vertices(&mesh, &scn.fixed_nodes).map_err(fem)?;
    let (face_tractions, patch_faces) = match cfg.loading {
        Loading::CrackPressure => (scn.cut.crack_pressure(load_ref_kpa), [0, 0]),
        Loading::Grasper { patch_radius_mm } => {
            let g = grasper_patches(&scn.cut, patch_radius_mm)?;
            let t: Vec<FaceTraction> = (0..2)
                .flat_map(|k| g.faces[k].iter().map(move |&face| (face, k)))
                .map(|(face, k)| FaceTraction { face, traction_kpa: g.pull[k] * load_ref_kpa })
                .collect();
            (t, [g.faces[0].len(), g.faces[1].len()])
        }
    };
    let loads = Loads { face_tractions, ..Default::default() };
    let mut problem = SolidProblem::new(mesh, material, &dirichlet, &loads, Quadrature::Degree2).map_err(fem)?;
    let mut inclusion_elements = 0;
    if let Some(inc) = &cfg.inclusion {
        let scale = inc.element_scale(&scn.cut.mesh)?;
        inclusion_elements = scale.iter().filter(|&&f| f != 1.0).count();
        if inclusion_elements == 0 {
            return Err(RegisterError::param(
                "radius_mm",
                inc.radius_mm,
                format!("the inclusion at {:?} holds no tetrahedron centroid", inc.centre_mm),
            ));
        }
        problem = problem.with_element_scale(scale).map_err(fem)?;
    }
    Ok(ProblemParts { problem, patch_faces, inclusion_elements })
}

/// The ground truth of `scn`: vertex displacements of the cut mesh (mm) and the calibration report
/// ([`fem_ground_truth_field`] restricted to the linear mesh's vertices). `progress` sees (solve index,
/// load kPa, calibrated quantity mm) after each solve.
pub fn fem_ground_truth(
    scn: &Scenario,
    cfg: &GroundTruthConfig,
    progress: &mut dyn FnMut(usize, f64, f64),
) -> Result<(Vec<Vector3<f64>>, GroundTruthReport)> {
    let (field, report) = fem_ground_truth_field(scn, cfg, progress)?;
    let n = scn.cut.mesh.vertices.len();
    Ok((field.vertex_displacement_mm(n).to_vec(), report))
}

/// The ground truth of `scn` as the full quadratic field ([`GroundTruthField`]) and the calibration report.
/// The load of `cfg.loading` is scaled by secant steps on (load, [`GroundTruthConfig::calibration`] quantity)
/// until the quantity lies in `cfg.target_gap_mm`, all solves on one `laparo_fem::solid::LoadPath` (each from
/// the nearest lower equilibrium already reached); a solve that fails (inversion) steps back halfway towards
/// the last good load. `progress` sees (solve index, load kPa, calibrated quantity mm) after each solve.
pub fn fem_ground_truth_field(
    scn: &Scenario,
    cfg: &GroundTruthConfig,
    progress: &mut dyn FnMut(usize, f64, f64),
) -> Result<(GroundTruthField, GroundTruthReport)> {
    let material = NeoHookean::from_young_poisson(cfg.youngs_modulus_kpa, cfg.poisson_ratio)
        .map_err(|e| RegisterError::bad("ground-truth material", e.to_string()))?;
    let [lo, hi] = cfg.target_gap_mm;
    if !(lo > 0.0 && hi > lo && hi.is_finite()) {
        return Err(RegisterError::param("target_gap_mm", lo, "need finite 0 < lo < hi"));
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
    // already reached (the loads are load factors of the first).
    let fem = |e: laparo_fem::FemError| RegisterError::bad(format!("FEM ground truth ({})", scn.name), e.to_string());
    let parts = ground_truth_problem(scn, cfg, material, p)?;
    let problem = &parts.problem;
    let settings = SolverSettings { steps: cfg.steps, rel_tol: cfg.rel_tol, ..Default::default() };
    let mut path = LoadPath::new(problem, &settings).map_err(fem)?;
    let mut best: Option<(Solution, f64, f64)> = None;
    for k in 0..cfg.max_solves.max(1) {
        let sol = match path.solve_at(p / cfg.initial_pressure_kpa).map_err(fem) {
            Ok(s) => s,
            Err(_) if k > 0 => {
                // too much load (inversion): step back halfway towards the last good load
                let good = tried.iter().rev().find(|t| t[1].is_finite()).map(|t| t[0]).unwrap_or(0.0);
                tried.push([p, f64::NAN]);
                p = 0.5 * (p + good);
                continue;
            }
            Err(e) => return Err(e),
        };
        let def: Vec<Vector3<f64>> = x0.iter().zip(sol.vertex_displacements()).map(|(a, u)| a + u).collect();
        let q = cfg.calibration.measure_mm(&scn.cut, &def)?;
        tried.push([p, q]);
        progress(k, p, q);
        let done = q >= lo && q <= hi;
        best = Some((sol, p, q));
        if done {
            break;
        }
        // secant on the last two good solves (opening ∝ load at first), else proportional scaling
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
            p * (target / q.max(1e-6)).clamp(0.1, 20.0)
        };
    }
    let (sol, p, q) =
        best.ok_or_else(|| RegisterError::bad(format!("FEM ground truth ({})", scn.name), "no solve succeeded"))?;
    if !(q >= lo && q <= hi) {
        return Err(RegisterError::bad(
            format!("FEM ground truth ({})", scn.name),
            format!(
                "the {} reached {q:.2} mm, not target_gap_mm [{lo}, {hi}] mm, after {} solves ((load kPa, mm): {:?})",
                cfg.calibration.name(),
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
        max_gap_mm: max_gap_mm(&scn.cut, &deformed),
        mean_mouth_opening_mm: mean_mouth_opening_mm(&scn.cut, &deformed)?,
        calibration_quantity: cfg.calibration.name().to_string(),
        loading: cfg.loading.name().to_string(),
        grasper_patch_faces: parts.patch_faces,
        inclusion_elements: parts.inclusion_elements,
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
    Ok((GroundTruthField { p2_displacement_mm: sol.displacement }, report))
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
        ground_truth_p2: None,
        points: None,
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
