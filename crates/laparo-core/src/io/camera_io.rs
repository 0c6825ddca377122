//! One reader for single-camera intrinsics files, used by every command that takes `--intrinsics`.
//!
//! | format | detected by | fields |
//! |---|---|---|
//! | JSON | `.json` or a leading `{` | `fx, fy, cx, cy` (+ `skew`) **or** `"K"` (3×3 rows or 9 numbers); numbers or numeric strings (the P2ILF camera file uses strings); optional `width`/`height` (or `image_width`/`image_height`, `size: [w, h]`); optional distortion as a list `dist`/`distortion`/`D`/`dist_coeffs` (OpenCV order) or named `k1 k2 p1 p2 k3 k4 k5 k6 s1..s4` |
//! | ROS `camera_info` YAML | `camera_matrix` / `K` keys | `image_width`, `image_height`, `camera_matrix.data`, `distortion_model` (`plumb_bob`, `rational_polynomial`), `distortion_coefficients.data` (or the message layout `K`, `D`, `width`, `height`) |
//! | OpenCV FileStorage YAML | other YAML | `camera_matrix`/`cameraMatrix`/`K`/`M`/`M1`, `distortion_coefficients`/`dist_coeffs`/`D`/`D1`, optional `image_width`/`image_height` |
//! | COLMAP `cameras.txt` | `.txt` with a COLMAP model name | the first camera: `SIMPLE_PINHOLE`, `PINHOLE`, `SIMPLE_RADIAL`, `RADIAL`, `OPENCV`, `FULL_OPENCV`; COLMAP's pixel centres are at +0.5, so cx, cy are shifted by −0.5 px |
//! | EndoVis 2017 `camera_calibration.txt` | `Camera-0-F:` lines | the left camera (`Camera-0-*`) |
//!
//! Distortion is never dropped: [`CameraFile::intrinsics_undistorted`] refuses a distorted camera
//! for computations that cannot apply it, naming the file.
use crate::camera::{Distortion, Intrinsics};
use crate::error::{CoreError, Result};
use crate::io::opencv_yaml::{FileStorage, FsNode};
use nalgebra::Matrix3;
use serde_json::Value;
use std::path::{Path, PathBuf};

/// Largest image side accepted from a file or a flag (px).
pub const MAX_IMAGE_SIDE: usize = 65_536;
/// Largest image area accepted from a file or a flag (px²): 2^28 (e.g. 16384 × 16384).
pub const MAX_IMAGE_PIXELS: usize = 1 << 28;

/// Check an image size read from a file or a flag: both sides in 1..=65536 and w·h ≤ 2^28.
/// `what` names the source (file or flag) in the error.
pub fn check_image_size(width: u64, height: u64, what: &str) -> Result<(usize, usize)> {
    let side = MAX_IMAGE_SIDE as u64;
    if width == 0 || height == 0 || width > side || height > side || width * height > MAX_IMAGE_PIXELS as u64 {
        return Err(CoreError::invalid(
            what,
            format!(
                "image size {width}x{height} px is out of range (each side 1..={MAX_IMAGE_SIDE}, at most {} px in all)",
                MAX_IMAGE_PIXELS
            ),
        ));
    }
    Ok((width as usize, height as usize))
}

/// A camera read from an intrinsics file: pinhole parameters in px, the distortion (zero when
/// the file has none) and the image size when the file states it.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraFile {
    /// The file it was read from (named in errors).
    pub path: PathBuf,
    /// Focal length along x (px).
    pub fx: f64,
    /// Focal length along y (px).
    pub fy: f64,
    /// Principal point x (px).
    pub cx: f64,
    /// Principal point y (px).
    pub cy: f64,
    /// Skew (K[0,1]), usually 0.
    pub skew: f64,
    /// Image size (width, height) in px, when the file gives it.
    pub size: Option<(usize, usize)>,
    /// Lens distortion (all zero when the file has none).
    pub distortion: Distortion,
}

impl CameraFile {
    /// True when the file gives a non-zero distortion.
    pub fn has_distortion(&self) -> bool {
        !self.distortion.is_zero()
    }

    /// The intrinsics for an image of `size` px (e.g. the depth map's): when the file states a
    /// size too they must agree; with neither the call fails naming the file.
    pub fn intrinsics(&self, size: Option<(usize, usize)>) -> Result<Intrinsics> {
        let (w, h) = match (self.size, size) {
            (Some(f), Some(s)) if f != s => {
                return Err(CoreError::format(
                    &self.path,
                    format!("intrinsics are for {}x{} px but the image is {}x{} px", f.0, f.1, s.0, s.1),
                ))
            }
            (Some(f), _) | (None, Some(f)) => f,
            (None, None) => {
                return Err(CoreError::format(&self.path, "no image size in the file (add width and height)"))
            }
        };
        let k = Intrinsics { fx: self.fx, fy: self.fy, cx: self.cx, cy: self.cy, skew: self.skew, width: w, height: h };
        k.validate().map_err(|e| CoreError::format(&self.path, e.to_string()))?;
        Ok(k)
    }

