//! Stereo calibration.
//!
//! [`StereoCalibration`] holds the two pinhole cameras (K, distortion) and the pose of the right
//! camera with respect to the left exactly as OpenCV's `stereoCalibrate` returns it:
//! `X_right = R · X_left + T`, T in millimetres.
//!
//! It reads
//! - OpenCV FileStorage YAML (`%YAML:1.0`, `!!opencv-matrix`): SCARED `endoscope_calibration.yaml`
//!   (`M1 D1 M2 D2 R T`), the EndoVis 2017 layout (`cam1 dis1 cam2 dis2 rot trans imageSize`),
//!   OpenCV's `stereo_calib` sample pair (`intrinsics.yml`: `M1 D1 M2 D2` + `extrinsics.yml`:
//!   `R T R1 R2 P1 P2 Q`, see [`StereoCalibration::read_pair`]) and the common key aliases
//!   (`K1`, `CameraMatrix1`, `DistCoeffs1`, ...);
//! - laparo's JSON format (see the crate README and [`StereoCalibration::write_json`]).
//!
//! The FileStorage parser lives in [`crate::io::opencv_yaml`] (re-exported here).
use crate::atomic::write_atomic;
use crate::camera::{Distortion, Intrinsics};
use crate::error::{CoreError, Result};
pub use crate::io::opencv_yaml::{read_filestorage, FileStorage, FsMatrix, FsNode};
use crate::se3::{se3_from_rt, Se3};
use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

// ---------------------------------------------------------------------------------------------
// Stereo calibration
// ---------------------------------------------------------------------------------------------

/// A calibrated stereo pair: intrinsics and distortion of each camera, and the pose of the right
/// camera w.r.t. the left as OpenCV `stereoCalibrate` gives it: `X_right = R · X_left + T`,
/// T in millimetres. Both cameras have the image size `width × height` px.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(into = "StereoJson", try_from = "StereoJson")]
pub struct StereoCalibration {
    /// Image width (px), both cameras.
    pub width: usize,
    /// Image height (px), both cameras.
    pub height: usize,
    /// Left camera intrinsics (px).
    pub left: Intrinsics,
    /// Left camera lens distortion.
    pub left_dist: Distortion,
    /// Right camera intrinsics (px).
    pub right: Intrinsics,
    /// Right camera lens distortion.
    pub right_dist: Distortion,
    /// Rotation R of `X_right = R · X_left + T`.
    pub r: Matrix3<f64>,
    /// Translation T of `X_right = R · X_left + T` (mm).
    pub t_mm: Vector3<f64>,
}

const LEFT_K: &[&str] =
    &["M1", "K1", "cam1", "CameraMatrix1", "cameraMatrix1", "camera_matrix_left", "left_camera_matrix", "KL", "K_left"];
const LEFT_D: &[&str] =
    &["D1", "dis1", "dist1", "DistCoeffs1", "distCoeffs1", "dist_coeffs_left", "left_distortion", "DL", "D_left"];
const RIGHT_K: &[&str] = &[
    "M2",
    "K2",
    "cam2",
    "CameraMatrix2",
    "cameraMatrix2",
    "camera_matrix_right",
    "right_camera_matrix",
    "KR",
    "K_right",
];
const RIGHT_D: &[&str] =
    &["D2", "dis2", "dist2", "DistCoeffs2", "distCoeffs2", "dist_coeffs_right", "right_distortion", "DR", "D_right"];
const ROT: &[&str] = &["R", "rot", "Rot", "rotation", "R_stereo"];
const TRANS: &[&str] = &["T", "trans", "Trans", "translation", "T_stereo"];
const SIZE: &[&str] = &["imageSize", "image_size", "ImageSize", "Size", "size", "imgSize", "resolution"];

/// Largest tolerated |RᵀR − I| entry and |det R − 1| for a rotation read from a file.
const ROTATION_TOL: f64 = 1e-3;

