//! Rigid initial alignment (§5.4.3 aligns the model rigidly first; App. A uses ICP): landmark
//! Procrustes (Umeyama 1991, optional scale), ICP point-to-point and point-to-plane with trimming for
//! partial overlap, RMSE; RANSAC floor plane and the vertical (gravity) projection of a structure onto
//! a surface (App. A).
use crate::distance::build_tree;
use crate::error::{RegisterError, Result};
use kiddo::SquaredEuclidean;
use nalgebra::{Matrix3, Matrix6, Rotation3, Vector3, Vector6};
use rand::{Rng, SeedableRng};

/// A similarity transform y = s R x + t (s = 1: rigid). Lengths in the input's units (mm).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Similarity {
    /// Rotation.
    pub rotation: Matrix3<f64>,
    /// Translation.
    pub translation: Vector3<f64>,
    /// Scale.
    pub scale: f64,
}

impl Similarity {
    /// Identity.
    pub fn identity() -> Self {
        Similarity { rotation: Matrix3::identity(), translation: Vector3::zeros(), scale: 1.0 }
    }
    /// Apply to a point.
    pub fn apply(&self, x: &Vector3<f64>) -> Vector3<f64> {
        self.rotation * x * self.scale + self.translation
    }
    /// self ∘ other (other first).
    pub fn compose(&self, other: &Similarity) -> Similarity {
        Similarity {
            rotation: self.rotation * other.rotation,
            translation: self.rotation * other.translation * self.scale + self.translation,
            scale: self.scale * other.scale,
        }
    }
}

/// Root-mean-square distance between paired points.
pub fn rmse(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> f64 {
    if a.is_empty() {
        return 0.0;
    }
    (a.iter().zip(b).map(|(x, y)| (x - y).norm_squared()).sum::<f64>() / a.len() as f64).sqrt()
}

/// Umeyama's least-squares similarity (or rigid, `with_scale = false`) from `src` to `dst` (paired).
pub fn umeyama(src: &[Vector3<f64>], dst: &[Vector3<f64>], with_scale: bool) -> Result<Similarity> {
    if src.len() != dst.len() {
        return Err(RegisterError::bad("landmarks", format!("{} source vs {} target points", src.len(), dst.len())));
    }
    if src.len() < 3 {
        return Err(RegisterError::bad("landmarks", format!("Procrustes needs >= 3 point pairs, got {}", src.len())));
    }
    let n = src.len() as f64;
    let ms = src.iter().sum::<Vector3<f64>>() / n;
    let md = dst.iter().sum::<Vector3<f64>>() / n;
    let mut cov = Matrix3::zeros();
    let mut var_s = 0.0;
    for (s, d) in src.iter().zip(dst) {
        cov += (d - md) * (s - ms).transpose();
        var_s += (s - ms).norm_squared();
    }
    cov /= n;
    var_s /= n;
    let svd = cov.svd(true, true);
    let (u, vt) = (svd.u.unwrap(), svd.v_t.unwrap());
    let mut sdiag = Vector3::new(1.0, 1.0, 1.0);
    if (u.determinant() * vt.determinant()) < 0.0 {
        sdiag[2] = -1.0;
    }
    let rotation = u * Matrix3::from_diagonal(&sdiag) * vt;
    // degenerate (collinear) configurations leave the rotation undetermined
    let sv = svd.singular_values;
    let mut sorted = [sv[0], sv[1], sv[2]];
    sorted.sort_by(|a, b| b.total_cmp(a));
    if sorted[1] <= 1e-12 * sorted[0].max(1e-300) {
        return Err(RegisterError::bad("landmarks", "the points are collinear: the rotation is undetermined"));
    }
    let scale = if with_scale { sv.dot(&sdiag) / var_s } else { 1.0 };
    Ok(Similarity { rotation, translation: md - rotation * ms * scale, scale })
}

/// ICP variant.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum IcpMode {
    /// Point-to-point (Besl & McKay), Umeyama per iteration.
    PointToPoint,
    /// Point-to-plane (Chen & Medioni), linearised rotation per iteration.
    PointToPlane,
}

