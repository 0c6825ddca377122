//! Relative pose from an essential matrix: the four decompositions E = [t]ₓ R (Hartley &
//! Zisserman result 9.19) and the choice among them by cheirality (triangulated points in front
//! of both cameras), as OpenCV's `recoverPose`.
//!
//! Convention: camera 2 coordinates X₂ = R X₁ + t, so x̂₂ᵀ E x̂₁ = 0 with E = [t]ₓ R; ‖t‖ = 1.
use crate::error::{FeaturesError, Result};
use nalgebra::{Matrix3, Matrix4, Vector3, Vector4};

/// A relative pose chosen by cheirality.
#[derive(Clone, Debug, PartialEq)]
pub struct RelativePose {
    /// Rotation (X₂ = R X₁ + t), det = +1.
    pub r: Matrix3<f64>,
    /// Unit translation direction.
    pub t: Vector3<f64>,
    /// Per correspondence: used (mask) and triangulated in front of both cameras, nearer than
    /// `distance_thresh`.
    pub in_front: Vec<bool>,
    /// Number of `in_front` correspondences.
    pub n_in_front: usize,
    /// Points in front of both cameras for each of the four candidates, in the order of
    /// [`decompose_essential`] (R₁ t, R₁ −t, R₂ t, R₂ −t).
    pub votes: [usize; 4],
}

/// The four (R, t) with [t]ₓ R ∝ E (H&Z result 9.19): (R₁, t), (R₁, −t), (R₂, t), (R₂, −t) with
/// R₁ = U W Vᵀ, R₂ = U Wᵀ Vᵀ, t = u₃, for E = U diag(1, 1, 0) Vᵀ with det U = det V = +1.
pub fn decompose_essential(e: &Matrix3<f64>) -> Result<[(Matrix3<f64>, Vector3<f64>); 4]> {
    if !e.iter().all(|v| v.is_finite()) || e.norm() == 0.0 {
        return Err(FeaturesError::invalid("essential matrix", "zero or not finite"));
    }
    let svd = e.svd(true, true);
    let (Some(mut u), Some(mut vt)) = (svd.u, svd.v_t) else {
        return Err(FeaturesError::Estimation("essential matrix: SVD failed".into()));
    };
    // SVD::new sorts the singular values in decreasing order: the null direction is column 2
    if u.determinant() < 0.0 {
        u = -u;
    }
    if vt.determinant() < 0.0 {
        vt = -vt;
    }
    let w = Matrix3::new(0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0);
    let r1 = u * w * vt;
    let r2 = u * w.transpose() * vt;
    let t: Vector3<f64> = u.column(2).into();
    Ok([(r1, t), (r1, -t), (r2, t), (r2, -t)])
}

/// Linear triangulation (H&Z §12.2, DLT) of x̂₁ ↔ x̂₂ with P₁ = [I | 0], P₂ = [R | t]; the
/// homogeneous point (X, w).
fn triangulate(r: &Matrix3<f64>, t: &Vector3<f64>, a: [f64; 2], b: [f64; 2]) -> Vector4<f64> {
    // rows x·P₃ − P₁ and y·P₃ − P₂ of both cameras
    let mut m = Matrix4::<f64>::zeros();
    m[(0, 0)] = -1.0;
    m[(0, 2)] = a[0];
    m[(1, 1)] = -1.0;
    m[(1, 2)] = a[1];
    for (k, u) in [(0usize, b[0]), (1, b[1])] {
        for j in 0..3 {
            m[(2 + k, j)] = u * r[(2, j)] - r[(k, j)];
        }
        m[(2 + k, 3)] = u * t[2] - t[k];
    }
    let svd = m.svd(false, true);
    let Some(vt) = svd.v_t else { return Vector4::zeros() };
    let imin = (0..4).min_by(|&i, &j| svd.singular_values[i].total_cmp(&svd.singular_values[j])).unwrap_or(3);
    vt.row(imin).transpose()
}

/// Cheirality count of one candidate (OpenCV `recoverPose`): the triangulated point has positive
/// depth in both cameras and lies nearer than `dist` (in units of ‖t‖ = 1).
fn in_front(r: &Matrix3<f64>, t: &Vector3<f64>, a: [f64; 2], b: [f64; 2], dist: f64) -> bool {
    let x = triangulate(r, t, a, b);
    let w = x[3];
    if w == 0.0 {
        return false;
    }
    let p = Vector3::new(x[0], x[1], x[2]) / w;
    let q = r * p + t;
    p[2] > 0.0 && p[2] < dist && q[2] > 0.0 && q[2] < dist
}

/// Recover (R, t) from E and normalised correspondences (x̂ = K⁻¹ x) as OpenCV's `recoverPose`:
/// of the four decompositions, the one with most correspondences (among `mask`, all if None)
/// triangulated in front of both cameras and nearer than `distance_thresh` (OpenCV: 50).
/// Errors: length mismatch, non-finite inputs, no usable correspondence, or a zero E.
pub fn recover_pose(
    e: &Matrix3<f64>,
    p1n: &[[f64; 2]],
    p2n: &[[f64; 2]],
    mask: Option<&[bool]>,
    distance_thresh: f64,
) -> Result<RelativePose> {
    if p1n.len() != p2n.len() {
        return Err(FeaturesError::invalid(
            "recover_pose correspondences",
            format!("p1 has {} points, p2 has {}", p1n.len(), p2n.len()),
        ));
    }
    if let Some(m) = mask {
        if m.len() != p1n.len() {
            return Err(FeaturesError::invalid("mask", format!("{} flags for {} correspondences", m.len(), p1n.len())));
        }
    }
    if distance_thresh.is_nan() || distance_thresh <= 0.0 {
        return Err(FeaturesError::invalid("distance_thresh", format!("{distance_thresh} (need > 0)")));
    }
    for (name, p) in [("p1", p1n), ("p2", p2n)] {
        if let Some(i) = p.iter().position(|q| !(q[0].is_finite() && q[1].is_finite())) {
            return Err(FeaturesError::invalid(
                "recover_pose correspondences",
                format!("{name}[{i}] = {:?} is not finite (NaN or inf)", p[i]),
            ));
        }
    }
    let used: Vec<usize> = (0..p1n.len()).filter(|&i| mask.is_none_or(|m| m[i])).collect();
    if used.is_empty() {
        return Err(FeaturesError::Estimation("recover_pose: no correspondence selected".into()));
    }
    let cands = decompose_essential(e)?;
    let flags: Vec<Vec<bool>> = cands
        .iter()
        .map(|(r, t)| {
            let mut f = vec![false; p1n.len()];
            for &i in &used {
                f[i] = in_front(r, t, p1n[i], p2n[i], distance_thresh);
            }
            f
        })
        .collect();
    let votes: [usize; 4] = std::array::from_fn(|k| flags[k].iter().filter(|&&b| b).count());
    // first maximum, as OpenCV's comparison chain
    let best = (0..4).fold(0, |b, k| if votes[k] > votes[b] { k } else { b });
    let (r, t) = cands[best];
    Ok(RelativePose { r, t, in_front: flags[best].clone(), n_in_front: votes[best], votes })
}
