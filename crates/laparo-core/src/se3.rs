//! Rigid transforms (SE(3)) and Euler-angle conventions.
//!
//! `Se3` is nalgebra's `Isometry3<f64>`: `T * p = R p + t`. Euler angles follow the thesis
//! (eq. 3.7): R = Rz(z) · Ry(y) · Rx(x), angles in radians unless a name says `_deg`.
use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};

/// A rigid transform `p ↦ R p + t` (f64).
pub type Se3 = Isometry3<f64>;

/// Build an `Se3` from a rotation matrix (re-orthonormalised) and a translation.
pub fn se3_from_rt(r: &Matrix3<f64>, t: &Vector3<f64>) -> Se3 {
    let rot = Rotation3::from_matrix(r);
    Isometry3::from_parts(Translation3::from(*t), UnitQuaternion::from_rotation_matrix(&rot))
}

/// R = Rz(z) · Ry(y) · Rx(x), angles in radians (thesis eq. 3.7).
pub fn rotation_zyx(x: f64, y: f64, z: f64) -> Matrix3<f64> {
    (Rotation3::from_axis_angle(&Vector3::z_axis(), z)
        * Rotation3::from_axis_angle(&Vector3::y_axis(), y)
        * Rotation3::from_axis_angle(&Vector3::x_axis(), x))
    .into_inner()
}

/// Inverse of [`rotation_zyx`]: `(x, y, z)` in radians with y in [-π/2, π/2].
pub fn euler_zyx(r: &Matrix3<f64>) -> (f64, f64, f64) {
    // R = Rz Ry Rx  =>  R[2,0] = -sin y, R[2,1] = cos y sin x, R[2,2] = cos y cos x,
    // R[1,0] = sin z cos y, R[0,0] = cos z cos y.
    let sy = (-r[(2, 0)]).clamp(-1.0, 1.0);
    let y = sy.asin();
    let cy = (r[(2, 1)].powi(2) + r[(2, 2)].powi(2)).sqrt();
    if cy > 1e-12 {
        let x = r[(2, 1)].atan2(r[(2, 2)]);
        let z = r[(1, 0)].atan2(r[(0, 0)]);
        (x, y, z)
    } else {
        // Gimbal lock: put everything in z.
        let z = (-r[(0, 1)]).atan2(r[(1, 1)]);
        (0.0, y, z)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn euler_round_trip_and_nalgebra_convention() {
        let (x, y, z) = (0.1, -0.2, 0.3);
        let r = rotation_zyx(x, y, z);
        // nalgebra's from_euler_angles(roll, pitch, yaw) is also Rz(yaw) Ry(pitch) Rx(roll).
        let n = Rotation3::from_euler_angles(x, y, z).into_inner();
        assert!((r - n).norm() < 1e-15);
        let (a, b, c) = euler_zyx(&r);
        assert!((a - x).abs() < 1e-14 && (b - y).abs() < 1e-14 && (c - z).abs() < 1e-14);
    }
}