/// ICP settings.
#[derive(Clone, Debug, serde::Serialize)]
pub struct IcpConfig {
    /// Variant.
    pub mode: IcpMode,
    /// Maximum iterations.
    pub iterations: usize,
    /// Fraction of the closest pairs kept (trimmed ICP, partial overlap); 1 = all.
    pub overlap: f64,
    /// Stop when the RMSE changes by less than this (mm).
    pub tolerance: f64,
}

impl Default for IcpConfig {
    fn default() -> Self {
        IcpConfig { mode: IcpMode::PointToPoint, iterations: 100, overlap: 1.0, tolerance: 1e-10 }
    }
}

/// ICP result.
#[derive(Clone, Debug, serde::Serialize)]
pub struct IcpResult {
    /// Source → target transform (including the initial one).
    pub transform: Similarity,
    /// RMSE of the kept pairs at the end (mm).
    pub rmse: f64,
    /// Iterations run.
    pub iterations: usize,
}

/// Iterative closest point from `src` to `dst` (with `dst_normals` for point-to-plane), starting at
/// `init`.
pub fn icp(
    src: &[Vector3<f64>],
    dst: &[Vector3<f64>],
    dst_normals: Option<&[Vector3<f64>]>,
    init: Similarity,
    cfg: &IcpConfig,
) -> Result<IcpResult> {
    icp_impl(src, dst, dst_normals, init, cfg, None).map(|(r, _)| r)
}

/// Fractional ICP (Phillips, Liu & Tomasi 2007): at every iteration the overlap is the fraction
/// `f ≥ min_overlap` of the closest pairs that minimises `RMSD_f / f^λ` ([`FRMSD_LAMBDA`]), then the
/// kept pairs are aligned; returns the result and the final overlap (`cfg.overlap` is ignored).
pub fn icp_fractional(
    src: &[Vector3<f64>],
    dst: &[Vector3<f64>],
    dst_normals: Option<&[Vector3<f64>]>,
    init: Similarity,
    cfg: &IcpConfig,
    min_overlap: f64,
) -> Result<(IcpResult, f64)> {
    if !(min_overlap > 0.0 && min_overlap <= 1.0) {
        return Err(RegisterError::param("min_overlap", min_overlap, "must be in (0, 1]"));
    }
    icp_impl(src, dst, dst_normals, init, &IcpConfig { overlap: 1.0, ..cfg.clone() }, Some(min_overlap))
}

/// The number of closest pairs (of `sorted_sq`, squared distances in increasing order) that minimises
/// the fractional RMSD, at least `min_keep`.
fn fractional_keep(sorted_sq: &[f64], min_keep: usize) -> usize {
    let n = sorted_sq.len();
    let mut sum = 0.0;
    let mut best = (f64::INFINITY, n);
    for (i, d) in sorted_sq.iter().enumerate() {
        sum += d;
        let k = i + 1;
        if k < min_keep {
            continue;
        }
        let f = k as f64 / n as f64;
        let score = (sum / k as f64).sqrt() / f.powf(FRMSD_LAMBDA);
        if score <= best.0 * (1.0 + 1e-12) {
            best = (score.min(best.0), k);
        }
    }
    best.1
}

