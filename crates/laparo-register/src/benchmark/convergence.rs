//! Mesh convergence of the incision benchmark's ground truth (issue 46, item 4): one scenario's FEM ground
//! truth on a coarse mesh A and a fine mesh B, compared at A's common evaluation points ([`EvalPoints`]).
//!
//! Each of A's points (rest position, incision side) is located in B's rest mesh **on its own side**: the
//! tetrahedron of B that contains it when that tetrahedron is of side 0 or of the point's side (a side-0
//! point takes any); else the nearest tetrahedron of a compatible side (side 0 or the point's), so a side-1
//! point is never read from a side-2 tetrahedron. B's TET10 field is then interpolated there
//! ([`ground_truth_at`]) with the point's unclamped barycentric weights in that tetrahedron: a point outside
//! it (outside B's surface by less than the tolerance, or across B's crack from its own side) reads that
//! element's quadratic field continued, so an affine or quadratic field is reproduced exactly and a smooth
//! one-sided field to second order in the distance (reported), where the element's closest point would be
//! first order.
//!
//! Crack-face points: A's crack faces lie on A's discretised crack, which differs from B's (both snap to the
//! same blade where the element quality allows, not everywhere). Such a point is read from B's own side's
//! nearest tetrahedron as above: where B's crack passes on the other side of it, the point sits in B's
//! other-side tissue and is read from its own side's field continued across B's crack instead (counted in
//! [`ConvergenceReport::points_read_off_side`], the largest such distance reported). Lattice points of
//! side 1 or 2 next to the crack are handled the same way.
//!
//! Points outside B by more than `outside_tolerance_mm` (the two meshes approximate the organ surface
//! differently) are skipped and counted. The displacement at a point is u = x_GT − X (deformed minus rest).
//! Every relative figure is normalised by the **fine** mesh B (the better estimate of the continuum field):
//! the relative RMS difference is RMS |u_B − u_A| / RMS |u_B|, and a "none" bin's relative difference is
//! |mean |u_B| − mean |u_A|| / mean |u_B| ("none"'s TRE at a point is |u| there).
use super::case::BenchmarkCase;
use super::points::{ground_truth_at, PointKind};
use super::rods::tet_sides;
use super::tre::DISTANCE_BIN_EDGES_MM;
use crate::baselines::TetLocator;
use crate::error::{RegisterError, Result};
use laparo_core::mesh::TetMesh;
use nalgebra::Vector3;
use rayon::prelude::*;

/// Default tolerance (mm) for a point of A outside B's rest mesh before it is skipped.
pub const DEFAULT_OUTSIDE_TOLERANCE_MM: f64 = 1.0;
/// The near-lip band (mm): points of A closer than this to A's source lip polylines.
pub const NEAR_LIP_MM: f64 = 10.0;
/// Acceptance: overall relative RMS difference at most 5 %.
pub const OVERALL_LIMIT: f64 = 0.05;
/// Acceptance: relative RMS difference within [`NEAR_LIP_MM`] of the lips at most 10 %.
pub const NEAR_LIP_LIMIT: f64 = 0.10;
/// Acceptance: "none"'s per-bin mean TRE agrees within 10 % between the meshes.
pub const NONE_BIN_LIMIT: f64 = 0.10;

/// How the comparison is made.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ConvergenceConfig {
    /// A point of A farther than this (mm) outside B's rest mesh is skipped (counted).
    pub outside_tolerance_mm: f64,
    /// The near-lip band (mm).
    pub near_lip_mm: f64,
}

impl Default for ConvergenceConfig {
    fn default() -> Self {
        ConvergenceConfig { outside_tolerance_mm: DEFAULT_OUTSIDE_TOLERANCE_MM, near_lip_mm: NEAR_LIP_MM }
    }
}

