//! `laparo.features`: SIFT / ORB keypoints and descriptors (thesis §4.2), 2-NN matching with
//! Lowe's or VLFeat's ratio test and a mutual check (§4.5), RANSAC-MSAC homography, fundamental
//! and essential matrices, and the two-way transfer error of §4.5.1.
use crate::arrays::*;
use laparo_core::Image;
use laparo_features::refcheck::{apply_h, invert_h};
use laparo_features::{
    detect_and_describe, find_essential, find_fundamental, find_homography, match_features, Descriptors,
    DetectorConfig, Features, Keypoint, MatchConfig, RansacParams, RatioTest, RobustFit,
};
use nalgebra::Matrix3;
use numpy::{PyArrayDyn, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// Keypoint columns of the (N, 6) arrays: x, y (px, pixel centres at integers), size (px),
/// angle (rad), response, octave.
const KP_COLS: usize = 6;

fn image_u8(obj: &Bound<'_, PyAny>, arg: &str) -> PyResult<Image<u8>> {
    let a = u8_array(obj, arg)?;
    let (h, w, c) = a.hwc(arg)?;
    if c != 1 && c != 3 && c != 4 {
        return Err(bad(arg, format!("{c} channels (expected 1, 3 or 4)")));
    }
    Image::from_vec(w, h, c, a.data).map_err(|e| bad(arg, e))
}

fn mask_for(
    obj: Option<&Bound<'_, PyAny>>,
    arg: &str,
    w: usize,
    h: usize,
) -> PyResult<Option<laparo_core::image::Mask>> {
    let Some(o) = obj else { return Ok(None) };
    let a = bool_array(o, arg)?;
    let (mh, mw) = a.hw(arg)?;
    if (mw, mh) != (w, h) {
        return Err(bad(arg, format!("shape ({mh}, {mw}) differs from the image's ({h}, {w})")));
    }
    Ok(Some(Image::from_vec(w, h, 1, a.data).map_err(|e| bad(arg, e))?))
}

/// A detector from a name (`sift`, `orb`) or a dict of a `DetectorConfig` (`{"Sift": {...}}`).
fn detector(obj: &Bound<'_, PyAny>) -> PyResult<DetectorConfig> {
    if let Ok(s) = obj.extract::<String>() {
        return DetectorConfig::by_name(&s).map_err(|e| bad("detector", e));
    }
    let v = py_to_json(obj, "detector")?;
    serde_json::from_value(v).map_err(|e| bad("detector", format!("not a detector configuration: {e}")))
}

/// Parse a ratio test: `lowe:R`, `ubc:T` or `none` (as `laparo features match --ratio`).
pub fn parse_ratio(s: &str) -> PyResult<RatioTest> {
    let t = s.trim().to_ascii_lowercase();
    if t == "none" {
        return Ok(RatioTest::None);
    }
    let (kind, v) = t.split_once(':').ok_or_else(|| bad("ratio", format!("{s:?}: expected lowe:R, ubc:T or none")))?;
    let v: f32 = v.parse().map_err(|_| bad("ratio", format!("{s:?}: {v:?} is not a number")))?;
    match kind {
        "lowe" => Ok(RatioTest::Lowe(v)),
        "ubc" => Ok(RatioTest::Ubc(v)),
        _ => Err(bad("ratio", format!("{s:?}: expected lowe:R, ubc:T or none"))),
    }
}

fn keypoints_array(kps: &[Keypoint]) -> Vec<f64> {
    kps.iter().flat_map(|k| [k.x, k.y, k.size_px, k.angle_rad, k.response, k.octave as f64]).collect()
}

fn descriptors_numpy<'py>(py: Python<'py>, d: Descriptors) -> PyResult<Bound<'py, PyAny>> {
    match d {
        Descriptors::Float { dim, data } => {
            let n = data.len().checked_div(dim).unwrap_or(0);
            to_numpy(py, data, &[n, dim])
        }
        Descriptors::Binary { bytes, data } => {
            let n = data.len().checked_div(bytes).unwrap_or(0);
            to_numpy(py, data, &[n, bytes])
        }
    }
}