    /// [`intrinsics`](Self::intrinsics) for a computation that assumes an undistorted (pinhole)
    /// image: a file with distortion is refused with a clear error rather than silently ignored.
    pub fn intrinsics_undistorted(&self, size: Option<(usize, usize)>, command: &str) -> Result<Intrinsics> {
        if self.has_distortion() {
            return Err(CoreError::format(
                &self.path,
                format!(
                    "the camera has lens distortion {:?} but {command} needs an undistorted image: undistort \
                     the inputs first (or give intrinsics without distortion)",
                    self.distortion.to_opencv()
                ),
            ));
        }
        self.intrinsics(size)
    }
}

/// Read a single camera's intrinsics (see the module table for the formats).
pub fn read_camera(path: impl AsRef<Path>) -> Result<CameraFile> {
    let path = path.as_ref();
    let bytes = super::read_bytes(path)?;
    let text = String::from_utf8(bytes).map_err(|_| CoreError::format(path, "not UTF-8 text"))?;
    let ext = super::extension(path);
    let mut cam = if ext == "json" || text.trim_start().starts_with('{') {
        let v: Value =
            serde_json::from_str(&text).map_err(|e| CoreError::format(path, format!("invalid JSON: {e}")))?;
        camera_from_json(&v, path)?
    } else if text.lines().any(|l| l.trim_start().starts_with("Camera-0-F")) {
        let c = super::calib_formats::parse_endovis_txt(&text, path, None)?;
        CameraFile {
            path: path.to_path_buf(),
            fx: c.left.fx,
            fy: c.left.fy,
            cx: c.left.cx,
            cy: c.left.cy,
            skew: c.left.skew,
            size: Some((c.width, c.height)),
            distortion: c.left_dist,
        }
    } else if ext == "txt" {
        super::calib_formats::parse_colmap_cameras(&text, path)?.remove(0)
    } else {
        let fs = FileStorage::parse(&text, path)?;
        camera_from_filestorage(&fs, path)?
    };
    cam.path = path.to_path_buf();
    check_camera(&cam)?;
    Ok(cam)
}

fn check_camera(c: &CameraFile) -> Result<()> {
    let bad = |m: String| Err(CoreError::format(&c.path, m));
    if !(c.fx.is_finite() && c.fx > 0.0 && c.fy.is_finite() && c.fy > 0.0) {
        return bad(format!("focal lengths fx = {}, fy = {} must be finite and > 0", c.fx, c.fy));
    }
    if !(c.cx.is_finite() && c.cy.is_finite() && c.skew.is_finite()) {
        return bad(format!("principal point ({}, {}) / skew {} must be finite", c.cx, c.cy, c.skew));
    }
    if c.distortion.to_opencv().iter().any(|v| !v.is_finite()) {
        return bad("non-finite distortion coefficient".into());
    }
    Ok(())
}

/// A number from JSON: a number or a string holding one (as in the P2ILF camera file).
pub(crate) fn json_num(v: &Value) -> Option<f64> {
    match v {
        Value::Number(n) => n.as_f64(),
        Value::String(s) => s.trim().parse::<f64>().ok(),
        _ => None,
    }
}

/// A flat list of numbers: nested arrays are flattened, `{"data": [...]}` is accepted.
pub(crate) fn json_numbers(v: &Value) -> Option<Vec<f64>> {
    fn walk(v: &Value, out: &mut Vec<f64>, depth: usize) -> Option<()> {
        match v {
            Value::Array(a) if depth < 3 => a.iter().try_for_each(|x| walk(x, out, depth + 1)),
            Value::Object(o) if depth == 0 => walk(o.get("data")?, out, depth + 1),
            x => {
                out.push(json_num(x)?);
                Some(())
            }
        }
    }
    let mut out = Vec::new();
    walk(v, &mut out, 0)?;
    Some(out)
}

fn json_size(v: &Value, key: &str, path: &Path) -> Result<Option<u64>> {
    match v.get(key) {
        None | Some(Value::Null) => Ok(None),
        Some(x) => match json_num(x) {
            Some(n) if n.fract() == 0.0 && (1.0..1e15).contains(&n) => Ok(Some(n as u64)),
            _ => Err(CoreError::format(path, format!("\"{key}\" must be a positive integer, found {x}"))),
        },
    }
}