fn icp_impl(
    src: &[Vector3<f64>],
    dst: &[Vector3<f64>],
    dst_normals: Option<&[Vector3<f64>]>,
    init: Similarity,
    cfg: &IcpConfig,
    fractional_min: Option<f64>,
) -> Result<(IcpResult, f64)> {
    if src.len() < 3 || dst.len() < 3 {
        return Err(RegisterError::bad(
            "ICP",
            format!("needs >= 3 points (source {}, target {})", src.len(), dst.len()),
        ));
    }
    if !(cfg.overlap > 0.0 && cfg.overlap <= 1.0) {
        return Err(RegisterError::param("overlap", cfg.overlap, "must be in (0, 1]"));
    }
    let normals = match (cfg.mode, dst_normals) {
        (IcpMode::PointToPlane, Some(n)) if n.len() == dst.len() => Some(n),
        (IcpMode::PointToPlane, _) => {
            return Err(RegisterError::bad("ICP", "point-to-plane needs one normal per target point"))
        }
        _ => None,
    };
    let tree = build_tree(dst);
    let mut t = init;
    let mut prev = f64::INFINITY;
    let mut rmse_now = f64::INFINITY;
    let mut overlap_now = cfg.overlap;
    let mut it = 0;
    while it < cfg.iterations {
        it += 1;
        let moved: Vec<Vector3<f64>> = src.iter().map(|p| t.apply(p)).collect();
        let mut pairs: Vec<(f64, usize, usize)> = moved
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let nb = tree.nearest_one::<SquaredEuclidean>(&[p[0], p[1], p[2]]);
                (nb.distance, i, nb.item as usize)
            })
            .collect();
        pairs.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let keep = match fractional_min {
            None => ((pairs.len() as f64 * cfg.overlap).ceil() as usize).clamp(3, pairs.len()),
            Some(fmin) => {
                let sq: Vec<f64> = pairs.iter().map(|p| p.0).collect();
                fractional_keep(&sq, ((pairs.len() as f64 * fmin).ceil() as usize).clamp(3, pairs.len()))
            }
        };
        overlap_now = keep as f64 / pairs.len() as f64;
        pairs.truncate(keep);
        rmse_now = (pairs.iter().map(|p| p.0).sum::<f64>() / keep as f64).sqrt();
        if (prev - rmse_now).abs() < cfg.tolerance {
            break;
        }
        prev = rmse_now;
        let step = match normals {
            None => {
                let a: Vec<Vector3<f64>> = pairs.iter().map(|p| moved[p.1]).collect();
                let b: Vec<Vector3<f64>> = pairs.iter().map(|p| dst[p.2]).collect();
                // an error here is about ICP's closest-point pairs, not about (possibly absent) landmarks
                umeyama(&a, &b, false).map_err(|e| match e {
                    RegisterError::BadInput { reason, .. } => {
                        RegisterError::bad("ICP", format!("the closest-point pairs: {reason}"))
                    }
                    e => e,
                })?
            }
            Some(nrm) => {
                let mut ata = Matrix6::<f64>::zeros();
                let mut atb = Vector6::<f64>::zeros();
                for &(_, i, j) in &pairs {
                    let (p, q, n) = (moved[i], dst[j], nrm[j]);
                    let c = p.cross(&n);
                    let row = Vector6::new(c[0], c[1], c[2], n[0], n[1], n[2]);
                    ata += row * row.transpose();
                    atb += row * (q - p).dot(&n);
                }
                let Some(sol) = ata.cholesky().map(|c| c.solve(&atb)) else {
                    return Err(RegisterError::bad("ICP", "point-to-plane system is singular (planar target?)"));
                };
                let w = Vector3::new(sol[0], sol[1], sol[2]);
                Similarity {
                    rotation: *Rotation3::new(w).matrix(),
                    translation: Vector3::new(sol[3], sol[4], sol[5]),
                    scale: 1.0,
                }
            }
        };
        t = step.compose(&t);
    }
    Ok((IcpResult { transform: t, rmse: rmse_now, iterations: it }, overlap_now))
}

/// The overlaps [`icp_estimate_overlap`] tries by default (fractions of the source kept).
pub const OVERLAP_CANDIDATES: [f64; 6] = [1.0, 0.8, 0.6, 0.45, 0.3, 0.2];

/// The exponent λ of the fractional RMSD (Phillips, Liu & Tomasi 2007, "Outlier robust ICP for
/// minimizing fractional RMSD", 3DIM): `FRMSD(f) = RMSD_f / f^λ`, λ = 3 for surfaces in 3D, so a
/// smaller overlap must lower the trimmed RMSD by more than `f³` to win.
pub const FRMSD_LAMBDA: f64 = 3.0;

/// One overlap tried by [`icp_estimate_overlap`].
#[derive(Clone, Debug, serde::Serialize)]
pub struct OverlapTrial {
    /// Fraction of the source's closest pairs kept.
    pub overlap: f64,
    /// Trimmed RMSE of the kept pairs at convergence (mm).
    pub rmse_mm: f64,
    /// Fractional RMSD `rmse_mm / overlap^λ` (mm), the selection criterion.
    pub frmsd_mm: f64,
    /// ICP iterations.
    pub iterations: usize,
    /// The overlap was re-chosen at every iteration ([`icp_fractional`]); `overlap` is the final one.
    pub fractional: bool,
    /// Rotation between this trial's transform and the chosen one (degrees).
    pub degrees_from_chosen: f64,
    /// Distance between this trial's translation and the chosen one (mm).
    pub mm_from_chosen: f64,
    /// The transform this trial converged to.
    #[serde(skip)]
    pub transform: Similarity,
}

