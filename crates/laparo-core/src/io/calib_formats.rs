//! Stereo-calibration and camera text formats other than OpenCV YAML / laparo JSON:
//!
//! - EndoVis 2017 `camera_calibration.txt`: `Width:`, `Height:`, `Camera-i-F: fx fy`,
//!   `Camera-i-C: cx cy`, optional `Camera-i-Alpha: skew`, `Camera-i-K: d0 d1 d2 d3 d4`,
//!   `Extrinsic-Omega: wx wy wz` (Rodrigues vector of R, left → right) and
//!   `Extrinsic-T: tx ty tz` (mm); `//` starts a comment. The five `K` values are read in OpenCV
//!   order (k1, k2, p1, p2, k3), as the public EndoVis tools pass them to `cv2.stereoRectify`.
//! - ROS `camera_info` YAML, one file per camera (left, right): `camera_matrix`,
//!   `distortion_coefficients`, `rectification_matrix` R_i, `projection_matrix` P_i. With
//!   X_rect,i = R_i X_i and P_i = K' [I | t_i] (t_i = K'⁻¹ P_i[:, 3], ROS units: metres by REP 103),
//!   the right camera w.r.t. the left is R = R_rᵀ R_l, T = R_rᵀ (t_r − t_l), converted to mm.
//! - Middlebury `calib.txt` (2014/2021): `cam0=[f 0 cx0; 0 f cy; 0 0 1]`, `cam1=[...]`,
//!   `doffs`, `baseline` (mm), `width`, `height`; rectified, so no distortion, R = I and
//!   T = (−baseline, 0, 0); `doffs = c_x1 − c_x0` is checked against the camera matrices.
//! - COLMAP `cameras.txt`: `CAMERA_ID MODEL WIDTH HEIGHT PARAMS...`. It has no extrinsics, so it
//!   is accepted for single-camera intrinsics only (a stereo rig needs R and T).
use crate::calib::StereoCalibration;
use crate::camera::{Distortion, Intrinsics};
use crate::error::{CoreError, Result};
use crate::io::camera_io::{camera_from_filestorage, check_image_size, fs_numbers, CameraFile};
use crate::io::opencv_yaml::FileStorage;
use nalgebra::{Matrix3, Vector3};
use std::collections::HashMap;
use std::path::Path;

/// Rotation matrix of a Rodrigues vector (axis × angle, rad).
pub fn rodrigues(w: Vector3<f64>) -> Matrix3<f64> {
    nalgebra::Rotation3::new(w).into_inner()
}