fn first<'a>(v: &'a Value, keys: &[&'static str]) -> Option<(&'static str, &'a Value)> {
    keys.iter().find_map(|k| v.get(*k).filter(|x| !x.is_null()).map(|x| (*k, x)))
}

const NAMED_DIST: [&str; 12] = ["k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6", "s1", "s2", "s3", "s4"];

/// Parse a camera from a JSON value (see the module table).
pub fn camera_from_json(v: &Value, path: &Path) -> Result<CameraFile> {
    let err = |m: String| CoreError::format(path, m);
    if !v.is_object() {
        return Err(err("expected a JSON object with fx, fy, cx, cy or K".into()));
    }
    let num = |k: &str| -> Result<Option<f64>> {
        match v.get(k) {
            None | Some(Value::Null) => Ok(None),
            Some(x) => json_num(x).map(Some).ok_or_else(|| err(format!("\"{k}\" is not a number: {x}"))),
        }
    };
    let (fx, fy, cx, cy, skew) = if let Some((k, m)) = first(v, &["K", "k", "camera_matrix", "intrinsic_matrix"]) {
        let m = json_numbers(m).filter(|m| m.len() == 9).ok_or_else(|| err(format!("\"{k}\" must be 3x3 numbers")))?;
        let km = Matrix3::from_row_slice(&m);
        check_k_matrix(&km).map_err(|e| err(format!("\"{k}\": {e}")))?;
        (km[(0, 0)], km[(1, 1)], km[(0, 2)], km[(1, 2)], km[(0, 1)])
    } else {
        match (num("fx")?, num("fy")?, num("cx")?, num("cy")?) {
            (Some(fx), Some(fy), Some(cx), Some(cy)) => (fx, fy, cx, cy, num("skew")?.unwrap_or(0.0)),
            _ => return Err(err("expected fields fx, fy, cx, cy (numbers or numeric strings) or \"K\"".into())),
        }
    };
    let w = match json_size(v, "width", path)? {
        Some(w) => Some(w),
        None => json_size(v, "image_width", path)?,
    };
    let h = match json_size(v, "height", path)? {
        Some(h) => Some(h),
        None => json_size(v, "image_height", path)?,
    };
    let (w, h) = match (w, h, first(v, &["size", "image_size", "imageSize"])) {
        (Some(w), Some(h), _) => (Some(w), Some(h)),
        (None, None, Some((k, s))) => match json_numbers(s).as_deref() {
            Some([w, h])
                if w.fract() == 0.0 && h.fract() == 0.0 && *w >= 1.0 && *h >= 1.0 && *w < 1e15 && *h < 1e15 =>
            {
                (Some(*w as u64), Some(*h as u64))
            }
            _ => return Err(err(format!("\"{k}\" must be [width, height]"))),
        },
        (None, None, None) => (None, None),
        _ => return Err(err("give both width and height, or neither".into())),
    };
    let size = match (w, h) {
        (Some(w), Some(h)) => Some(check_image_size(w, h, &path.display().to_string())?),
        _ => None,
    };
    let listed = first(v, &["dist", "distortion", "D", "d", "dist_coeffs", "distCoeffs", "distortion_coefficients"]);
    let named: Vec<(usize, f64)> = NAMED_DIST
        .iter()
        .enumerate()
        .filter_map(|(i, k)| v.get(*k).filter(|x| !x.is_null()).map(|x| (i, x)))
        .map(|(i, x)| json_num(x).map(|n| (i, n)).ok_or_else(|| err(format!("\"{}\" is not a number", NAMED_DIST[i]))))
        .collect::<Result<_>>()?;
    if let Some(m) = v.get("distortion_model").and_then(Value::as_str) {
        check_distortion_model(m).map_err(err)?;
    }
    let distortion = match (listed, named.is_empty()) {
        (Some(_), false) => {
            return Err(err("distortion is given twice (a list and named k1, k2, ... fields)".into()));
        }
        (Some((k, d)), true) => {
            let c = json_numbers(d).ok_or_else(|| err(format!("\"{k}\" must be a list of numbers")))?;
            distortion_from(&c).map_err(|e| err(format!("\"{k}\": {e}")))?
        }
        (None, false) => {
            let mut c = [0.0; 12];
            for (i, n) in named {
                c[i] = n;
            }
            Distortion::from_opencv(&c).map_err(|e| err(e.to_string()))?
        }
        (None, true) => Distortion::default(),
    };
    Ok(CameraFile { path: path.to_path_buf(), fx, fy, cx, cy, skew, size, distortion })
}

