//! Rigid transforms (SE(3)) and Euler-angle conventions.
//!
//! `Se3` is nalgebra's `Isometry3<f64>`: `T * p = R p + t`. Euler angles follow the thesis
//! (eq. 3.7): R = Rz(z) · Ry(y) · Rx(x), angles in radians unless a name says `_deg`.
//!
//! # The transform file form
//!
//! Every transform laparo writes (`register rigid`, `guide`, `cpc pair`) and every transform it reads
//! (`--extrinsics`, `--initial-pose`, `--init`, poses files) uses one form, written by
//! [`transform_json`] and read by [`transform_from_json`] / [`read_transform`]:
//!
//! ```json
//! {"source_to_target": {
//!     "R": [[r00, r01, r02], [r10, r11, r12], [r20, r21, r22]],
//!     "t_mm": [tx, ty, tz],
//!     "scale": 1.0,
//!     "T": [[s·r00, s·r01, s·r02, tx], [...], [...], [0, 0, 0, 1]]}}
//! ```
//!
//! The key names the direction (`source_to_target`, `model_to_camera`, `world_to_camera`): the
//! transform maps a point given in the first frame to the second, `p_target = scale · R @ p_source +
//! t_mm` with `R` a list of **rows** (numpy: `R = np.array(d["R"])`, `p @ R.T * scale + t_mm`), or
//! equivalently `T @ [p, 1]`. `scale` is 1 for rigid transforms. `T` repeats `R`, `t_mm` and
//! `scale` for readers that prefer one 4×4 matrix; when both are present they must agree.
//! The reader also takes `{"T": 4×4}` alone, `{"R", "t"}` with an optional `"unit": "mm" | "m"`
//! (the caller decides the unit of a bare `t`), and flat lists of 9 or 16 numbers read row by row.
use crate::depth::DepthUnit;
use crate::error::{CoreError, Result};
use nalgebra::{Isometry3, Matrix3, Matrix4, Rotation3, Translation3, UnitQuaternion, Vector3};
use std::path::Path;

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

/// A transform read by [`transform_from_json`]: `p ↦ scale · R p + t`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TransformRecord {
    /// Rotation (orthonormal, determinant +1).
    pub rotation: Matrix3<f64>,
    /// Translation, in `translation_unit` (or the caller's default unit when `None`).
    pub translation: Vector3<f64>,
    /// Scale (1 for a rigid transform).
    pub scale: f64,
    /// The unit the file states for the translation (`t_mm` or `"unit"`), `None` when it states none.
    pub translation_unit: Option<DepthUnit>,
}

impl TransformRecord {
    /// The translation in millimetres, taking `default_unit` when the file states no unit.
    pub fn translation_mm(&self, default_unit: DepthUnit) -> Vector3<f64> {
        self.translation * self.translation_unit.unwrap_or(default_unit).to_metres() * 1e3
    }
    /// The rigid part as an [`Se3`] with the translation in millimetres; an error when the scale is not 1.
    pub fn to_se3_mm(&self, default_unit: DepthUnit, what: &str) -> Result<Se3> {
        if (self.scale - 1.0).abs() > 1e-9 {
            return Err(CoreError::invalid(what, format!("scale {} where a rigid transform is expected", self.scale)));
        }
        Ok(se3_from_rt(&self.rotation, &self.translation_mm(default_unit)))
    }
}

fn rows3(m: &Matrix3<f64>) -> [[f64; 3]; 3] {
    [[m[(0, 0)], m[(0, 1)], m[(0, 2)]], [m[(1, 0)], m[(1, 1)], m[(1, 2)]], [m[(2, 0)], m[(2, 1)], m[(2, 2)]]]
}

/// The documented transform form (see the module docs) of `p ↦ scale · R p + t_mm`: `{"R": rows,
/// "t_mm": [x, y, z], "scale": s, "T": 4×4 rows}`. Put it under a key that names the direction.
pub fn transform_json(rotation: &Matrix3<f64>, t_mm: &Vector3<f64>, scale: f64) -> serde_json::Value {
    let sr = rotation * scale;
    let t4: Vec<[f64; 4]> = (0..3)
        .map(|i| [sr[(i, 0)], sr[(i, 1)], sr[(i, 2)], t_mm[i]])
        .chain(std::iter::once([0.0, 0.0, 0.0, 1.0]))
        .collect();
    serde_json::json!({"R": rows3(rotation), "t_mm": [t_mm[0], t_mm[1], t_mm[2]], "scale": scale, "T": t4})
}

/// [`transform_json`] of a rigid transform whose translation is in millimetres.
pub fn se3_json(t: &Se3) -> serde_json::Value {
    transform_json(t.rotation.to_rotation_matrix().matrix(), &t.translation.vector, 1.0)
}

fn numbers(v: &serde_json::Value, out: &mut Vec<f64>) -> bool {
    match v {
        serde_json::Value::Array(a) => a.iter().all(|x| numbers(x, out)),
        serde_json::Value::Number(n) => n.as_f64().map(|x| out.push(x)).is_some(),
        _ => false,
    }
}

