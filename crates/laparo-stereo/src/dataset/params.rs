//! Hand-written augmentation parameters (`laparo cats apply --params`): JSON with K as an object
//! or a matrix, optional distortion, per camera.
use crate::augment::{CameraAugmentation, Mat3Rows, StereoAugmentation};
use crate::error::{Result, StereoError};
use laparo_core::{Distortion, Intrinsics};
use nalgebra::Matrix3;
use serde::Deserialize;

#[derive(Deserialize)]
struct KObj {
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
    #[serde(default)]
    skew: f64,
}

#[derive(Deserialize)]
#[serde(untagged)]
enum KInput {
    Obj(KObj),
    Rows(Mat3Rows),
}

#[derive(Deserialize)]
#[serde(untagged)]
enum DistInput {
    Coeffs(Vec<f64>),
    Obj(Distortion),
}

#[derive(Deserialize, Default)]
struct CameraInput {
    k: Option<KInput>,
    distortion: Option<DistInput>,
    euler_deg: Option<[f64; 3]>,
    rotation: Option<Mat3Rows>,
    k_rel: Option<Mat3Rows>,
    distortion_out: Option<DistInput>,
}

#[derive(Deserialize)]
struct ParamsInput {
    k: Option<KInput>,
    #[serde(default)]
    left: Option<CameraInput>,
    #[serde(default)]
    right: Option<CameraInput>,
    dx_right_px: Option<f64>,
}

fn json(what: &str, source: serde_json::Error) -> StereoError {
    StereoError::ConfigJson { what: what.into(), source }
}

fn k_of(k: &KInput, w: usize, h: usize, what: &str) -> Result<Intrinsics> {
    let m = match k {
        KInput::Obj(o) => Matrix3::new(o.fx, o.skew, o.cx, 0.0, o.fy, o.cy, 0.0, 0.0, 1.0),
        KInput::Rows(r) => Matrix3::from_row_slice(&r.concat()),
    };
    Intrinsics::from_matrix(&m, w, h).map_err(|source| StereoError::ConfigField { what: what.into(), source })
}

fn dist_of(d: &Option<DistInput>, what: &str) -> Result<Distortion> {
    match d {
        None => Ok(Distortion::default()),
        Some(DistInput::Obj(o)) => Ok(*o),
        Some(DistInput::Coeffs(c)) => {
            Distortion::from_opencv(c).map_err(|source| StereoError::ConfigField { what: what.into(), source })
        }
    }
}