impl OverlapEstimate {
    /// The trials whose fractional RMSD is within `score_factor` of the chosen one's while their pose is
    /// more than `min_deg` away from it: rival fits the criterion cannot tell apart (an ambiguous
    /// alignment, e.g. a view of a smooth, nearly symmetric part of an organ).
    pub fn rivals(&self, score_factor: f64, min_deg: f64) -> Vec<&OverlapTrial> {
        let best = self.best.rmse / self.overlap.powf(FRMSD_LAMBDA);
        self.trials
            .iter()
            .filter(|t| t.frmsd_mm <= score_factor * best + 1e-9 && t.degrees_from_chosen > min_deg)
            .collect()
    }
}

/// The result of [`icp_estimate_overlap`]: the trial with the lowest FRMSD and every trial.
#[derive(Clone, Debug, serde::Serialize)]
pub struct OverlapEstimate {
    /// ICP result at the chosen overlap.
    pub best: IcpResult,
    /// The chosen overlap.
    pub overlap: f64,
    /// Every overlap tried, in the order given.
    pub trials: Vec<OverlapTrial>,
}

/// Trimmed ICP at each of `overlaps` (each from `init`), then fractional ICP ([`icp_fractional`], the
/// overlap free down to the smallest of `overlaps`), keeping the fit with the lowest fractional RMSD
/// (see [`FRMSD_LAMBDA`]); on a tie (within 1e-9 relative, e.g. an exact fit at several overlaps) the
/// larger fixed overlap wins. For a source that covers only part of the target or the other
/// way round (an intraoperative view of part of an organ), where plain ICP (`overlap` 1) is pulled off
/// by the unmatched part.
pub fn icp_estimate_overlap(
    src: &[Vector3<f64>],
    dst: &[Vector3<f64>],
    dst_normals: Option<&[Vector3<f64>]>,
    init: Similarity,
    cfg: &IcpConfig,
    overlaps: &[f64],
) -> Result<OverlapEstimate> {
    if overlaps.is_empty() {
        return Err(RegisterError::bad("ICP", "no overlap to try"));
    }
    let mut best: Option<(IcpResult, f64, f64)> = None;
    let mut trials = Vec::with_capacity(overlaps.len());
    for &f in overlaps {
        let r = icp(src, dst, dst_normals, init, &IcpConfig { overlap: f, ..cfg.clone() })?;
        let frmsd = r.rmse / f.powf(FRMSD_LAMBDA);
        trials.push(OverlapTrial {
            overlap: f,
            rmse_mm: r.rmse,
            frmsd_mm: frmsd,
            iterations: r.iterations,
            fractional: false,
            degrees_from_chosen: 0.0,
            mm_from_chosen: 0.0,
            transform: r.transform,
        });
        let better = match &best {
            None => true,
            Some((_, bf, bs)) => {
                let tie = (frmsd - bs).abs() <= 1e-9 * bs.max(frmsd) + 1e-12;
                if tie {
                    f > *bf
                } else {
                    frmsd < *bs
                }
            }
        };
        if better {
            best = Some((r, f, frmsd));
        }
    }
    // fractional ICP, the overlap re-chosen at every iteration from the lowest candidate up
    let fmin = overlaps.iter().copied().fold(1.0, f64::min);
    let (r, f) = icp_fractional(src, dst, dst_normals, init, cfg, fmin)?;
    let frmsd = r.rmse / f.powf(FRMSD_LAMBDA);
    trials.push(OverlapTrial {
        overlap: f,
        rmse_mm: r.rmse,
        frmsd_mm: frmsd,
        iterations: r.iterations,
        fractional: true,
        degrees_from_chosen: 0.0,
        mm_from_chosen: 0.0,
        transform: r.transform,
    });
    if best.as_ref().is_some_and(|(_, _, bs)| frmsd < bs * (1.0 - 1e-9) - 1e-12) {
        best = Some((r, f, frmsd));
    }
    let (best, overlap, _) = best.expect("overlaps is not empty");
    for t in &mut trials {
        t.degrees_from_chosen = rotation_angle_deg(&t.transform.rotation, &best.transform.rotation);
        t.mm_from_chosen = (t.transform.translation - best.transform.translation).norm();
    }
    Ok(OverlapEstimate { best, overlap, trials })
}