/// `n`×`n` numbers, row by row (nested rows or one flat list).
fn matrix_rows(v: &serde_json::Value, n: usize, what: &str, key: &str) -> Result<Vec<f64>> {
    let mut m = Vec::new();
    if !numbers(v, &mut m) || m.len() != n * n {
        return Err(CoreError::invalid(
            what,
            format!("\"{key}\" must be a {n}x{n} matrix of numbers (a list of rows)"),
        ));
    }
    if let serde_json::Value::Array(rows) = v {
        if rows.iter().any(|r| r.is_array())
            && (rows.len() != n || rows.iter().any(|r| r.as_array().map(Vec::len) != Some(n)))
        {
            return Err(CoreError::invalid(what, format!("\"{key}\" must have {n} rows of {n} numbers")));
        }
    }
    if !m.iter().all(|x| x.is_finite()) {
        return Err(CoreError::invalid(what, format!("\"{key}\" has non-finite entries")));
    }
    Ok(m)
}

fn vector3(v: &serde_json::Value, what: &str, key: &str) -> Result<Vector3<f64>> {
    let mut t = Vec::new();
    if !numbers(v, &mut t) || t.len() != 3 || !t.iter().all(|x| x.is_finite()) {
        return Err(CoreError::invalid(what, format!("\"{key}\" must be 3 finite numbers")));
    }
    Ok(Vector3::new(t[0], t[1], t[2]))
}

/// Read a transform in the documented form (module docs) from `v`: the object under `direction`
/// (e.g. `"source_to_target"`) when `v` has that key, else `v` itself when it has `R` or `T`.
/// `what` (a file or flag) is named in errors. The rotation must be orthonormal with determinant +1
/// (tolerance 1e-4 on |RᵀR − I|, then re-orthonormalised by the caller's `se3_from_rt`); `R`/`t_mm`/`scale` and `T` must agree when both are given.
pub fn transform_from_json(v: &serde_json::Value, direction: &str, what: &str) -> Result<TransformRecord> {
    let o = match v.get(direction) {
        Some(o) => o,
        None if v.get("R").is_some() || v.get("T").is_some() => v,
        None => {
            let legacy = v.get("transform").and_then(|t| t.get("rotation")).is_some();
            return Err(CoreError::invalid(
                what,
                if legacy {
                    format!(
                        "this is the old `register rigid` layout (\"transform\".\"rotation\": 9 numbers, column-major); \
                         expected \"{direction}\": {{\"R\": 3 rows, \"t_mm\": [x, y, z]}}: re-run `laparo register rigid`"
                    )
                } else {
                    format!("expected \"{direction}\": {{\"R\": 3x3 rows, \"t_mm\": [x, y, z]}} or {{\"T\": 4x4 rows}}")
                },
            ));
        }
    };
    let stated_unit = match o.get("unit").and_then(|u| u.as_str()) {
        Some(s) => Some(s.parse::<DepthUnit>().map_err(|e| CoreError::invalid(what, e.to_string()))?),
        None => None,
    };
    let from_t = match o.get("T") {
        Some(tm) => {
            let m = Matrix4::from_row_slice(&matrix_rows(tm, 4, what, "T")?);
            let last = m.row(3);
            if last[0].abs() + last[1].abs() + last[2].abs() + (last[3] - 1.0).abs() > 1e-9 {
                return Err(CoreError::invalid(what, "last row of \"T\" must be [0, 0, 0, 1]"));
            }
            let block = m.fixed_view::<3, 3>(0, 0).into_owned();
            let det = block.determinant();
            if det <= 0.0 {
                return Err(CoreError::invalid(what, "\"T\" has a rotation block with determinant <= 0"));
            }
            let s = det.cbrt();
            Some((block / s, Vector3::new(m[(0, 3)], m[(1, 3)], m[(2, 3)]), s))
        }
        None => None,
    };
    let from_rt = match o.get("R") {
        Some(r) => {
            let rot = Matrix3::from_row_slice(&matrix_rows(r, 3, what, "R")?);
            let (t, unit) = if let Some(t) = o.get("t_mm") {
                (vector3(t, what, "t_mm")?, Some(DepthUnit::Mm))
            } else if let Some(t) = o.get("t_m") {
                (vector3(t, what, "t_m")?, Some(DepthUnit::M))
            } else if let Some(t) = o.get("t") {
                (vector3(t, what, "t")?, None)
            } else {
                return Err(CoreError::invalid(what, "\"R\" without a translation (\"t_mm\", or \"t\" with \"unit\")"));
            };
            let s = match o.get("scale") {
                Some(s) => s
                    .as_f64()
                    .filter(|s| s.is_finite() && *s > 0.0)
                    .ok_or_else(|| CoreError::invalid(what, "\"scale\" must be a positive number"))?,
                None => 1.0,
            };
            Some((rot, t, s, unit))
        }
        None => None,
    };
    let (rotation, translation, scale, unit) = match (from_rt, from_t) {
        (Some((r, t, s, u)), Some((r4, t4, s4))) => {
            let tol = 1e-9 * (1.0 + t.norm());
            if (r - r4).norm() > 1e-9 || (t - t4).norm() > tol || (s - s4).abs() > 1e-9 * s {
                return Err(CoreError::invalid(what, "\"T\" disagrees with \"R\", \"t_mm\" and \"scale\""));
            }
            (r, t, s, u)
        }
        (Some((r, t, s, u)), None) => (r, t, s, u),
        (None, Some((r, t, s))) => (r, t, s, None),
        (None, None) => unreachable!("checked above: the object has R or T"),
    };
    let translation_unit = match (unit, stated_unit) {
        (Some(a), Some(b)) if a != b => {
            return Err(CoreError::invalid(what, "\"unit\" contradicts the translation's key (t_mm / t_m)"))
        }
        (a, b) => a.or(b),
    };
    if !((rotation.transpose() * rotation - Matrix3::identity()).norm() < 1e-4 && rotation.determinant() > 0.0) {
        return Err(CoreError::invalid(
            what,
            "the rotation is not orthonormal with determinant +1 (tolerance 1e-4); \"R\" is a list of rows",
        ));
    }
    Ok(TransformRecord { rotation, translation, scale, translation_unit })
}

