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