/// JSON has neither NaN nor infinity: a non-finite value is written as `null` and read back as NaN.
mod nan_as_null {
    use serde::{Deserialize, Deserializer, Serializer};
    pub fn serialize<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
        if v.is_finite() {
            s.serialize_f64(*v)
        } else {
            s.serialize_none()
        }
    }
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
    }
}

/// [`nan_as_null`] for a vector.
mod vec_nan_as_null {
    use serde::{Deserialize, Deserializer, Serialize, Serializer};
    pub fn serialize<S: Serializer>(v: &[f64], s: S) -> Result<S::Ok, S::Error> {
        v.iter().map(|x| x.is_finite().then_some(*x)).collect::<Vec<Option<f64>>>().serialize(s)
    }
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<f64>, D::Error> {
        Ok(Vec::<Option<f64>>::deserialize(d)?.into_iter().map(|x| x.unwrap_or(f64::NAN)).collect())
    }
}

/// The agreement of two meshes' ground truths of one scenario at the coarse mesh's evaluation points.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ConvergenceReport {
    /// The scenario (case name) of both cases.
    pub scenario: String,
    /// A's evaluation points.
    pub points_a: usize,
    /// Points compared (inside B up to the tolerance).
    pub points_compared: usize,
    /// Points skipped: outside B's rest mesh by more than `outside_tolerance_mm`.
    pub points_skipped: usize,
    /// The tolerance (mm) used.
    pub outside_tolerance_mm: f64,
    /// Compared points whose tetrahedron of B (the one containing them, or the nearest) is of the other side,
    /// read from their own side's nearest tetrahedron instead (mostly crack-face points where B's crack
    /// passes on the other side of A's).
    pub points_read_off_side: usize,
    /// Largest distance (mm) from such a point to its own side's tetrahedron of B (0 without one).
    pub max_off_side_distance_mm: f64,
    /// Compared crack-face points of A.
    pub crack_face_points: usize,
    /// RMS |u_B| over the compared points (mm): the fine mesh's displacement, the normaliser.
    pub rms_u_mm: f64,
    /// RMS |u_A| over the compared points (mm).
    pub rms_u_a_mm: f64,
    /// RMS |u_B − u_A| over the compared points (mm).
    pub rms_diff_mm: f64,
    /// Largest |u_B − u_A| (mm).
    pub max_diff_mm: f64,
    /// rms_diff_mm / rms_u_mm over every compared point.
    #[serde(with = "nan_as_null")]
    pub relative_rms: f64,
    /// The near-lip band (mm, by A's distance to its lip polylines).
    pub near_lip_mm: f64,
    /// Compared points within the band.
    pub points_near_lip: usize,
    /// RMS |u_B| within the band (mm).
    #[serde(with = "nan_as_null")]
    pub near_lip_rms_u_mm: f64,
    /// RMS |u_B − u_A| within the band (mm).
    #[serde(with = "nan_as_null")]
    pub near_lip_rms_diff_mm: f64,
    /// Relative RMS difference within the band (NaN without a point there).
    #[serde(with = "nan_as_null")]
    pub near_lip_relative_rms: f64,
    /// Relative RMS difference over the crack-face points only (NaN without one).
    #[serde(with = "nan_as_null")]
    pub crack_face_relative_rms: f64,
    /// Lower edges (mm) of the distance bins ([`DISTANCE_BIN_EDGES_MM`]; the last bin is open).
    pub bin_lo_mm: Vec<f64>,
    /// Compared points per bin.
    pub bin_counts: Vec<usize>,
    /// "none"'s mean TRE (mean |u_A|) per bin on mesh A (mm; NaN for an empty bin).
    #[serde(with = "vec_nan_as_null")]
    pub none_bins_a_mm: Vec<f64>,
    /// "none"'s mean TRE (mean |u_B|) per bin on mesh B at the same points (mm; NaN for an empty bin).
    #[serde(with = "vec_nan_as_null")]
    pub none_bins_b_mm: Vec<f64>,
    /// |b − a| / b per bin (NaN for an empty bin; 0 when both are 0).
    #[serde(with = "vec_nan_as_null")]
    pub none_bin_relative_diff: Vec<f64>,
    /// RMS |u_B − u_A| / RMS |u_B| per bin (NaN for an empty bin).
    #[serde(with = "vec_nan_as_null")]
    pub bin_relative_rms: Vec<f64>,
    /// relative_rms ≤ 5 %.
    pub passes_5pct: bool,
    /// near_lip_relative_rms ≤ 10 % (false without a near-lip point).
    pub passes_10pct_near: bool,
    /// Every non-empty bin's none_bin_relative_diff ≤ 10 % (false without a compared point).
    pub none_bins_within_10pct: bool,
}