impl StereoCalibration {
    /// Check sizes, intrinsics, distortion finiteness, that R is a rotation and T finite.
    pub fn validate(&self) -> Result<()> {
        crate::io::camera_io::check_image_size(self.width as u64, self.height as u64, "stereo calibration")?;
        self.left.validate()?;
        self.right.validate()?;
        if self.left_dist.to_opencv().iter().chain(self.right_dist.to_opencv().iter()).any(|v| !v.is_finite()) {
            return Err(CoreError::invalid("stereo calibration", "non-finite distortion coefficient"));
        }
        if self.r.iter().chain(self.t_mm.iter()).any(|v| !v.is_finite()) {
            return Err(CoreError::invalid("stereo calibration", "non-finite R or T"));
        }
        let e = (self.r.transpose() * self.r - Matrix3::identity()).abs().max();
        let det = self.r.determinant();
        if e > ROTATION_TOL || (det - 1.0).abs() > ROTATION_TOL {
            return Err(CoreError::invalid(
                "stereo calibration",
                format!("R is not a rotation (max |RᵀR − I| = {e:.2e}, det = {det:.6})"),
            ));
        }
        Ok(())
    }

    /// The rigid transform mapping left-camera coordinates to right-camera coordinates (mm).
    pub fn right_from_left(&self) -> Se3 {
        se3_from_rt(&self.r, &self.t_mm)
    }

    /// Baseline |T| in millimetres.
    pub fn baseline_mm(&self) -> f64 {
        self.t_mm.norm()
    }

    /// Angle of the relative rotation R in degrees.
    pub fn relative_rotation_deg(&self) -> f64 {
        ((self.r.trace() - 1.0) / 2.0).clamp(-1.0, 1.0).acos().to_degrees()
    }

    /// Read a calibration: JSON (by `.json` extension or a leading `{`), the EndoVis 2017
    /// `camera_calibration.txt` (`Camera-0-F: ...` lines), Middlebury `calib.txt` (`cam0=[...]`)
    /// or OpenCV FileStorage YAML.
    /// The image size must be in the file; otherwise use [`StereoCalibration::read_with_size`].
    pub fn read(path: impl AsRef<Path>) -> Result<Self> {
        Self::read_impl(path.as_ref(), None)
    }

    /// Like [`read`](Self::read) for files that do not state the image size (SCARED's
    /// `endoscope_calibration.yaml` does not: it is 1280×1024). A size in the file must agree.
    pub fn read_with_size(path: impl AsRef<Path>, width: usize, height: usize) -> Result<Self> {
        Self::read_impl(path.as_ref(), Some((width, height)))
    }

    fn read_impl(path: &Path, size: Option<(usize, usize)>) -> Result<Self> {
        let bytes = std::fs::read(path).map_err(|e| CoreError::io(path, e))?;
        let text = String::from_utf8(bytes).map_err(|_| CoreError::format(path, "not UTF-8 text"))?;
        let is_json = crate::io::extension(path) == "json" || text.trim_start().starts_with('{');
        if text.lines().any(|l| l.trim_start().starts_with("Camera-0-F")) {
            return crate::io::calib_formats::parse_endovis_txt(&text, path, size);
        }
        if text.lines().any(|l| l.trim_start().starts_with("cam0") && l.contains('=')) {
            let c = crate::io::calib_formats::parse_middlebury_calib(&text, path)?;
            if let Some((w, h)) = size {
                if (w, h) != (c.width, c.height) {
                    return Err(CoreError::format(
                        path,
                        format!("file says {}x{}, caller says {w}x{h}", c.width, c.height),
                    ));
                }
            }
            return Ok(c);
        }
        if !is_json && crate::io::extension(path) == "txt" {
            return Err(CoreError::format(
                path,
                "a text file that is not an EndoVis camera_calibration.txt: COLMAP cameras.txt holds no stereo \
                 extrinsics (use it as --intrinsics); a stereo calibration needs R and T",
            ));
        }
        let c = if is_json {
            let j: StereoJson = serde_json::from_str(&text)
                .map_err(|e| CoreError::format(path, format!("not a laparo stereo calibration JSON: {e}")))?;
            let c = Self::try_from(j).map_err(|e| CoreError::format(path, e))?;
            if let Some((w, h)) = size {
                if (w, h) != (c.width, c.height) {
                    return Err(CoreError::format(
                        path,
                        format!("file says {}x{}, caller says {w}x{h}", c.width, c.height),
                    ));
                }
            }
            c
        } else {
            let fs = FileStorage::parse(&text, path)?;
            if crate::io::calib_formats::is_ros_camera_info(&fs) {
                return Err(CoreError::format(
                    path,
                    "a ROS camera_info file describes one camera: give the left and the right file as a pair",
                ));
            }
            Self::from_filestorage(&fs, size)?
        };
        Ok(c)
    }