/// Parse an EndoVis 2017 `camera_calibration.txt` (see the module doc). `size` is used when the
/// file has no `Width`/`Height` and must agree when it has.
pub fn parse_endovis_txt(text: &str, path: &Path, size: Option<(usize, usize)>) -> Result<StereoCalibration> {
    let err = |m: String| CoreError::format(path, m);
    let mut vals: HashMap<String, Vec<f64>> = HashMap::new();
    for (no, raw) in text.lines().enumerate() {
        let line = raw.split("//").next().unwrap_or("").trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let Some((key, rest)) = line.split_once(':') else {
            return Err(err(format!("line {}: expected 'Key: values', found '{line}'", no + 1)));
        };
        let nums: Vec<f64> =
            rest.split_whitespace()
                .map(|t| t.parse::<f64>())
                .collect::<std::result::Result<_, _>>()
                .map_err(|_| err(format!("line {}: '{}' is not a list of numbers", no + 1, rest.trim())))?;
        if nums.iter().any(|v| !v.is_finite()) {
            return Err(err(format!("line {}: non-finite value in '{}'", no + 1, key.trim())));
        }
        if vals.insert(key.trim().to_string(), nums).is_some() {
            return Err(err(format!("line {}: duplicate key '{}'", no + 1, key.trim())));
        }
    }
    let get = |k: &str, n: &[usize]| -> Result<Vec<f64>> {
        let v = vals.get(k).ok_or_else(|| err(format!("missing '{k}'")))?;
        if !n.contains(&v.len()) {
            return Err(err(format!("'{k}' has {} values, expected {n:?}", v.len())));
        }
        Ok(v.clone())
    };
    let file_size = match (vals.get("Width"), vals.get("Height")) {
        (Some(w), Some(h)) => match (w.as_slice(), h.as_slice()) {
            ([w], [h]) if w.fract() == 0.0 && h.fract() == 0.0 && *w >= 1.0 && *h >= 1.0 && *w < 1e15 && *h < 1e15 => {
                Some(check_image_size(*w as u64, *h as u64, &path.display().to_string())?)
            }
            _ => return Err(err("Width/Height must be positive integers".into())),
        },
        _ => None,
    };
    let (width, height) = match (file_size, size) {
        (Some(f), Some(s)) if f != s => {
            return Err(err(format!("file says {}x{} px, caller says {}x{}", f.0, f.1, s.0, s.1)));
        }
        (Some(f), _) | (None, Some(f)) => f,
        (None, None) => return Err(err("no Width/Height in the file; give the image size".into())),
    };
    let cam = |i: usize| -> Result<(Intrinsics, Distortion)> {
        let f = get(&format!("Camera-{i}-F"), &[2])?;
        let c = get(&format!("Camera-{i}-C"), &[2])?;
        let skew = match vals.get(&format!("Camera-{i}-Alpha")) {
            Some(a) if a.len() == 1 => a[0] * f[0],
            Some(_) => return Err(err(format!("'Camera-{i}-Alpha' must be one number"))),
            None => 0.0,
        };
        let d = get(&format!("Camera-{i}-K"), &[4, 5, 8, 12, 14])?;
        let k = Intrinsics { fx: f[0], fy: f[1], cx: c[0], cy: c[1], skew, width, height };
        k.validate().map_err(|e| err(format!("camera {i}: {e}")))?;
        Ok((k, Distortion::from_opencv(&d).map_err(|e| err(format!("Camera-{i}-K: {e}")))?))
    };
    let (left, left_dist) = cam(0)?;
    let (right, right_dist) = cam(1)?;
    let w = get("Extrinsic-Omega", &[3])?;
    let t = get("Extrinsic-T", &[3])?;
    let c = StereoCalibration {
        width,
        height,
        left,
        left_dist,
        right,
        right_dist,
        r: rodrigues(Vector3::new(w[0], w[1], w[2])),
        t_mm: Vector3::new(t[0], t[1], t[2]),
    };
    c.validate().map_err(|e| err(e.to_string()))?;
    Ok(c)
}

fn middlebury_matrix(v: &str, path: &Path, key: &str) -> Result<Matrix3<f64>> {
    let inner = v.trim().trim_start_matches('[').trim_end_matches(']');
    let nums: Vec<f64> = inner
        .split(|c: char| c == ';' || c.is_whitespace() || c == ',')
        .filter(|s| !s.is_empty())
        .map(|s| s.parse::<f64>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|_| CoreError::format(path, format!("{key}: not a 3x3 matrix of numbers: '{v}'")))?;
    if nums.len() != 9 {
        return Err(CoreError::format(path, format!("{key}: {} numbers, expected 9", nums.len())));
    }
    Ok(Matrix3::from_row_slice(&nums))
}