/// Where a query was read in B.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SideLocation {
    /// B's tetrahedron and the query's barycentric weights in it (unclamped: negative outside it).
    pub element: (usize, [f64; 4]),
    /// Distance (mm) from the query to B's rest mesh (0 inside).
    pub outside_mm: f64,
    /// Whether the tetrahedron holding the query was of the other side (read from its own side's nearest).
    pub off_side: bool,
    /// Distance (mm) from the query to the tetrahedron read (0 inside it).
    pub element_distance_mm: f64,
}

/// Distance (mm) from `p` to tetrahedron `c` (0 inside) and the barycentric weights of its closest point; None
/// when degenerate.
fn closest_in_tet(c: &[Vector3<f64>; 4], p: &Vector3<f64>) -> Option<(f64, [f64; 4])> {
    crate::baselines::closest_point_in_tet(c, p).map(|(q, w)| ((q - p).norm(), w))
}

/// Locate `queries` (rest position mm, incision side) in `case`'s rest mesh on their own side (see the
/// module doc): None for a query outside the mesh by more than `outside_tolerance_mm`.
pub fn locate_on_side(
    case: &BenchmarkCase,
    queries: &[(Vector3<f64>, u8)],
    outside_tolerance_mm: f64,
) -> Result<Vec<Option<SideLocation>>> {
    if !(outside_tolerance_mm.is_finite() && outside_tolerance_mm >= 0.0) {
        return Err(RegisterError::param("outside_tolerance_mm", outside_tolerance_mm, "must be finite and >= 0"));
    }
    case.validate()?;
    if let Some((i, q)) = queries.iter().enumerate().find(|(_, q)| !q.0.iter().all(|c| c.is_finite()) || q.1 > 2) {
        return Err(RegisterError::bad(
            format!("benchmark case `{}`: query {i}", case.scenario),
            format!("position {:?} side {} (need finite coordinates and side 0, 1 or 2)", q.0.as_slice(), q.1),
        ));
    }
    let tside = tet_sides(&case.tets, &case.node_side);
    let full = TetMesh { vertices: case.rest.clone(), tets: case.tets.clone() };
    // per side s ∈ {1, 2}: the tetrahedra of side 0 or s, and their indices in the case
    let subs: Vec<(TetMesh, Vec<usize>)> = (1..=2u8)
        .map(|s| {
            let ids: Vec<usize> = (0..case.tets.len()).filter(|&t| tside[t] == 0 || tside[t] == s).collect();
            (TetMesh { vertices: case.rest.clone(), tets: ids.iter().map(|&t| case.tets[t]).collect() }, ids)
        })
        .collect();
    let loc_full = TetLocator::new(&full);
    let loc_side: Vec<TetLocator> = subs.iter().map(|(m, _)| TetLocator::new(m)).collect();
    let corners = |t: usize| case.tets[t].map(|i| case.rest[i]);
    let degenerate =
        |t: usize| RegisterError::bad(format!("benchmark case `{}`: tetrahedron {t}", case.scenario), "degenerate");
    queries
        .par_iter()
        .map(|&(p, side)| {
            let Some((e, w)) = loc_full.nearest_tet(&p) else {
                return Err(RegisterError::bad(format!("benchmark case `{}`", case.scenario), "no tetrahedron"));
            };
            let (outside_mm, _) = closest_in_tet(&corners(e), &p).ok_or_else(|| degenerate(e))?;
            if outside_mm > outside_tolerance_mm {
                return Ok(None);
            }
            if side == 0 || tside[e] == 0 || tside[e] == side {
                return Ok(Some(SideLocation {
                    element: (e, w),
                    outside_mm,
                    off_side: false,
                    element_distance_mm: outside_mm,
                }));
            }
            let k = usize::from(side - 1);
            let Some((se, sw)) = loc_side[k].nearest_tet(&p) else {
                return Err(RegisterError::bad(
                    format!("benchmark case `{}`", case.scenario),
                    format!("no tetrahedron of side 0 or {side}"),
                ));
            };
            let t = subs[k].1[se];
            let (d, _) = closest_in_tet(&corners(t), &p).ok_or_else(|| degenerate(t))?;
            Ok(Some(SideLocation { element: (t, sw), outside_mm, off_side: true, element_distance_mm: d }))
        })
        .collect()
}