/// Parse augmentation parameters from JSON: a sidecar of `cats augment` (its `params`), or a
/// hand-written object `{ "k": K (3×3 rows or {fx, fy, cx, cy}), "left": {...}, "right": {...},
/// "dx_right_px": Δx }` where each camera may give `k`, `euler_deg` `[x, y, z]` or `rotation`
/// (3×3 rows), `k_rel` (3×3 rows), `distortion` / `distortion_out` (OpenCV vector or object).
/// Missing rotation = identity; missing K_rel = identity (left) or [[1, 0, t_L − Δx], ...] (right);
/// missing Δx_right = t_L − t_R. `width`, `height` are the images'.
pub fn parse_params(text: &str, width: usize, height: usize) -> Result<StereoAugmentation> {
    let v: serde_json::Value =
        serde_json::from_str(text).map_err(|source| json("parameters are not valid JSON", source))?;
    let v = v.get("params").cloned().unwrap_or(v);
    let p: ParamsInput = serde_json::from_value(v).map_err(|source| json("parameters", source))?;
    let left = p.left.unwrap_or_default();
    let right = p.right.unwrap_or_default();
    /// K, input distortion, rotation R, optional K_rel, output distortion of one camera.
    type CameraParams = (Intrinsics, Distortion, Matrix3<f64>, Option<Matrix3<f64>>, Distortion);
    let cam = |c: &CameraInput, side: &str| -> Result<CameraParams> {
        let k = c.k.as_ref().or(p.k.as_ref()).ok_or_else(|| {
            StereoError::Config(format!("parameters: no intrinsics for the {side} camera (give \"k\" or \"{side}.k\")"))
        })?;
        let k = k_of(k, width, height, &format!("{side}.k"))?;
        let r = match (&c.rotation, &c.euler_deg) {
            (Some(r), _) => Matrix3::from_row_slice(&r.concat()),
            (None, Some(e)) => laparo_core::se3::rotation_zyx(e[0].to_radians(), e[1].to_radians(), e[2].to_radians()),
            (None, None) => Matrix3::identity(),
        };
        let kr = c.k_rel.map(|r| Matrix3::from_row_slice(&r.concat()));
        Ok((
            k,
            dist_of(&c.distortion, &format!("{side}.distortion"))?,
            r,
            kr,
            dist_of(&c.distortion_out, &format!("{side}.distortion_out"))?,
        ))
    };
    let (kl, dl, rl, krl, dol) = cam(&left, "left")?;
    let (kr_, dr, rr, krr, dor) = cam(&right, "right")?;
    let krl = krl.unwrap_or_else(Matrix3::identity);
    let t_l = krl[(0, 2)];
    let (krr, dx) = match (krr, p.dx_right_px) {
        (Some(m), Some(dx)) => {
            let pure = m[(0, 0)] == 1.0 && krl[(0, 0)] == 1.0;
            if pure && (t_l - m[(0, 2)] - dx).abs() > 1e-6 {
                return Err(StereoError::Config(format!(
                    "dx_right_px = {dx} disagrees with K_rel: t_x,left − t_x,right = {} (Δx_right is added to disparities, \
                     so the right principal point moves by −Δx_right)",
                    t_l - m[(0, 2)]
                )));
            }
            (m, dx)
        }
        (Some(m), None) => (m, t_l - m[(0, 2)]),
        (None, dx) => {
            let dx = dx.unwrap_or(0.0);
            (Matrix3::new(1.0, 0.0, t_l - dx, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0), dx)
        }
    };
    let a = StereoAugmentation {
        left: CameraAugmentation::from_rotation(kl, dl, rl, krl, dol),
        right: CameraAugmentation::from_rotation(kr_, dr, rr, krr, dor),
        dx_right_px: dx,
    };
    let check = |e: StereoError| StereoError::ConfigCheck { what: "parameters".into(), source: Box::new(e) };
    a.validate().map_err(check)?;
    check_homographies(&a).map_err(check)?;
    Ok(a)
}

/// Check that both cameras' K are numerically invertible and that the homographies
/// H = K_rel K R K⁻¹ (eq. 3.6) and their inverses are finite and non-singular. A tiny or huge
/// focal length passes [`Intrinsics::validate`] but makes K⁻¹ overflow or K singular in f64.
pub fn check_homographies(a: &StereoAugmentation) -> Result<()> {
    for (side, c) in [("left", &a.left), ("right", &a.right)] {
        let k = c.k.matrix();
        let ki = k.try_inverse().filter(|m| m.iter().all(|v| v.is_finite()));
        if ki.is_none() || k.determinant().abs() < 1e-12 {
            return Err(StereoError::invalid(
                format!("{side}.k"),
                format!("fx = {}, fy = {} is not numerically invertible; focal lengths are in px", c.k.fx, c.k.fy),
            ));
        }
        let h = c.homography();
        let hi =
            c.homography_inverse().map_err(|e| StereoError::ConfigCheck { what: side.into(), source: Box::new(e) })?;
        let det = h.determinant();
        if h.iter().chain(hi.iter()).any(|v| !v.is_finite()) || !det.is_finite() || det == 0.0 {
            return Err(StereoError::invalid(
                format!("{side} homography"),
                format!("H = K_rel K R K⁻¹ is not finite and invertible: {h:?}"),
            ));
        }
    }
    Ok(())
}