    /// Read a two-file calibration: OpenCV's `stereo_calib` layout, `intrinsics` (M1 D1 M2 D2) and
    /// `extrinsics` (R T, plus rectification R1 R2 P1 P2 Q which are ignored), or a left/right
    /// pair of ROS `camera_info` YAML files (see [`crate::io::calib_formats`]). The size must be
    /// in one of them.
    pub fn read_pair(intrinsics: impl AsRef<Path>, extrinsics: impl AsRef<Path>) -> Result<Self> {
        Self::read_pair_impl(intrinsics.as_ref(), extrinsics.as_ref(), None)
    }

    /// [`read_pair`](Self::read_pair) with the image size given by the caller.
    pub fn read_pair_with_size(
        intrinsics: impl AsRef<Path>,
        extrinsics: impl AsRef<Path>,
        width: usize,
        height: usize,
    ) -> Result<Self> {
        Self::read_pair_impl(intrinsics.as_ref(), extrinsics.as_ref(), Some((width, height)))
    }

    fn read_pair_impl(intr: &Path, extr: &Path, size: Option<(usize, usize)>) -> Result<Self> {
        let a = read_filestorage(intr)?;
        let b = read_filestorage(extr)?;
        if crate::io::calib_formats::is_ros_camera_info(&a) && crate::io::calib_formats::is_ros_camera_info(&b) {
            return crate::io::calib_formats::read_ros_pair(&a, &b, size);
        }
        let mut merged = a.clone();
        merged.path = PathBuf::from(format!("{} + {}", intr.display(), extr.display()));
        for (k, v) in b.entries {
            if merged.get(&k).is_none() {
                merged.entries.push((k, v));
            }
        }
        Self::from_filestorage(&merged, size)
    }

    /// Interpret a parsed FileStorage document (see the module doc for the accepted keys).
    pub fn from_filestorage(fs: &FileStorage, size: Option<(usize, usize)>) -> Result<Self> {
        let path = &fs.path;
        let need = |keys: &[&str], what: &str| -> Result<FsMatrix> {
            match fs.get_any(keys) {
                Some((k, _)) => fs.matrix(k),
                None => Err(CoreError::format(
                    path,
                    format!("no {what} (looked for {keys:?}; the file has {})", fs.keys_summary()),
                )),
            }
        };
        let k1 = need(LEFT_K, "left camera matrix")?;
        let k2 = need(RIGHT_K, "right camera matrix")?;
        let d1 = need(LEFT_D, "left distortion")?;
        let d2 = need(RIGHT_D, "right distortion")?;
        let r = fs.get_any(ROT).map(|(k, _)| fs.matrix(k)).transpose()?;
        let t = fs.get_any(TRANS).map(|(k, _)| fs.matrix(k)).transpose()?;
        let (r, t) = match (r, t) {
            (Some(r), Some(t)) => (r, t),
            _ => {
                return Err(CoreError::format(
                    path,
                    "no stereo extrinsics R and T (for OpenCV's two-file intrinsics/extrinsics layout use \
                     StereoCalibration::read_pair)",
                ))
            }
        };
        let m3 = |m: &FsMatrix, what: &str| {
            m.to_matrix3()
                .ok_or_else(|| CoreError::format(path, format!("{what} is {}x{}, expected 3x3", m.rows, m.cols)))
        };
        let k3 = |m: &FsMatrix, what: &str| -> Result<Matrix3<f64>> {
            let k = m3(m, what)?;
            crate::io::camera_io::check_k_matrix(&k).map_err(|e| CoreError::format(path, format!("{what}: {e}")))?;
            Ok(k)
        };
        let dist = |m: &FsMatrix, what: &str| -> Result<Distortion> {
            crate::io::camera_io::distortion_from(&m.data).map_err(|e| CoreError::format(path, format!("{what}: {e}")))
        };
        let file_size = Self::size_from(fs)?;
        let (width, height) = match (file_size, size) {
            (Some(f), Some(s)) if f != s => {
                return Err(CoreError::format(
                    path,
                    format!("file says image size {}x{}, caller says {}x{}", f.0, f.1, s.0, s.1),
                ))
            }
            (Some(f), _) => f,
            (None, Some(s)) => s,
            (None, None) => {
                return Err(CoreError::format(
                    path,
                    "no image size in the file (image_width/image_height, imageSize or Size); pass it \
                     with read_with_size (SCARED: 1280x1024)",
                ))
            }
        };
        let fmt = |e: CoreError| CoreError::format(path, e.to_string());
        let t_mm = t
            .to_vector3()
            .ok_or_else(|| CoreError::format(path, format!("T is {}x{}, expected 3x1", t.rows, t.cols)))?;
        let c = StereoCalibration {
            width,
            height,
            left: Intrinsics::from_matrix(&k3(&k1, "left camera matrix")?, width, height).map_err(fmt)?,
            left_dist: dist(&d1, "left distortion")?,
            right: Intrinsics::from_matrix(&k3(&k2, "right camera matrix")?, width, height).map_err(fmt)?,
            right_dist: dist(&d2, "right distortion")?,
            r: m3(&r, "R")?,
            t_mm,
        };
        c.validate().map_err(fmt)?;
        Ok(c)
    }