/// Distortion from a coefficient list read from a file: an empty list is an error (write
/// zeros for "no distortion"), lengths other than 4, 5, 8, 12, 14 too.
pub fn distortion_from(c: &[f64]) -> Result<Distortion> {
    if c.is_empty() {
        return Err(CoreError::invalid("distortion", "empty coefficient list (write 0s for no distortion)"));
    }
    Distortion::from_opencv(c)
}

/// Check that a camera matrix has the pinhole form [[fx s cx] [0 fy cy] [0 0 1]].
pub fn check_k_matrix(k: &Matrix3<f64>) -> std::result::Result<(), String> {
    if k.iter().any(|v| !v.is_finite()) {
        return Err("non-finite entry in the camera matrix".into());
    }
    let tol = 1e-9 * k[(0, 0)].abs().max(1.0);
    if k[(1, 0)].abs() > tol || k[(2, 0)].abs() > 1e-9 || k[(2, 1)].abs() > 1e-9 || (k[(2, 2)] - 1.0).abs() > 1e-9 {
        return Err(format!(
            "camera matrix must be [[fx, s, cx], [0, fy, cy], [0, 0, 1]]; its last rows are [{}, {}, {}], [{}, {}, {}]",
            k[(1, 0)],
            k[(1, 1)],
            k[(1, 2)],
            k[(2, 0)],
            k[(2, 1)],
            k[(2, 2)]
        ));
    }
    Ok(())
}

fn check_distortion_model(m: &str) -> std::result::Result<(), String> {
    match m.to_ascii_lowercase().as_str() {
        "plumb_bob" | "rational_polynomial" | "brown_conrady" | "opencv" | "none" | "" => Ok(()),
        other => Err(format!("distortion_model '{other}' is not supported (plumb_bob or rational_polynomial)")),
    }
}

/// Numbers of a FileStorage node: an `!!opencv-matrix`, a list, or a ROS `{rows, cols, data}` map.
pub(crate) fn fs_numbers(n: &FsNode) -> Option<Vec<f64>> {
    match n {
        FsNode::Mat(m) => Some(m.data.clone()),
        FsNode::Map(_) => n.get("data").and_then(FsNode::numbers),
        other => other.numbers(),
    }
}

/// A camera from a FileStorage document (ROS camera_info YAML or OpenCV YAML).
pub fn camera_from_filestorage(fs: &FileStorage, path: &Path) -> Result<CameraFile> {
    let err = |m: String| CoreError::format(path, m);
    let (kkey, knode) =
        fs.get_any(&["camera_matrix", "cameraMatrix", "K", "k", "M", "M1", "K1", "cam1", "CameraMatrix"]).ok_or_else(
            || err(format!("no camera matrix (camera_matrix, K, M, ...); the file has {}", fs.keys_summary())),
        )?;
    let km = fs_numbers(knode).filter(|m| m.len() == 9).ok_or_else(|| err(format!("'{kkey}' is not 3x3 numbers")))?;
    let km = Matrix3::from_row_slice(&km);
    check_k_matrix(&km).map_err(|e| err(format!("'{kkey}': {e}")))?;
    if let Some(m) = fs.get("distortion_model").and_then(FsNode::as_str) {
        check_distortion_model(m).map_err(err)?;
    }
    let distortion = match fs.get_any(&[
        "distortion_coefficients",
        "dist_coeffs",
        "distCoeffs",
        "DistCoeffs",
        "D",
        "d",
        "D1",
        "dis1",
    ]) {
        Some((k, n)) => {
            let c = fs_numbers(n).ok_or_else(|| err(format!("'{k}' is not a list of numbers")))?;
            distortion_from(&c).map_err(|e| err(format!("'{k}': {e}")))?
        }
        None => Distortion::default(),
    };
    let w = fs.get_any(&["image_width", "width", "imageWidth"]);
    let h = fs.get_any(&["image_height", "height", "imageHeight"]);
    let size = match (w, h) {
        (Some((_, w)), Some((_, h))) => match (w.as_f64(), h.as_f64()) {
            (Some(w), Some(h))
                if w.fract() == 0.0 && h.fract() == 0.0 && w >= 1.0 && h >= 1.0 && w < 1e15 && h < 1e15 =>
            {
                Some(check_image_size(w as u64, h as u64, &path.display().to_string())?)
            }
            _ => return Err(err("image width/height are not positive integers".into())),
        },
        _ => None,
    };
    Ok(CameraFile {
        path: path.to_path_buf(),
        fx: km[(0, 0)],
        fy: km[(1, 1)],
        cx: km[(0, 2)],
        cy: km[(1, 2)],
        skew: km[(0, 1)],
        size,
        distortion,
    })
}