/// Parse the text of a Middlebury `calib.txt` (`path` is used in error messages).
pub fn parse_middlebury_calib(text: &str, path: &Path) -> Result<StereoCalibration> {
    let mut get = std::collections::HashMap::new();
    for line in text.lines() {
        if let Some((k, v)) = line.split_once('=') {
            get.insert(k.trim().to_string(), v.trim().to_string());
        }
    }
    let need = |k: &str| get.get(k).ok_or_else(|| CoreError::format(path, format!("missing key '{k}'")));
    let num = |k: &str| -> Result<f64> {
        need(k)?.parse::<f64>().map_err(|_| CoreError::format(path, format!("{k}: not a number")))
    };
    let k0 = middlebury_matrix(need("cam0")?, path, "cam0")?;
    let k1 = middlebury_matrix(need("cam1")?, path, "cam1")?;
    let (w, h) = (num("width")?, num("height")?);
    if !(w >= 1.0 && h >= 1.0 && w.fract() == 0.0 && h.fract() == 0.0) {
        return Err(CoreError::format(path, format!("width/height {w}x{h} are not positive integers")));
    }
    let (w, h) = check_image_size(w.min(1e15) as u64, h.min(1e15) as u64, &path.display().to_string())?;
    for (k, m) in [("cam0", &k0), ("cam1", &k1)] {
        crate::io::camera_io::check_k_matrix(m).map_err(|e| CoreError::format(path, format!("{k}: {e}")))?;
    }
    let b = num("baseline")?;
    if !(b.is_finite() && b > 0.0) {
        return Err(CoreError::format(path, format!("baseline = {b} (must be > 0 mm)")));
    }
    let fmt = |e: CoreError| CoreError::format(path, e.to_string());
    let left = Intrinsics::from_matrix(&k0, w, h).map_err(fmt)?;
    let right = Intrinsics::from_matrix(&k1, w, h).map_err(fmt)?;
    if get.contains_key("doffs") {
        let doffs = num("doffs")?;
        if !doffs.is_finite() {
            return Err(CoreError::format(path, format!("doffs = {doffs} (must be finite)")));
        }
        let d = right.cx - left.cx;
        if (doffs - d).abs() > 1e-3 * doffs.abs().max(1.0) {
            return Err(CoreError::format(path, format!("doffs = {doffs} but cam1 cx − cam0 cx = {d}")));
        }
    }
    Ok(StereoCalibration {
        width: w,
        height: h,
        left,
        left_dist: Distortion::default(),
        right,
        right_dist: Distortion::default(),
        r: Matrix3::identity(),
        t_mm: Vector3::new(-b, 0.0, 0.0),
    })
}

/// Parse COLMAP `cameras.txt` into cameras (in file order; at least one).
pub fn parse_colmap_cameras(text: &str, path: &Path) -> Result<Vec<CameraFile>> {
    let err = |m: String| CoreError::format(path, m);
    let mut out = Vec::new();
    for (no, raw) in text.lines().enumerate() {
        let line = raw.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let tok: Vec<&str> = line.split_whitespace().collect();
        if tok.len() < 5 {
            return Err(err(format!("line {}: expected 'CAMERA_ID MODEL WIDTH HEIGHT PARAMS...'", no + 1)));
        }
        let num = |s: &str| s.parse::<f64>().ok().filter(|v| v.is_finite());
        let (w, h) = match (tok[2].parse::<u64>(), tok[3].parse::<u64>()) {
            (Ok(w), Ok(h)) => check_image_size(w, h, &format!("{} line {}", path.display(), no + 1))?,
            _ => return Err(err(format!("line {}: width/height are not integers", no + 1))),
        };
        let p: Vec<f64> = tok[4..]
            .iter()
            .map(|t| num(t))
            .collect::<Option<_>>()
            .ok_or_else(|| err(format!("line {}: parameters are not finite numbers", no + 1)))?;
        let model = tok[1];
        let need = |n: usize| -> Result<()> {
            if p.len() != n {
                return Err(err(format!("line {}: {model} needs {n} parameters, found {}", no + 1, p.len())));
            }
            Ok(())
        };
        let (fx, fy, cx, cy, d): (f64, f64, f64, f64, Vec<f64>) = match model {
            "SIMPLE_PINHOLE" => {
                need(3)?;
                (p[0], p[0], p[1], p[2], vec![])
            }
            "PINHOLE" => {
                need(4)?;
                (p[0], p[1], p[2], p[3], vec![])
            }
            "SIMPLE_RADIAL" => {
                need(4)?;
                (p[0], p[0], p[1], p[2], vec![p[3], 0.0, 0.0, 0.0])
            }
            "RADIAL" => {
                need(5)?;
                (p[0], p[0], p[1], p[2], vec![p[3], p[4], 0.0, 0.0])
            }
            "OPENCV" => {
                need(8)?;
                (p[0], p[1], p[2], p[3], p[4..8].to_vec())
            }
            "FULL_OPENCV" => {
                need(12)?;
                // COLMAP order k1 k2 p1 p2 k3 k4 k5 k6 = OpenCV's first eight.
                (p[0], p[1], p[2], p[3], p[4..12].to_vec())
            }
            other => {
                return Err(err(format!(
                    "line {}: camera model {other} is not supported (SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, \
                     OPENCV, FULL_OPENCV)",
                    no + 1
                )))
            }
        };
        let distortion = if d.is_empty() {
            Distortion::default()
        } else {
            Distortion::from_opencv(&d).map_err(|e| err(e.to_string()))?
        };
        // COLMAP puts the centre of the top-left pixel at (0.5, 0.5); laparo (like OpenCV) at (0, 0).
        out.push(CameraFile {
            path: path.to_path_buf(),
            fx,
            fy,
            cx: cx - 0.5,
            cy: cy - 0.5,
            skew: 0.0,
            size: Some((w, h)),
            distortion,
        });
    }
    if out.is_empty() {
        return Err(err("no camera in the COLMAP cameras.txt".into()));
    }
    Ok(out)
}