    fn size_from(fs: &FileStorage) -> Result<Option<(usize, usize)>> {
        let bad =
            |what: &str| CoreError::format(&fs.path, format!("image size entry '{what}' is not two positive integers"));
        if let (Some(w), Some(h)) = (
            fs.get_any(&["image_width", "imageWidth", "width", "ImageWidth"]),
            fs.get_any(&["image_height", "imageHeight", "height", "ImageHeight"]),
        ) {
            return match (w.1.as_usize(), h.1.as_usize()) {
                (Some(w), Some(h)) if w > 0 && h > 0 => {
                    crate::io::camera_io::check_image_size(w as u64, h as u64, &fs.path.display().to_string()).map(Some)
                }
                _ => Err(bad("image_width/image_height")),
            };
        }
        if let Some((k, v)) = fs.get_any(SIZE) {
            let wh = match v {
                FsNode::Map(_) => {
                    match (v.get("width").and_then(FsNode::as_usize), v.get("height").and_then(FsNode::as_usize)) {
                        (Some(w), Some(h)) => vec![w as f64, h as f64],
                        _ => return Err(bad(k)),
                    }
                }
                _ => v.numbers().ok_or_else(|| bad(k))?,
            };
            return match wh.as_slice() {
                [w, h] if *w >= 1.0 && *h >= 1.0 && w.fract() == 0.0 && h.fract() == 0.0 && *w < 1e15 && *h < 1e15 => {
                    crate::io::camera_io::check_image_size(*w as u64, *h as u64, &fs.path.display().to_string())
                        .map(Some)
                }
                _ => Err(bad(k)),
            };
        }
        Ok(None)
    }

    /// The calibration as a FileStorage document (`image_width`, `image_height`, `M1 D1 M2 D2 R T`).
    pub fn to_filestorage(&self) -> FileStorage {
        let mat = |rows: usize, cols: usize, data: Vec<f64>| {
            FsNode::Mat(FsMatrix { rows, cols, channels: 1, dt: "d".into(), data })
        };
        let m3 = |m: &Matrix3<f64>| mat(3, 3, (0..9).map(|i| m[(i / 3, i % 3)]).collect());
        let dv = |d: &Distortion| {
            let v = d.to_opencv();
            mat(1, v.len(), v)
        };
        FileStorage {
            path: PathBuf::new(),
            entries: vec![
                ("image_width".into(), FsNode::Int(self.width as i64)),
                ("image_height".into(), FsNode::Int(self.height as i64)),
                ("M1".into(), m3(&self.left.matrix())),
                ("D1".into(), dv(&self.left_dist)),
                ("M2".into(), m3(&self.right.matrix())),
                ("D2".into(), dv(&self.right_dist)),
                ("R".into(), m3(&self.r)),
                ("T".into(), mat(3, 1, self.t_mm.iter().copied().collect())),
            ],
        }
    }

    /// Write as OpenCV FileStorage YAML (SCARED layout plus `image_width`/`image_height`), atomically.
    pub fn write_opencv_yaml(&self, path: impl AsRef<Path>) -> Result<()> {
        self.to_filestorage().write(path)
    }

    /// Write laparo's JSON calibration format (documented in the crate README), atomically.
    pub fn write_json(&self, path: impl AsRef<Path>) -> Result<()> {
        let path = path.as_ref();
        let s = serde_json::to_string_pretty(&StereoJson::from(self.clone()))
            .map_err(|e| CoreError::format(path, format!("cannot encode JSON: {e}")))?;
        write_atomic(path, (s + "\n").as_bytes())
    }
}