/// Diagonal of the bounding box of `points` (0 for none).
pub fn bbox_diagonal(points: &[Vector3<f64>]) -> f64 {
    let Some(first) = points.first() else { return 0.0 };
    let (lo, hi) = points.iter().fold((*first, *first), |(lo, hi), p| (lo.inf(p), hi.sup(p)));
    (hi - lo).norm()
}

/// Angle of the rotation `a⁻¹ b` (degrees).
pub fn rotation_angle_deg(a: &Matrix3<f64>, b: &Matrix3<f64>) -> f64 {
    let m = a.transpose() * b;
    ((m.trace() - 1.0) / 2.0).clamp(-1.0, 1.0).acos().to_degrees()
}

/// A plane n·x = d (unit n).
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct Plane {
    /// Unit normal.
    pub normal: Vector3<f64>,
    /// Offset.
    pub offset: f64,
    /// Inliers of the RANSAC fit.
    pub inliers: usize,
}

/// RANSAC plane fit (threshold in mm), refined by PCA of the inliers; deterministic for a seed.
pub fn ransac_plane(points: &[Vector3<f64>], threshold: f64, trials: usize, seed: u64) -> Result<Plane> {
    if points.len() < 3 {
        return Err(RegisterError::bad("floor points", format!("needs >= 3 points, got {}", points.len())));
    }
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut best: Option<(usize, Vector3<f64>, f64)> = None;
    for _ in 0..trials.max(1) {
        let (i, j, k) =
            (rng.gen_range(0..points.len()), rng.gen_range(0..points.len()), rng.gen_range(0..points.len()));
        let n = (points[j] - points[i]).cross(&(points[k] - points[i]));
        if n.norm() < 1e-12 {
            continue;
        }
        let n = n.normalize();
        let d = n.dot(&points[i]);
        let count = points.iter().filter(|p| (n.dot(p) - d).abs() <= threshold).count();
        if best.is_none_or(|b| count > b.0) {
            best = Some((count, n, d));
        }
    }
    let Some((_, n, d)) = best else { return Err(RegisterError::bad("floor points", "all points are collinear")) };
    let inl: Vec<Vector3<f64>> = points.iter().filter(|p| (n.dot(p) - d).abs() <= threshold).copied().collect();
    let c = inl.iter().sum::<Vector3<f64>>() / inl.len() as f64;
    let cov = inl.iter().fold(Matrix3::zeros(), |a, p| a + (p - c) * (p - c).transpose());
    let eig = cov.symmetric_eigen();
    let imin = (0..3).min_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b])).unwrap_or(0);
    let mut normal: Vector3<f64> = eig.eigenvectors.column(imin).into();
    if normal.dot(&n) < 0.0 {
        normal = -normal;
    }
    Ok(Plane { normal, offset: normal.dot(&c), inliers: inl.len() })
}

/// Ray–triangle intersection (Möller–Trumbore): distance t ≥ 0 along `dir`, if any.
pub fn ray_triangle(
    o: &Vector3<f64>,
    dir: &Vector3<f64>,
    a: &Vector3<f64>,
    b: &Vector3<f64>,
    c: &Vector3<f64>,
) -> Option<f64> {
    laparo_core::geometry::ray_triangle(o, dir, a, b, c).filter(|&t| t >= 0.0)
}

/// Vertical (gravity) projection (App. A): each point moved along `direction` to the first surface
/// hit (None when the ray misses the surface).
pub fn project_along(
    points: &[Vector3<f64>],
    direction: &Vector3<f64>,
    vertices: &[Vector3<f64>],
    faces: &[[usize; 3]],
) -> Vec<Option<Vector3<f64>>> {
    use rayon::prelude::*;
    let d = direction.normalize();
    points
        .par_iter()
        .map(|p| {
            faces
                .iter()
                .filter_map(|f| ray_triangle(p, &d, &vertices[f[0]], &vertices[f[1]], &vertices[f[2]]))
                .min_by(|a, b| a.total_cmp(b))
                .map(|t| p + d * t)
        })
        .collect()
}