fn features_dict<'py>(py: Python<'py>, f: Features, det: &DetectorConfig) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let n = f.len();
    d.set_item("keypoints", to_numpy(py, keypoints_array(&f.keypoints), &[n, KP_COLS])?)?;
    d.set_item("descriptors", descriptors_numpy(py, f.descriptors)?)?;
    d.set_item("detector", to_py(py, det)?)?;
    Ok(d)
}

/// Detect keypoints and compute descriptors of one 8-bit image (grey, RGB or RGBA; colour is
/// converted to Rec. 601 luma). Returns keypoints (N, 6) float64, descriptors (N, 128) float32
/// (SIFT) or (N, 32) uint8 (ORB), and the detector configuration.
#[pyfunction]
#[pyo3(signature = (image, detector = None, mask = None))]
pub fn features_detect<'py>(
    py: Python<'py>,
    image: &Bound<'py, PyAny>,
    detector: Option<&Bound<'py, PyAny>>,
    mask: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    guard(|| {
        let det = match detector {
            Some(d) => self::detector(d)?,
            None => DetectorConfig::by_name("sift").map_err(lib_err)?,
        };
        let img = image_u8(image, "image")?;
        let m = mask_for(mask, "mask", img.width, img.height)?;
        let f = par(py, || detect_and_describe(&img, &det, m.as_ref())).map_err(lib_err)?;
        features_dict(py, f, &det)
    })
}

/// Descriptors from an (N, D) float32/float64 (float descriptors) or uint8 (binary) array.
fn descriptors_from(obj: &Bound<'_, PyAny>, arg: &str) -> PyResult<Descriptors> {
    if let Ok(a) = obj.cast::<PyArrayDyn<u8>>() {
        if !a.is_c_contiguous() {
            return Err(bad(arg, "array is not C-contiguous (use numpy.ascontiguousarray)"));
        }
        let ro = a.readonly();
        let [_, bytes] = ro.shape() else {
            return Err(bad(arg, format!("expected shape (N, bytes), got {:?}", ro.shape())));
        };
        if *bytes == 0 {
            return Err(bad(arg, "descriptors of 0 bytes"));
        }
        return Ok(Descriptors::Binary { bytes: *bytes, data: ro.as_slice().map_err(|e| bad(arg, e))?.to_vec() });
    }
    let a = f32_array(obj, arg).map_err(|e| {
        if e.is_instance_of::<PyTypeError>(obj.py()) {
            PyTypeError::new_err(format!(
                "{arg}: expected a numpy.ndarray of dtype float32 (SIFT) or uint8 (ORB); {}",
                e.value(obj.py())
            ))
        } else {
            e
        }
    })?;
    let [_, dim] = a.shape.as_slice() else {
        return Err(bad(arg, format!("expected shape (N, dim), got {:?}", a.shape)));
    };
    if *dim == 0 {
        return Err(bad(arg, "descriptors of dimension 0"));
    }
    if let Some(i) = a.data.iter().position(|v| !v.is_finite()) {
        return Err(bad(arg, format!("contains a non-finite value at flat index {i}")));
    }
    Ok(Descriptors::Float { dim: *dim, data: a.data })
}

fn dummy_features(d: Descriptors) -> Features {
    let n = d.len();
    let k = Keypoint { x: 0.0, y: 0.0, size_px: 0.0, angle_rad: 0.0, response: 0.0, octave: 0 };
    Features { keypoints: vec![k; n], descriptors: d }
}