/// One camera in the JSON format: K (3×3, rows) and OpenCV-order distortion (4, 5, 8, 12 or 14).
#[derive(Clone, Debug, Serialize, Deserialize)]
struct CameraJson {
    #[serde(rename = "K")]
    k: [[f64; 3]; 3],
    #[serde(default)]
    dist: Vec<f64>,
}

/// The JSON calibration format (see the crate README).
#[derive(Clone, Debug, Serialize, Deserialize)]
struct StereoJson {
    #[serde(default = "format_tag")]
    format: String,
    width: usize,
    height: usize,
    left: CameraJson,
    right: CameraJson,
    #[serde(rename = "R")]
    r: [[f64; 3]; 3],
    #[serde(rename = "T_mm", alias = "T")]
    t_mm: [f64; 3],
}

fn format_tag() -> String {
    "laparo-stereo-calibration-v1".into()
}

impl From<StereoCalibration> for StereoJson {
    fn from(c: StereoCalibration) -> Self {
        let rows = |m: &Matrix3<f64>| {
            [[m[(0, 0)], m[(0, 1)], m[(0, 2)]], [m[(1, 0)], m[(1, 1)], m[(1, 2)]], [m[(2, 0)], m[(2, 1)], m[(2, 2)]]]
        };
        StereoJson {
            format: format_tag(),
            width: c.width,
            height: c.height,
            left: CameraJson { k: rows(&c.left.matrix()), dist: c.left_dist.to_opencv() },
            right: CameraJson { k: rows(&c.right.matrix()), dist: c.right_dist.to_opencv() },
            r: rows(&c.r),
            t_mm: [c.t_mm.x, c.t_mm.y, c.t_mm.z],
        }
    }
}