/// True when a FileStorage document looks like a ROS `camera_info` (projection matrix present).
pub fn is_ros_camera_info(fs: &FileStorage) -> bool {
    fs.get_any(&["projection_matrix", "P", "p"]).is_some()
        && fs.get_any(&["camera_matrix", "K", "k"]).is_some()
        && fs.get_any(&["M1", "M2", "K1", "K2"]).is_none()
}

/// Read a left/right pair of ROS `camera_info` YAML files into a stereo calibration (see the
/// module doc for the derivation of R and T). `size` must agree with the files' size if given.
pub fn read_ros_pair(
    left: &FileStorage,
    right: &FileStorage,
    size: Option<(usize, usize)>,
) -> Result<StereoCalibration> {
    let l = camera_from_filestorage(left, &left.path)?;
    let r = camera_from_filestorage(right, &right.path)?;
    let rect = |fs: &FileStorage| -> Result<(Matrix3<f64>, Vector3<f64>)> {
        let err = |m: String| CoreError::format(&fs.path, m);
        let rm = match fs.get_any(&["rectification_matrix", "R", "r"]) {
            Some((k, n)) => {
                let v = fs_numbers(n).filter(|v| v.len() == 9).ok_or_else(|| err(format!("'{k}' is not 3x3")))?;
                Matrix3::from_row_slice(&v)
            }
            None => Matrix3::identity(),
        };
        let (k, n) = fs.get_any(&["projection_matrix", "P", "p"]).ok_or_else(|| err("no projection_matrix".into()))?;
        let p = fs_numbers(n).filter(|v| v.len() == 12).ok_or_else(|| err(format!("'{k}' is not 3x4")))?;
        if p.iter().chain(rm.iter()).any(|v| !v.is_finite()) {
            return Err(err("non-finite rectification or projection matrix".into()));
        }
        let kp = Matrix3::new(p[0], p[1], p[2], p[4], p[5], p[6], p[8], p[9], p[10]);
        let kinv = kp.try_inverse().ok_or_else(|| err(format!("'{k}': its left 3x3 block is singular")))?;
        let t = kinv * Vector3::new(p[3], p[7], p[11]);
        let e = (rm.transpose() * rm - Matrix3::identity()).abs().max();
        if e > 1e-3 || (rm.determinant() - 1.0).abs() > 1e-3 {
            return Err(err("rectification_matrix is not a rotation".into()));
        }
        Ok((rm, t))
    };
    let (rl, tl) = rect(left)?;
    let (rr, tr) = rect(right)?;
    let path_pair = format!("{} + {}", left.path.display(), right.path.display());
    let err = |m: String| CoreError::format(&path_pair, m);
    let (width, height) = match (l.size, r.size, size) {
        (Some(a), Some(b), _) if a != b => {
            return Err(err(format!("left is {}x{}, right {}x{} px", a.0, a.1, b.0, b.1)))
        }
        (Some(a), _, Some(s)) if a != s => {
            return Err(err(format!("files say {}x{}, caller says {}x{}", a.0, a.1, s.0, s.1)))
        }
        (Some(a), _, _) | (None, Some(a), _) | (None, None, Some(a)) => a,
        (None, None, None) => return Err(err("no image size (image_width/image_height)".into())),
    };
    let c = StereoCalibration {
        width,
        height,
        left: l.intrinsics(Some((width, height)))?,
        left_dist: l.distortion,
        right: r.intrinsics(Some((width, height)))?,
        right_dist: r.distortion,
        r: rr.transpose() * rl,
        t_mm: rr.transpose() * (tr - tl) * 1000.0,
    };
    c.validate().map_err(|e| err(e.to_string()))?;
    Ok(c)
}