/// Match descriptors of image 1 to those of image 2: 2-NN, ratio test (`lowe:R`, `ubc:T`,
/// `none`), optional mutual check. Returns (M, 2) int64 indices (i1, i2), sorted by i1, and (M,)
/// float32 distances (L2, or Hamming bits).
#[pyfunction]
#[pyo3(signature = (descriptors1, descriptors2, ratio = "lowe:0.8", mutual = true))]
pub fn features_match<'py>(
    py: Python<'py>,
    descriptors1: &Bound<'py, PyAny>,
    descriptors2: &Bound<'py, PyAny>,
    ratio: &str,
    mutual: bool,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    guard(|| {
        let cfg = MatchConfig { ratio: parse_ratio(ratio)?, mutual };
        let a = descriptors_from(descriptors1, "descriptors1")?;
        let b = descriptors_from(descriptors2, "descriptors2")?;
        match (&a, &b) {
            (Descriptors::Float { dim: x, .. }, Descriptors::Float { dim: y, .. }) if x != y => {
                return Err(bad("descriptors2", format!("dimension {y} differs from descriptors1's {x}")))
            }
            (Descriptors::Binary { bytes: x, .. }, Descriptors::Binary { bytes: y, .. }) if x != y => {
                return Err(bad("descriptors2", format!("{y} bytes per descriptor, descriptors1 has {x}")))
            }
            (Descriptors::Float { .. }, Descriptors::Binary { .. })
            | (Descriptors::Binary { .. }, Descriptors::Float { .. }) => {
                return Err(PyTypeError::new_err(
                    "descriptors2: dtype differs from descriptors1's (float vs binary descriptors)",
                ))
            }
            _ => {}
        }
        let (fa, fb) = (dummy_features(a), dummy_features(b));
        let m = par(py, || match_features(&fa, &fb, &cfg)).map_err(lib_err)?;
        let idx: Vec<i64> = m.iter().flat_map(|m| [m.i1 as i64, m.i2 as i64]).collect();
        let dist: Vec<f32> = m.iter().map(|m| m.distance).collect();
        Ok((to_numpy(py, idx, &[m.len(), 2])?, to_numpy(py, dist, &[m.len()])?))
    })
}

fn points(obj: &Bound<'_, PyAny>, arg: &str) -> PyResult<Vec<[f64; 2]>> {
    with_f64(obj, arg, |shape, d| {
        match shape {
            [_, 2] => {}
            s => return Err(bad(arg, format!("expected shape (N, 2), got {s:?}"))),
        }
        if let Some(i) = d.iter().position(|v| !v.is_finite()) {
            return Err(bad(arg, format!("contains a non-finite value at flat index {i}")));
        }
        Ok(d.chunks_exact(2).map(|p| [p[0], p[1]]).collect())
    })
}

fn ransac_params(threshold_px: f64, confidence: f64, max_iters: usize, seed: u64) -> PyResult<RansacParams> {
    if !(threshold_px > 0.0 && threshold_px.is_finite()) {
        return Err(bad("threshold_px", format!("{threshold_px} (must be > 0)")));
    }
    if !(confidence > 0.0 && confidence < 1.0) {
        return Err(bad("confidence", format!("{confidence} (must be in (0, 1))")));
    }
    if max_iters == 0 {
        return Err(bad("max_iters", "must be ≥ 1"));
    }
    Ok(RansacParams { threshold_px, confidence, max_iters, seed })
}

fn fit_dict<'py>(py: Python<'py>, f: RobustFit<Matrix3<f64>>) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let m: Vec<f64> = (0..9).map(|k| f.model[(k / 3, k % 3)]).collect();
    d.set_item("model", to_numpy(py, m, &[3, 3])?)?;
    let n = f.inliers.len();
    d.set_item("inliers", to_numpy(py, f.inliers, &[n])?)?;
    d.set_item("rms_px", f.rms_px)?;
    d.set_item("n_inliers", f.n_inliers)?;
    d.set_item("iterations", f.iterations)?;
    Ok(d)
}

type Fitter = fn(&[[f64; 2]], &[[f64; 2]], &RansacParams) -> laparo_features::Result<RobustFit<Matrix3<f64>>>;

#[allow(clippy::too_many_arguments)]
fn robust<'py>(
    py: Python<'py>,
    fit: Fitter,
    p1: &Bound<'py, PyAny>,
    p2: &Bound<'py, PyAny>,
    threshold_px: f64,
    confidence: f64,
    max_iters: usize,
    seed: u64,
) -> PyResult<Bound<'py, PyDict>> {
    guard(|| {
        let prm = ransac_params(threshold_px, confidence, max_iters, seed)?;
        let (a, b) = (points(p1, "p1")?, points(p2, "p2")?);
        if a.len() != b.len() {
            return Err(bad("p2", format!("{} points, p1 has {}", b.len(), a.len())));
        }
        let f = par(py, || fit(&a, &b, &prm)).map_err(lib_err)?;
        fit_dict(py, f)
    })
}