impl TryFrom<StereoJson> for StereoCalibration {
    type Error = String;
    fn try_from(j: StereoJson) -> std::result::Result<Self, String> {
        if !j.format.starts_with("laparo-stereo-calibration") {
            return Err(format!("unknown format tag '{}'", j.format));
        }
        let m = |a: &[[f64; 3]; 3]| Matrix3::from_fn(|r, c| a[r][c]);
        crate::io::camera_io::check_image_size(j.width as u64, j.height as u64, "width/height")
            .map_err(|e| e.to_string())?;
        crate::io::camera_io::check_k_matrix(&m(&j.left.k)).map_err(|e| format!("left: {e}"))?;
        crate::io::camera_io::check_k_matrix(&m(&j.right.k)).map_err(|e| format!("right: {e}"))?;
        let c = StereoCalibration {
            width: j.width,
            height: j.height,
            left: Intrinsics::from_matrix(&m(&j.left.k), j.width, j.height).map_err(|e| format!("left: {e}"))?,
            left_dist: Distortion::from_opencv(&j.left.dist).map_err(|e| format!("left: {e}"))?,
            right: Intrinsics::from_matrix(&m(&j.right.k), j.width, j.height).map_err(|e| format!("right: {e}"))?,
            right_dist: Distortion::from_opencv(&j.right.dist).map_err(|e| format!("right: {e}"))?,
            r: m(&j.r),
            t_mm: Vector3::from(j.t_mm),
        };
        c.validate().map_err(|e| e.to_string())?;
        Ok(c)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn data_dir() -> PathBuf {
        PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data/calib"))
    }

    fn sample_calib() -> StereoCalibration {
        StereoCalibration {
            width: 1280,
            height: 1024,
            left: Intrinsics::new(1035.30811, 1035.08765, 596.955017, 520.410034, 1280, 1024).unwrap(),
            left_dist: Distortion::brown_conrady(-0.000595157442, -0.000546629308, 0.0, 0.0, 0.00182959007),
            right: Intrinsics::new(1035.17419, 1034.979, 688.361877, 521.070801, 1280, 1024).unwrap(),
            right_dist: Distortion::from_opencv(&[0.1, -0.2, 0.001, 0.002, 0.3, 0.01, 0.02, 0.03]).unwrap(),
            r: crate::se3::rotation_zyx(0.01, -0.02, 0.003),
            t_mm: Vector3::new(-4.14339018, -0.0238197036, -0.00190685259),
        }
    }

    #[test]
    fn json_and_yaml_round_trip_bit_exact() {
        let dir = tempfile::tempdir().unwrap();
        let c = sample_calib();
        let j = dir.path().join("c.json");
        c.write_json(&j).unwrap();
        assert_eq!(StereoCalibration::read(&j).unwrap(), c);
        let y = dir.path().join("c.yaml");
        c.write_opencv_yaml(&y).unwrap();
        assert_eq!(StereoCalibration::read(&y).unwrap(), c);
        // serde embedding uses the same JSON shape
        let v = serde_json::to_value(&c).unwrap();
        assert_eq!(v["T_mm"][0], serde_json::json!(-4.14339018));
        assert_eq!(v["left"]["K"][0][2], serde_json::json!(596.955017));
        let back: StereoCalibration = serde_json::from_value(v).unwrap();
        assert_eq!(back, c);
    }

    #[test]
    fn bad_calibrations_are_rejected() {
        let dir = tempfile::tempdir().unwrap();
        let mut c = sample_calib();
        c.r[(0, 0)] = 2.0;
        assert!(c.validate().is_err());
        let p = dir.path().join("bad.yaml");
        c.to_filestorage().write(&p).unwrap();
        let e = StereoCalibration::read(&p).unwrap_err().to_string();
        assert!(e.contains("bad.yaml") && e.contains("rotation"), "{e}");
        let p = dir.path().join("bad.json");
        std::fs::write(&p, "{\"width\": 10}").unwrap();
        assert!(StereoCalibration::read(&p).unwrap_err().to_string().contains("bad.json"));
        // size given and stated differently
        let ok = dir.path().join("ok.yaml");
        sample_calib().write_opencv_yaml(&ok).unwrap();
        let e = StereoCalibration::read_with_size(&ok, 640, 480).unwrap_err().to_string();
        assert!(e.contains("1280x1024") && e.contains("640x480"), "{e}");
    }

    /// Regression (issue 10): a K whose last row is not [0 0 1], an empty distortion vector and
    /// absurd image sizes were accepted (or panicked / allocated without bound downstream).
    #[test]
    fn malformed_calibration_values_are_clear_errors() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("c.yaml");
        sample_calib().write_opencv_yaml(&p).unwrap();
        let good = std::fs::read_to_string(&p).unwrap();
        let fs = FileStorage::parse(&good, "c.yaml").unwrap();
        let with = |key: &str, node: FsNode| {
            let mut f = fs.clone();
            for (k, v) in f.entries.iter_mut() {
                if k == key {
                    *v = node.clone();
                }
            }
            f.write(&p).unwrap();
            StereoCalibration::read(&p).unwrap_err().to_string()
        };
        let mut k = sample_calib().left.matrix();
        k[(2, 2)] = 2.0;
        let m = FsNode::Mat(FsMatrix::new(3, 3, (0..9).map(|i| k[(i / 3, i % 3)]).collect()).unwrap());
        let e = with("M1", m);
        assert!(e.contains("c.yaml") && e.contains("[0, 0, 1]"), "{e}");
        let e = with("D2", FsNode::Mat(FsMatrix::new(0, 0, vec![]).unwrap()));
        assert!(e.contains("c.yaml") && e.contains("empty"), "{e}");
        let e = with("image_width", FsNode::Int(i64::MAX));
        assert!(e.contains("c.yaml") && e.contains("out of range"), "{e}");
        let e = with("image_height", FsNode::Int(100_000));
        assert!(e.contains("out of range"), "{e}");
        let e = with("T", FsNode::Mat(FsMatrix::new(3, 1, vec![f64::NAN, 0.0, 0.0]).unwrap()));
        assert!(e.contains("c.yaml") && e.contains("non-finite"), "{e}");
        // Caller-given sizes are bounded too (cats stats --width/--height, stereo --width).
        let scared = "%YAML:1.0\nM1: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 1000., 0., 600., 0., 1000., 500., 0., 0., 1. ]\n\
D1: [ 0., 0., 0., 0., 0. ]\nM2: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 1000., 0., 600., 0., 1000., 500., 0., 0., 1. ]\n\
D2: [ 0., 0., 0., 0., 0. ]\nR: [ 1., 0., 0., 0., 1., 0., 0., 0., 1. ]\nT: [ -5., 0., 0. ]\n";
        std::fs::write(&p, scared).unwrap();
        assert!(StereoCalibration::read_with_size(&p, 1280, 1024).is_ok());
        let e = StereoCalibration::read_with_size(&p, i64::MAX as usize, 1).unwrap_err().to_string();
        assert!(e.contains("out of range"), "{e}");
        let e = StereoCalibration::read_with_size(&p, 100_000, 100_000).unwrap_err().to_string();
        assert!(e.contains("out of range"), "{e}");
        // imageSize with i64::MAX
        std::fs::write(&p, format!("{scared}imageSize: [ 9223372036854775807, 1024 ]\n")).unwrap();
        assert!(StereoCalibration::read(&p).unwrap_err().to_string().contains("c.yaml"));
    }