#[cfg(test)]
mod tests {
    use super::*;

    const ENDOVIS: &str = "Width: 1280\nHeight: 1024\n\
Camera-0-F: 1084.21 1084.05 // left camera x,y focal dist in pixels\n\
Camera-0-C: 580.02 506.79\nCamera-0-Alpha: 0.0\nCamera-0-K: -0.00069 0.00195 0.00018 0.00000 0.00000\n\
Camera-1-F: 1083.43 1083.22\nCamera-1-C: 680.91 505.81\nCamera-1-Alpha: 0.0\n\
Camera-1-K: -0.00085 0.00245 0.00004 0.00000 0.00000\n\
Extrinsic-Omega: -0.0002 -0.0011 -0.0000 // left to right camera rotation\n\
Extrinsic-T: -4.3499 0.0333 -0.0369\n";

    #[test]
    fn endovis_txt_by_hand() {
        let c = parse_endovis_txt(ENDOVIS, Path::new("camera_calibration.txt"), None).unwrap();
        assert_eq!((c.width, c.height), (1280, 1024));
        assert_eq!((c.left.fx, c.left.fy, c.left.cx, c.left.cy), (1084.21, 1084.05, 580.02, 506.79));
        assert_eq!((c.left_dist.k1, c.left_dist.k2, c.left_dist.p1), (-0.00069, 0.00195, 0.00018));
        assert_eq!(c.right.cx, 680.91);
        assert_eq!(c.t_mm, Vector3::new(-4.3499, 0.0333, -0.0369));
        // Rodrigues of a small vector: R ≈ I + [w]x; angle |w| = sqrt(0.0002² + 0.0011²) rad.
        let ang = (0.0002f64.hypot(0.0011)).to_degrees();
        assert!((c.relative_rotation_deg() - ang).abs() < 1e-9, "{}", c.relative_rotation_deg());
        assert!((c.r[(0, 2)] - (-0.0011)).abs() < 1e-6 && (c.r[(2, 1)] - (-0.0002)).abs() < 1e-6);
        // errors name the file
        let bad = ENDOVIS.replace("Extrinsic-T: -4.3499 0.0333 -0.0369", "Extrinsic-T: nan 0 0");
        let e = parse_endovis_txt(&bad, Path::new("cc.txt"), None).unwrap_err().to_string();
        assert!(e.contains("cc.txt") && e.contains("non-finite"), "{e}");
        let e = parse_endovis_txt(&ENDOVIS.replace("Camera-1-C: 680.91 505.81\n", ""), Path::new("cc.txt"), None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("Camera-1-C"), "{e}");
    }