/// RANSAC-MSAC homography p2 ~ H p1 (px; forward transfer error), refined on the inliers.
#[pyfunction]
#[pyo3(signature = (p1, p2, threshold_px = 1.0, confidence = 0.999, max_iters = 10000, seed = 0))]
pub fn features_find_homography<'py>(
    py: Python<'py>,
    p1: &Bound<'py, PyAny>,
    p2: &Bound<'py, PyAny>,
    threshold_px: f64,
    confidence: f64,
    max_iters: usize,
    seed: u64,
) -> PyResult<Bound<'py, PyDict>> {
    robust(py, find_homography, p1, p2, threshold_px, confidence, max_iters, seed)
}

/// RANSAC-MSAC fundamental matrix x2ᵀ F x1 = 0 (px; Sampson distance).
#[pyfunction]
#[pyo3(signature = (p1, p2, threshold_px = 1.0, confidence = 0.999, max_iters = 10000, seed = 0))]
pub fn features_find_fundamental<'py>(
    py: Python<'py>,
    p1: &Bound<'py, PyAny>,
    p2: &Bound<'py, PyAny>,
    threshold_px: f64,
    confidence: f64,
    max_iters: usize,
    seed: u64,
) -> PyResult<Bound<'py, PyDict>> {
    robust(py, find_fundamental, p1, p2, threshold_px, confidence, max_iters, seed)
}

/// RANSAC-MSAC essential matrix from ≥ 5 normalised points (K⁻¹ x; threshold in normalised units):
/// Stewénius–Engels–Nistér 5-point minimal solver, local optimisation on each new best.
#[pyfunction]
#[pyo3(signature = (p1, p2, threshold = 1e-3, confidence = 0.999, max_iters = 10000, seed = 0))]
pub fn features_find_essential<'py>(
    py: Python<'py>,
    p1: &Bound<'py, PyAny>,
    p2: &Bound<'py, PyAny>,
    threshold: f64,
    confidence: f64,
    max_iters: usize,
    seed: u64,
) -> PyResult<Bound<'py, PyDict>> {
    robust(py, find_essential, p1, p2, threshold, confidence, max_iters, seed)
}

fn homography_rows(obj: &Bound<'_, PyAny>, arg: &str) -> PyResult<[[f64; 3]; 3]> {
    let m = mat3(obj, arg)?;
    let h: [[f64; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|j| m[(i, j)]));
    invert_h(&h).map_err(|e| bad(arg, e))?;
    Ok(h)
}

fn transfer(h: &[[f64; 3]; 3], hinv: &[[f64; 3]; 3], p: [f64; 2], q: [f64; 2]) -> f64 {
    let (tp, tq) = (apply_h(h, p), apply_h(hinv, q));
    0.5 * ((tp[0] - q[0]).hypot(tp[1] - q[1]) + (tq[0] - p[0]).hypot(tq[1] - p[1]))
}

/// Two-way averaged transfer error (px) of correspondences under a ground-truth homography
/// image 1 → image 2 (thesis §4.5.1): ½(‖H p1 − p2‖ + ‖H⁻¹ p2 − p1‖).
#[pyfunction]
pub fn features_transfer_error<'py>(
    py: Python<'py>,
    homography: &Bound<'py, PyAny>,
    p1: &Bound<'py, PyAny>,
    p2: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyAny>> {
    guard(|| {
        let h = homography_rows(homography, "homography")?;
        let hinv = invert_h(&h).map_err(|e| bad("homography", e))?;
        let (a, b) = (points(p1, "p1")?, points(p2, "p2")?);
        if a.len() != b.len() {
            return Err(bad("p2", format!("{} points, p1 has {}", b.len(), a.len())));
        }
        let e: Vec<f64> = a.iter().zip(&b).map(|(p, q)| transfer(&h, &hinv, *p, *q)).collect();
        to_numpy(py, e, &[a.len()])
    })
}