    #[test]
    fn real_scared_calibrations() {
        let dir = data_dir();
        let p = dir.join("scared_ds1-3_endoscope_calibration.yaml");
        if !p.exists() {
            eprintln!("SKIP real_scared_calibrations: {} absent", dir.display());
            return;
        }
        // SCARED files do not state the size.
        let e = StereoCalibration::read(&p).unwrap_err().to_string();
        assert!(e.contains("read_with_size") && e.contains("scared_ds1-3"), "{e}");
        let c = StereoCalibration::read_with_size(&p, 1280, 1024).unwrap();
        assert_eq!(c.left.fx, 1035.30811);
        assert_eq!(c.right.cx, 688.361877);
        assert_eq!(c.left_dist.k3, 0.00182959007);
        assert_eq!(c.t_mm.x, -4.14339018);
        assert_eq!(c.r[(0, 1)], 1.94856493e-05);
        assert!((c.baseline_mm() - 4.1435).abs() < 1e-3);
        assert!(c.relative_rotation_deg() < 0.02);
        for f in ["scared_ds4-5_endoscope_calibration.yaml", "scared_ds8_endoscope_calibration.yaml"] {
            let c = StereoCalibration::read_with_size(dir.join(f), 1280, 1024).unwrap();
            assert!(c.baseline_mm() > 4.0 && c.baseline_mm() < 4.5, "{f}");
            assert!(c.t_mm.x < 0.0, "{f}: right camera is to the +x of the left, so T.x < 0");
        }
    }

    #[test]
    #[allow(clippy::excessive_precision)]
    fn real_ris2017_calibration() {
        let p = data_dir().join("ris2017_kidney_ghattab_camera2.yml");
        if !p.exists() {
            eprintln!("SKIP real_ris2017_calibration: {} absent", p.display());
            return;
        }
        let c = StereoCalibration::read(&p).unwrap();
        assert_eq!((c.width, c.height), (1280, 1024));
        assert_eq!(c.left.fx, 1068.39);
        assert_eq!(c.right.cx, 698.22);
        assert_eq!(c.right_dist.k2, 0.00403);
        assert_eq!(c.t_mm, Vector3::new(-4.2773, -0.0440, -0.0303));
        assert_eq!(c.r[(0, 2)], -0.0013);
        let fs = read_filestorage(&p).unwrap();
        let p2 = fs.matrix("P2").unwrap();
        assert_eq!((p2.rows, p2.cols), (3, 4));
        assert_eq!(p2.get(0, 3), -2.9531842436268389e+03);
    }

    #[test]
    #[allow(clippy::excessive_precision)]
    fn real_questionable_stereo_calib_pair() {
        let d = data_dir().join("questionable");
        let (i, e) = (d.join("dvrk_student_intrinsics.yml"), d.join("dvrk_student_extrinsics.yml"));
        if !i.exists() {
            eprintln!("SKIP real_questionable_stereo_calib_pair: {} absent", d.display());
            return;
        }
        let err = StereoCalibration::read_with_size(&i, 640, 480).unwrap_err().to_string();
        assert!(err.contains("read_pair"), "{err}");
        let err = StereoCalibration::read_pair(&i, &e).unwrap_err().to_string();
        assert!(err.contains("image size"), "{err}");
        let c = StereoCalibration::read_pair_with_size(&i, &e, 640, 480).unwrap();
        assert_eq!(c.left.fx, 7.6708803985990880e+02);
        assert_eq!(c.left_dist.k6, 2.1677690293834040e+00);
        assert_eq!(c.right_dist.k6, -2.2090680312824404e+00);
        assert_eq!(c.t_mm.z, 2.0633522772376783e-01);
        // README: "~2 deg relative rotation"
        let a = c.relative_rotation_deg();
        assert!(a > 1.5 && a < 3.0, "{a}");
    }
}