/// RMS of the norms of `v` (NaN when empty).
fn rms(v: impl Iterator<Item = f64>) -> f64 {
    let (n, s) = v.fold((0usize, 0.0), |(n, s), x| (n + 1, s + x * x));
    if n == 0 {
        f64::NAN
    } else {
        (s / n as f64).sqrt()
    }
}

/// Compare the ground truth of the coarse case `a` and the fine case `b` (the same scenario) at `a`'s
/// evaluation points ([`BenchmarkCase::with_points`]), `b`'s field read on each point's own side (module doc).
pub fn compare_ground_truths(
    a: &BenchmarkCase,
    b: &BenchmarkCase,
    cfg: &ConvergenceConfig,
) -> Result<ConvergenceReport> {
    if !(cfg.near_lip_mm.is_finite() && cfg.near_lip_mm > 0.0) {
        return Err(RegisterError::param("near_lip_mm", cfg.near_lip_mm, "must be finite and > 0"));
    }
    if a.scenario != b.scenario {
        return Err(RegisterError::bad(
            "mesh-convergence cases",
            format!(
                "case A is scenario `{}` and case B `{}`: compare one scenario (and ground truth) on two meshes",
                a.scenario, b.scenario
            ),
        ));
    }
    a.validate()?;
    let pts = a.points.as_ref().ok_or_else(|| {
        RegisterError::bad(
            format!("mesh-convergence case A (`{}`): evaluation points", a.scenario),
            "none: build them with BenchmarkCase::with_points",
        )
    })?;
    let located = locate_on_side(b, &pts.queries(), cfg.outside_tolerance_mm)?;
    let idx: Vec<usize> = (0..pts.len()).filter(|&i| located[i].is_some()).collect();
    if idx.is_empty() {
        return Err(RegisterError::bad(
            format!("mesh-convergence case B (`{}`)", b.scenario),
            format!(
                "none of A's {} evaluation points lies within outside_tolerance_mm {} of B's mesh",
                pts.len(),
                cfg.outside_tolerance_mm
            ),
        ));
    }
    let loc: Vec<SideLocation> = idx.iter().filter_map(|&i| located[i]).collect();
    let elements: Vec<(usize, [f64; 4])> = loc.iter().map(|l| l.element).collect();
    let gt_b = ground_truth_at(b, &elements)?;
    // u_B = x_GT − X, X the rest position the weights give (the point itself, up to round-off)
    let u_b: Vec<Vector3<f64>> = elements
        .iter()
        .zip(&gt_b)
        .map(|((t, w), g)| g - b.tets[*t].iter().zip(w).map(|(&i, &w)| b.rest[i] * w).sum::<Vector3<f64>>())
        .collect();
    let u_a: Vec<Vector3<f64>> = idx.iter().map(|&i| pts.ground_truth[i] - pts.rest[i]).collect();
    let d_lip: Vec<f64> = idx.iter().map(|&i| pts.d_lip_mm[i]).collect();
    let diff: Vec<f64> = u_a.iter().zip(&u_b).map(|(a, b)| (b - a).norm()).collect();
    if let Some(k) = diff.iter().position(|d| !d.is_finite()) {
        return Err(RegisterError::bad(
            format!("mesh-convergence cases (`{}`)", a.scenario),
            format!("non-finite ground truth at A's evaluation point {}", idx[k]),
        ));
    }
    let sel_rms = |keep: &dyn Fn(usize) -> bool| -> (usize, f64, f64) {
        let k: Vec<usize> = (0..idx.len()).filter(|&j| keep(j)).collect();
        (k.len(), rms(k.iter().map(|&j| u_b[j].norm())), rms(k.iter().map(|&j| diff[j])))
    };
    let ratio = |num: f64, den: f64| if num == 0.0 && den == 0.0 { 0.0 } else { num / den };
    let (_, rms_u_mm, rms_diff_mm) = sel_rms(&|_| true);
    let relative_rms = ratio(rms_diff_mm, rms_u_mm);
    let (points_near_lip, near_lip_rms_u_mm, near_lip_rms_diff_mm) = sel_rms(&|j| d_lip[j] < cfg.near_lip_mm);
    let near_lip_relative_rms = ratio(near_lip_rms_diff_mm, near_lip_rms_u_mm);
    let (crack_face_points, cu, cd) = sel_rms(&|j| pts.kind[idx[j]] == PointKind::CrackFace);
    let edges = DISTANCE_BIN_EDGES_MM;
    let nb = edges.len() - 1;
    let (mut bin_counts, mut none_bins_a_mm, mut none_bins_b_mm) = (vec![0; nb], vec![0.0; nb], vec![0.0; nb]);
    let (mut none_bin_relative_diff, mut bin_relative_rms) = (vec![f64::NAN; nb], vec![f64::NAN; nb]);
    for k in 0..nb {
        let in_bin = |j: usize| d_lip[j] >= edges[k] && d_lip[j] < edges[k + 1];
        let (n, ru, rd) = sel_rms(&in_bin);
        bin_counts[k] = n;
        if n == 0 {
            none_bins_a_mm[k] = f64::NAN;
            none_bins_b_mm[k] = f64::NAN;
            continue;
        }
        let j: Vec<usize> = (0..idx.len()).filter(|&j| in_bin(j)).collect();
        none_bins_a_mm[k] = j.iter().map(|&j| u_a[j].norm()).sum::<f64>() / n as f64;
        none_bins_b_mm[k] = j.iter().map(|&j| u_b[j].norm()).sum::<f64>() / n as f64;
        none_bin_relative_diff[k] = ratio((none_bins_b_mm[k] - none_bins_a_mm[k]).abs(), none_bins_b_mm[k]);
        bin_relative_rms[k] = ratio(rd, ru);
    }
    let off: Vec<&SideLocation> = loc.iter().filter(|l| l.off_side).collect();
    Ok(ConvergenceReport {
        scenario: a.scenario.clone(),
        points_a: pts.len(),
        points_compared: idx.len(),
        points_skipped: pts.len() - idx.len(),
        outside_tolerance_mm: cfg.outside_tolerance_mm,
        points_read_off_side: off.len(),
        max_off_side_distance_mm: off.iter().map(|l| l.element_distance_mm).fold(0.0, f64::max),
        crack_face_points,
        rms_u_mm,
        rms_u_a_mm: rms(u_a.iter().map(|u| u.norm())),
        rms_diff_mm,
        max_diff_mm: diff.iter().copied().fold(0.0, f64::max),
        relative_rms,
        near_lip_mm: cfg.near_lip_mm,
        points_near_lip,
        near_lip_rms_u_mm,
        near_lip_rms_diff_mm,
        near_lip_relative_rms,
        crack_face_relative_rms: if crack_face_points == 0 { f64::NAN } else { ratio(cd, cu) },
        bin_lo_mm: edges[..nb].to_vec(),
        passes_5pct: relative_rms <= OVERALL_LIMIT,
        passes_10pct_near: near_lip_relative_rms <= NEAR_LIP_LIMIT,
        none_bins_within_10pct: bin_counts
            .iter()
            .zip(&none_bin_relative_diff)
            .all(|(&n, &r)| n == 0 || r <= NONE_BIN_LIMIT),
        bin_counts,
        none_bins_a_mm,
        none_bins_b_mm,
        none_bin_relative_diff,
        bin_relative_rms,
    })
}

