//! Quality measures of a flattening: corner-angle error against the 3D mesh, δ_area (eq. 4.13),
//! flipped triangles.
use crate::mesh::signed_area;
use nalgebra::Vector3;

/// Interior angles (rad) at the corners a, b, c of a 2D triangle.
pub fn corner_angles_2d(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> [f64; 3] {
    let ang = |p: [f64; 2], q: [f64; 2], r: [f64; 2]| {
        let (u, v) = ([q[0] - p[0], q[1] - p[1]], [r[0] - p[0], r[1] - p[1]]);
        let cross = u[0] * v[1] - u[1] * v[0];
        let dot = u[0] * v[0] + u[1] * v[1];
        cross.abs().atan2(dot)
    };
    [ang(a, b, c), ang(b, c, a), ang(c, a, b)]
}

/// Interior angles (rad) at the corners A, B, C of a 3D triangle.
pub fn corner_angles_3d(a: &Vector3<f64>, b: &Vector3<f64>, c: &Vector3<f64>) -> [f64; 3] {
    let ang = |p: &Vector3<f64>, q: &Vector3<f64>, r: &Vector3<f64>| {
        let (u, v) = (q - p, r - p);
        u.cross(&v).norm().atan2(u.dot(&v))
    };
    [ang(a, b, c), ang(b, c, a), ang(c, a, b)]
}

/// Mean absolute difference (deg) between the corner angles of the 2D triangles at `p` and of
/// their 3D counterparts.
pub fn angle_error_deg(p: &[[f64; 2]], x3d: &[Vector3<f64>], faces: &[[usize; 3]]) -> f64 {
    let mut s = 0.0;
    for f in faces {
        let a2 = corner_angles_2d(p[f[0]], p[f[1]], p[f[2]]);
        let a3 = corner_angles_3d(&x3d[f[0]], &x3d[f[1]], &x3d[f[2]]);
        for k in 0..3 {
            s += (a2[k] - a3[k]).abs();
        }
    }
    (s / (3 * faces.len()).max(1) as f64).to_degrees()
}

/// δ_area (eq. 4.13): RMS over triangles of 1 − A_flat / A_init.
pub fn delta_area(p: &[[f64; 2]], p_init: &[[f64; 2]], faces: &[[usize; 3]]) -> f64 {
    let mut s = 0.0;
    for f in faces {
        let a0 = signed_area(p_init[f[0]], p_init[f[1]], p_init[f[2]]);
        let a1 = signed_area(p[f[0]], p[f[1]], p[f[2]]);
        s += (1.0 - a1 / a0).powi(2);
    }
    (s / faces.len().max(1) as f64).sqrt()
}

/// Restore the image scale of a flattening: the similarity p ↦ c₀ + s (p − c) with
/// s = √(Σ A_init / Σ A_flat) (total triangle areas) and c, c₀ the area-weighted centroids of the
/// flattened and the initial mesh. A uniform scale and a translation leave every angle, hence the
/// conformal term (eq. 4.7), unchanged; they undo the global shrink that the convex
/// least-displacement solve (eq. 4.12) trades against conformality, so the warped image keeps the
/// original pixel density (the thesis' Fig. 4.11 shows that shrink). Returns s (1 when undefined).
pub fn restore_scale(p: &mut [[f64; 2]], p_init: &[[f64; 2]], faces: &[[usize; 3]]) -> f64 {
    rescale(p, p_init, faces, None)
}

/// Smaller singular value of the affine map of a triangle from its initial image position
/// (a, b, c) to its flattened one (pa, pb, pc): the local scale along the most compressed
/// direction (< 1: the warp minifies, i.e. downsamples, the image there). NaN when degenerate.
pub fn min_singular_value(a: [f64; 2], b: [f64; 2], c: [f64; 2], pa: [f64; 2], pb: [f64; 2], pc: [f64; 2]) -> f64 {
    let d = |p: [f64; 2], q: [f64; 2]| [p[0] - q[0], p[1] - q[1]];
    edge_map(d(pb, pa), d(pc, pa), d(b, a), d(c, a)).map_or(f64::NAN, |l| singular_values(l)[0])
}

/// Singular values (smaller, larger) of the 2×2 matrix [[l0, l1], [l2, l3]].
pub(crate) fn singular_values(l: [f64; 4]) -> [f64; 2] {
    let ss = l.iter().map(|v| v * v).sum::<f64>();
    let det = l[0] * l[3] - l[1] * l[2];
    let disc = (ss * ss - 4.0 * det * det).max(0.0).sqrt();
    [(0.5 * (ss - disc)).max(0.0).sqrt(), (0.5 * (ss + disc)).sqrt()]
}

/// Largest singular value of the 2×2 matrix [[l0, l1], [l2, l3]].
pub(crate) fn largest_singular_value(l: [f64; 4]) -> f64 {
    singular_values(l)[1]
}

/// `[[e0x, e1x], [e0y, e1y]] · adj([[f0x, f1x], [f0y, f1y]]) / det(F)`: the linear part of the
/// affine map sending edges f to edges e. Multiplying before dividing keeps the identity exact.
pub(crate) fn edge_map(e0: [f64; 2], e1: [f64; 2], f0: [f64; 2], f1: [f64; 2]) -> Option<[f64; 4]> {
    let det = f0[0] * f1[1] - f1[0] * f0[1];
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    // adj(F) = [[f1y, −f1x], [−f0y, f0x]]
    let m00 = e0[0] * f1[1] - e1[0] * f0[1];
    let m01 = -e0[0] * f1[0] + e1[0] * f0[0];
    let m10 = e0[1] * f1[1] - e1[1] * f0[1];
    let m11 = -e0[1] * f1[0] + e1[1] * f0[0];
    Some([m00 / det, m01 / det, m10 / det, m11 / det])
}

/// Restore the image resolution of a flattening: the similarity p ↦ c₀ + s (p − c) (c, c₀ the
/// area-weighted centroids) with s chosen so that the area-weighted median over the triangles of
/// the local scale along the most compressed direction ([`min_singular_value`]) is 1: the warp
/// then stretches foreshortened directions instead of downsampling the others, so no image
/// detail is lost to minification (an oblique plane at tilt θ gets singular values 1 and 1/cos θ,
/// where [`restore_scale`] gives √cos θ and 1/√cos θ). Returns s (1 when undefined).
pub fn restore_resolution(p: &mut [[f64; 2]], p_init: &[[f64; 2]], faces: &[[usize; 3]]) -> f64 {
    let mut sv: Vec<(f64, f64)> = faces
        .iter()
        .map(|f| {
            let a = signed_area(p_init[f[0]], p_init[f[1]], p_init[f[2]]);
            (min_singular_value(p_init[f[0]], p_init[f[1]], p_init[f[2]], p[f[0]], p[f[1]], p[f[2]]), a)
        })
        .filter(|(s, a)| s.is_finite() && *s > 0.0 && *a > 0.0)
        .collect();
    if sv.is_empty() {
        return 1.0;
    }
    sv.sort_by(|x, y| x.0.total_cmp(&y.0));
    let half = 0.5 * sv.iter().map(|x| x.1).sum::<f64>();
    let mut acc = 0.0;
    let mut med = sv[sv.len() - 1].0;
    for &(s, a) in &sv {
        acc += a;
        if acc >= half {
            med = s;
            break;
        }
    }
    rescale(p, p_init, faces, Some(1.0 / med))
}

/// The similarity of [`restore_scale`] / [`restore_resolution`]: scale `s` (total-area ratio
/// when `None`) about the area-weighted centroids.
fn rescale(p: &mut [[f64; 2]], p_init: &[[f64; 2]], faces: &[[usize; 3]], scale: Option<f64>) -> f64 {
    let (mut a_init, mut a_flat) = (0.0, 0.0);
    let (mut c, mut c0) = ([0.0; 2], [0.0; 2]);
    for f in faces {
        let (ai, af) = (signed_area(p_init[f[0]], p_init[f[1]], p_init[f[2]]), signed_area(p[f[0]], p[f[1]], p[f[2]]));
        a_init += ai;
        a_flat += af;
        for k in 0..2 {
            c0[k] += ai * (p_init[f[0]][k] + p_init[f[1]][k] + p_init[f[2]][k]) / 3.0;
            c[k] += af * (p[f[0]][k] + p[f[1]][k] + p[f[2]][k]) / 3.0;
        }
    }
    let s = scale.unwrap_or((a_init / a_flat).sqrt());
    if !(s.is_finite() && s > 0.0 && a_init > 0.0) {
        return 1.0;
    }
    for k in 0..2 {
        c[k] /= a_flat;
        c0[k] /= a_init;
    }
    for q in p.iter_mut() {
        for k in 0..2 {
            q[k] = c0[k] + s * (q[k] - c[k]);
        }
    }
    s
}

/// Number of triangles whose flattened orientation is not positive (flipped or collapsed).
pub fn n_flipped(p: &[[f64; 2]], faces: &[[usize; 3]]) -> usize {
    faces
        .iter()
        .filter(|f| {
            let a = signed_area(p[f[0]], p[f[1]], p[f[2]]);
            a.is_nan() || a <= 0.0
        })
        .count()
}

/// Mean and maximum vertex displacement |p − P_init| (px).
pub fn displacement_px(p: &[[f64; 2]], p_init: &[[f64; 2]]) -> (f64, f64) {
    let mut s = 0.0;
    let mut mx: f64 = 0.0;
    for (a, b) in p.iter().zip(p_init) {
        let d = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt();
        s += d;
        mx = mx.max(d);
    }
    (s / p.len().max(1) as f64, mx)
}