/// Detect in two images and match them (`laparo features match`): the dict of its matches.json
/// (keypoint counts, matches with positions and distances; with a homography, transfer errors,
/// correctness at `eps_px` and precision), plus the features of both images.
#[pyfunction]
#[pyo3(signature = (image1, image2, detector = None, ratio = "lowe:0.8", mutual = true, mask1 = None, mask2 = None, homography = None, eps_px = 3.0))]
#[allow(clippy::too_many_arguments)]
pub fn features_match_images<'py>(
    py: Python<'py>,
    image1: &Bound<'py, PyAny>,
    image2: &Bound<'py, PyAny>,
    detector: Option<&Bound<'py, PyAny>>,
    ratio: &str,
    mutual: bool,
    mask1: Option<&Bound<'py, PyAny>>,
    mask2: Option<&Bound<'py, PyAny>>,
    homography: Option<&Bound<'py, PyAny>>,
    eps_px: f64,
) -> PyResult<Bound<'py, PyDict>> {
    guard(|| {
        let det = match detector {
            Some(d) => self::detector(d)?,
            None => DetectorConfig::by_name("sift").map_err(lib_err)?,
        };
        let mcfg = MatchConfig { ratio: parse_ratio(ratio)?, mutual };
        if eps_px.is_nan() || eps_px <= 0.0 {
            return Err(bad("eps_px", format!("{eps_px} (must be > 0)")));
        }
        let h = homography.map(|h| homography_rows(h, "homography")).transpose()?;
        let (i1, i2) = (image_u8(image1, "image1")?, image_u8(image2, "image2")?);
        let m1 = mask_for(mask1, "mask1", i1.width, i1.height)?;
        let m2 = mask_for(mask2, "mask2", i2.width, i2.height)?;
        let (f1, f2, matches) = par(py, || -> laparo_features::Result<_> {
            let (f1, f2) = rayon::join(
                || detect_and_describe(&i1, &det, m1.as_ref()),
                || detect_and_describe(&i2, &det, m2.as_ref()),
            );
            let (f1, f2) = (f1?, f2?);
            let m = match_features(&f1, &f2, &mcfg)?;
            Ok((f1, f2, m))
        })
        .map_err(lib_err)?;
        let errors: Option<Vec<f64>> = h.map(|h| {
            let hinv = invert_h(&h).expect("checked above");
            matches
                .iter()
                .map(|m| {
                    let (p, q) = (f1.keypoints[m.i1 as usize], f2.keypoints[m.i2 as usize]);
                    transfer(&h, &hinv, [p.x, p.y], [q.x, q.y])
                })
                .collect()
        });
        let n = matches.len();
        let d = PyDict::new(py);
        d.set_item("detector", to_py(py, &det)?)?;
        d.set_item("match", to_py(py, &mcfg)?)?;
        d.set_item("n_keypoints1", f1.len())?;
        d.set_item("n_keypoints2", f2.len())?;
        d.set_item("n_matches", n)?;
        d.set_item("eps_px", eps_px)?;
        let idx: Vec<i64> = matches.iter().flat_map(|m| [m.i1 as i64, m.i2 as i64]).collect();
        let pts = |k: &[Keypoint], side: usize| -> Vec<f64> {
            matches
                .iter()
                .flat_map(|m| {
                    let p = k[if side == 0 { m.i1 } else { m.i2 } as usize];
                    [p.x, p.y]
                })
                .collect()
        };
        d.set_item("matches", to_numpy(py, idx, &[n, 2])?)?;
        d.set_item("points1", to_numpy(py, pts(&f1.keypoints, 0), &[n, 2])?)?;
        d.set_item("points2", to_numpy(py, pts(&f2.keypoints, 1), &[n, 2])?)?;
        d.set_item("distances", to_numpy(py, matches.iter().map(|m| m.distance).collect::<Vec<f32>>(), &[n])?)?;
        match errors {
            Some(e) => {
                let correct: Vec<bool> = e.iter().map(|&x| x < eps_px).collect();
                let c = correct.iter().filter(|&&b| b).count();
                d.set_item("n_correct", c)?;
                d.set_item("precision", if n == 0 { 0.0 } else { c as f64 / n as f64 })?;
                d.set_item("transfer_error_px", to_numpy(py, e, &[n])?)?;
                d.set_item("correct", to_numpy(py, correct, &[n])?)?;
            }
            None => {
                d.set_item("n_correct", py.None())?;
                d.set_item("precision", py.None())?;
            }
        }
        d.set_item("features1", features_dict(py, f1, &det)?)?;
        d.set_item("features2", features_dict(py, f2, &det)?)?;
        Ok(d)
    })
}