impl ConvergenceReport {
    /// A markdown summary: the three acceptance figures and the per-bin table.
    pub fn markdown(&self) -> String {
        use std::fmt::Write;
        let pct = |x: f64| if x.is_finite() { format!("{:.2} %", 100.0 * x) } else { "–".into() };
        let mm = |x: f64| if x.is_finite() { format!("{x:.3}") } else { "–".into() };
        let ok = |b: bool| if b { "pass" } else { "FAIL" };
        let mut s = String::new();
        let _ = writeln!(s, "| figure | value | limit | |\n|---|---|---|---|");
        let _ = writeln!(
            s,
            "| RMS \\|u_B − u_A\\| / RMS \\|u_B\\|, all {} points | {} ({} / {} mm) | 5 % | {} |",
            self.points_compared,
            pct(self.relative_rms),
            mm(self.rms_diff_mm),
            mm(self.rms_u_mm),
            ok(self.passes_5pct)
        );
        let _ = writeln!(
            s,
            "| the same within {} mm of the lips, {} points | {} ({} / {} mm) | 10 % | {} |",
            self.near_lip_mm,
            self.points_near_lip,
            pct(self.near_lip_relative_rms),
            mm(self.near_lip_rms_diff_mm),
            mm(self.near_lip_rms_u_mm),
            ok(self.passes_10pct_near)
        );
        let worst = self.none_bin_relative_diff.iter().copied().filter(|x| x.is_finite()).fold(0.0, f64::max);
        let _ = writeln!(
            s,
            "| \"none\"'s per-bin TRE, largest relative difference | {} | 10 % | {} |",
            pct(worst),
            ok(self.none_bins_within_10pct)
        );
        let _ = writeln!(
            s,
            "\n{} of A's {} points compared, {} skipped (outside B by > {} mm); {} crack-face points (relative RMS {}); \
             {} read from their own side's nearest tetrahedron of B (up to {:.3} mm away); largest |u_B − u_A| {:.3} mm.\n",
            self.points_compared,
            self.points_a,
            self.points_skipped,
            self.outside_tolerance_mm,
            self.crack_face_points,
            pct(self.crack_face_relative_rms),
            self.points_read_off_side,
            self.max_off_side_distance_mm,
            self.max_diff_mm
        );
        let _ = writeln!(
            s,
            "| distance to the lips (mm) | points | none A (mm) | none B (mm) | \\|B − A\\| / B | RMS diff / RMS \\|u_B\\| |\n|---|---|---|---|---|---|"
        );
        for k in 0..self.bin_counts.len() {
            let hi = DISTANCE_BIN_EDGES_MM.get(k + 1).copied().unwrap_or(f64::INFINITY);
            let range = if hi.is_finite() {
                format!("{}–{}", self.bin_lo_mm[k], hi)
            } else {
                format!("> {}", self.bin_lo_mm[k])
            };
            let _ = writeln!(
                s,
                "| {range} | {} | {} | {} | {} | {} |",
                self.bin_counts[k],
                mm(self.none_bins_a_mm[k]),
                mm(self.none_bins_b_mm[k]),
                pct(self.none_bin_relative_diff[k]),
                pct(self.bin_relative_rms[k])
            );
        }
        s
    }
}