/// [`transform_from_json`] of a JSON file; errors name the file.
pub fn read_transform(path: &Path, direction: &str) -> Result<TransformRecord> {
    let text = std::fs::read_to_string(path).map_err(|e| CoreError::io(path, e))?;
    let v: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| CoreError::format(path, format!("not JSON: {e}")))?;
    transform_from_json(&v, direction, &path.display().to_string())
}
#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn transform_form_round_trips_and_is_row_major() {
        let r = rotation_zyx(0.3, -0.5, 1.1);
        let t = Vector3::new(10.0, -20.0, 35.5);
        let v = serde_json::json!({"source_to_target": transform_json(&r, &t, 1.25)});
        // Row-major by hand: R[0][1] is row 0, column 1.
        assert_eq!(v["source_to_target"]["R"][0][1].as_f64().unwrap(), r[(0, 1)]);
        assert_eq!(v["source_to_target"]["T"][1][3].as_f64().unwrap(), -20.0);
        assert_eq!(v["source_to_target"]["T"][2][0].as_f64().unwrap(), 1.25 * r[(2, 0)]);
        let back = transform_from_json(&v, "source_to_target", "t.json").unwrap();
        assert!((back.rotation - r).norm() < 1e-15 && back.translation == t && back.scale == 1.25);
        assert_eq!(back.translation_unit, Some(DepthUnit::Mm));
        // T alone gives the same transform (the scale from its determinant).
        let only_t = serde_json::json!({"T": v["source_to_target"]["T"]});
        let b2 = transform_from_json(&only_t, "source_to_target", "t.json").unwrap();
        assert!((b2.rotation - r).norm() < 1e-12 && (b2.translation - t).norm() < 1e-12);
        assert!((b2.scale - 1.25).abs() < 1e-12 && b2.translation_unit.is_none());
        assert!(matches!(back.to_se3_mm(DepthUnit::Mm, "t.json"), Err(CoreError::Invalid { .. })));
    }

    #[test]
    fn transform_reader_refuses_transposed_or_contradictory_input() {
        let r = rotation_zyx(0.2, 0.1, -0.4);
        let mut v = transform_json(&r, &Vector3::new(1.0, 2.0, 3.0), 1.0);
        // A T that disagrees with R (transposed rotation block) is refused.
        let rt = r.transpose();
        v["T"] = serde_json::json!([
            [rt[(0, 0)], rt[(0, 1)], rt[(0, 2)], 1.0],
            [rt[(1, 0)], rt[(1, 1)], rt[(1, 2)], 2.0],
            [rt[(2, 0)], rt[(2, 1)], rt[(2, 2)], 3.0],
            [0.0, 0.0, 0.0, 1.0]
        ]);
        let e = transform_from_json(&v, "a_to_b", "x.json").unwrap_err().to_string();
        assert!(e.contains("x.json") && e.contains("disagrees"), "{e}");
        // The pre-v1 register rigid layout gets an error that says what it is.
        let old = serde_json::json!({"transform": {"rotation": [1, 0, 0, 0, 1, 0, 0, 0, 1], "translation": [0, 0, 0]}});
        let e = transform_from_json(&old, "source_to_target", "old.json").unwrap_err().to_string();
        assert!(e.contains("column-major") && e.contains("source_to_target"), "{e}");
        // A reflection is not a rotation; bare "t" takes the unit the file states.
        let refl = serde_json::json!({"R": [[1, 0, 0], [0, 1, 0], [0, 0, -1]], "t": [0, 0, 0]});
        assert!(transform_from_json(&refl, "a_to_b", "r.json").is_err());
        let m = serde_json::json!({"R": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "t": [0.01, 0, 0], "unit": "m"});
        let rec = transform_from_json(&m, "a_to_b", "m.json").unwrap();
        assert!((rec.translation_mm(DepthUnit::Mm) - Vector3::new(10.0, 0.0, 0.0)).norm() < 1e-12);
    }
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