    #[test]
    fn colmap_cameras_by_hand() {
        let t = "# Camera list\n1 PINHOLE 640 480 500 510 320.5 240.5\n2 OPENCV 800 600 700 700 400 300 -0.1 0.01 0.001 0.002\n";
        let c = parse_colmap_cameras(t, Path::new("cameras.txt")).unwrap();
        assert_eq!(c.len(), 2);
        assert_eq!((c[0].fx, c[0].fy, c[0].cx, c[0].cy, c[0].size), (500.0, 510.0, 320.0, 240.0, Some((640, 480))));
        assert!(!c[0].has_distortion());
        assert_eq!(c[1].distortion.to_opencv(), vec![-0.1, 0.01, 0.001, 0.002, 0.0]);
        let e = parse_colmap_cameras("1 FISHEYE 10 10 1 2 3 4", Path::new("cameras.txt")).unwrap_err().to_string();
        assert!(e.contains("cameras.txt") && e.contains("FISHEYE"), "{e}");
        assert!(parse_colmap_cameras("1 PINHOLE 10 10 1 2 3", Path::new("c.txt")).is_err());
    }

    fn ros(name: &str, k: [f64; 9], r: [f64; 9], p: [f64; 12]) -> String {
        let list = |v: &[f64]| v.iter().map(|x| format!("{x:?}")).collect::<Vec<_>>().join(", ");
        format!(
            "image_width: 640\nimage_height: 480\ncamera_name: {name}\ncamera_matrix:\n  rows: 3\n  cols: 3\n  data: [{}]\n\
distortion_model: plumb_bob\ndistortion_coefficients:\n  rows: 1\n  cols: 5\n  data: [0.1, 0, 0, 0, 0]\n\
rectification_matrix:\n  rows: 3\n  cols: 3\n  data: [{}]\nprojection_matrix:\n  rows: 3\n  cols: 4\n  data: [{}]\n",
            list(&k),
            list(&r),
            list(&p)
        )
    }

    #[test]
    fn ros_pair_gives_r_and_t() {
        // Rectifying rotations: left about y by +a, right about y by +a too (parallel rig after
        // rectification); baseline 0.05 m along x in the rectified frame: P_r[0,3] = -f * 0.05.
        let a = 0.02f64;
        let ry = nalgebra::Rotation3::from_axis_angle(&Vector3::y_axis(), a).into_inner();
        let rl: Vec<f64> = (0..9).map(|i| ry[(i / 3, i % 3)]).collect();
        let rr = rl.clone();
        let k = [500.0, 0.0, 320.0, 0.0, 500.0, 240.0, 0.0, 0.0, 1.0];
        let pl = [450.0, 0.0, 300.0, 0.0, 0.0, 450.0, 240.0, 0.0, 0.0, 0.0, 1.0, 0.0];
        let mut pr = pl;
        pr[3] = -450.0 * 0.05;
        let l = FileStorage::parse(&ros("left", k, rl.try_into().unwrap(), pl), "left.yaml").unwrap();
        let r = FileStorage::parse(&ros("right", k, rr.try_into().unwrap(), pr), "right.yaml").unwrap();
        assert!(is_ros_camera_info(&l));
        let c = read_ros_pair(&l, &r, None).unwrap();
        // Same rectifying rotation → R = I; T = R_rᵀ (−0.05, 0, 0) m = −50 mm along the rotated x.
        assert!((c.r - Matrix3::identity()).abs().max() < 1e-12);
        let want = ry.transpose() * Vector3::new(-50.0, 0.0, 0.0);
        assert!((c.t_mm - want).norm() < 1e-9, "{:?}", c.t_mm);
        assert_eq!(c.left_dist.k1, 0.1);
        assert_eq!((c.width, c.height), (640, 480));
    }
}
