//! `laparo.cats` and `laparo.stereo`: CATS camera augmentation (thesis §3.3.3–3.3.5, eqs.
//! 3.5–3.9), rectification, disparity ↔ depth (§3.3.8) and stereo evaluation (Tables 3.7–3.8).
use crate::arrays::*;
use laparo_core::{Distortion, Image, Intrinsics, StereoCalibration};
use laparo_stereo::DisparityGeometry;
use laparo_stereo::Layout;
use laparo_stereo::{augment_stereo, AugmentedDisparity, GtRule, StereoAugmentation, StereoSample};
use laparo_stereo::{evaluate, EvalOptions};
use laparo_stereo::{sample_rng, sample_seed, CatsConfig};
use laparo_stereo::{Rectification, RectifyOptions, Side};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use std::path::PathBuf;

/// A CATS configuration (the TOML of `laparo cats config`), validated.
#[pyclass(name = "CatsConfig", module = "laparo._laparo", frozen)]
#[derive(Clone)]
pub struct PyCatsConfig {
    pub inner: CatsConfig,
}

#[pymethods]
impl PyCatsConfig {
    /// The thesis' configuration (Table 3.6 row, Δx_right ~ U(−100, 0) px).
    #[staticmethod]
    #[pyo3(signature = (row = "SCARED+StMIS"))]
    fn thesis(row: &str) -> PyResult<Self> {
        Ok(PyCatsConfig { inner: CatsConfig::thesis(row).map_err(|e| bad("row", e))? })
    }
    /// Parse TOML text.
    #[staticmethod]
    fn from_toml(text: &str) -> PyResult<Self> {
        Ok(PyCatsConfig { inner: CatsConfig::from_toml_str(text).map_err(|e| bad("text", e))? })
    }
    /// Read a TOML file.
    #[staticmethod]
    fn from_file(path: PathBuf) -> PyResult<Self> {
        let text = std::fs::read_to_string(&path)
            .map_err(|e| pyo3::exceptions::PyOSError::new_err(format!("{}: {e}", path.display())))?;
        Ok(PyCatsConfig { inner: CatsConfig::from_toml_str(&text).map_err(|e| bad(&path.display().to_string(), e))? })
    }
    /// The configuration as TOML text.
    fn to_toml(&self) -> String {
        self.inner.to_toml_string()
    }
    /// The configuration as a dict.
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_py(py, &self.inner)
    }
    fn __repr__(&self) -> String {
        format!("CatsConfig(source={:?})", self.inner.source)
    }
}

fn intrinsics_from(k: &Bound<'_, PyAny>, arg: &str, width: usize, height: usize) -> PyResult<Intrinsics> {
    let m = mat3(k, arg)?;
    Intrinsics::from_matrix(&m, width, height).map_err(|e| bad(arg, e))
}

/// The source cameras: K matrices when given, else the config's `[camera]`, else SceneFlow's.
fn cameras(
    cfg: &CatsConfig,
    width: usize,
    height: usize,
    k_left: Option<&Bound<'_, PyAny>>,
    k_right: Option<&Bound<'_, PyAny>>,
) -> PyResult<(Intrinsics, Intrinsics)> {
    if width == 0 || height == 0 {
        return Err(bad("width/height", format!("{width}x{height}")));
    }
    match (k_left, k_right) {
        (Some(l), r) => {
            let kl = intrinsics_from(l, "k_left", width, height)?;
            let kr = match r {
                Some(r) => intrinsics_from(r, "k_right", width, height)?,
                None => kl,
            };
            Ok((kl, kr))
        }
        (None, Some(_)) => Err(bad("k_right", "given without k_left")),
        (None, None) => cfg
            .camera
            .unwrap_or(laparo_stereo::SourceCamera::SCENEFLOW)
            .intrinsics(width, height)
            .map_err(|e| bad("config.camera", e)),
    }
}

/// The CATS generator id of (sample id, epoch): epoch 0 is the id itself, so that epoch 0
/// reproduces `laparo cats augment` for the same seed.
fn epoch_id(id: &str, epoch: u64) -> String {
    if epoch == 0 {
        id.to_string()
    } else {
        format!("{id}#epoch{epoch}")
    }
}

fn sample_params(cfg: &CatsConfig, seed: u64, id: &str, kl: &Intrinsics, kr: &Intrinsics) -> StereoAugmentation {
    let mut rng = sample_rng(seed, id);
    cfg.sample(&mut rng, kl, &Distortion::default(), kr, &Distortion::default())
}

/// Draw the parameters of one sample (dict: left, right, dx_right_px, homographies, seed).
#[pyfunction]
#[pyo3(signature = (config, width, height, seed, sample_id, epoch = 0, k_left = None, k_right = None))]
#[allow(clippy::too_many_arguments)]
pub fn cats_sample_params<'py>(
    py: Python<'py>,
    config: &PyCatsConfig,
    width: usize,
    height: usize,
    seed: u64,
    sample_id: &str,
    epoch: u64,
    k_left: Option<&Bound<'py, PyAny>>,
    k_right: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    guard(|| {
        let (kl, kr) = cameras(&config.inner, width, height, k_left, k_right)?;
        let id = epoch_id(sample_id, epoch);
        let p = sample_params(&config.inner, seed, &id, &kl, &kr);
        params_dict(py, &p, Some((seed, sample_seed(seed, &id))))
    })
}

fn rows(m: &nalgebra::Matrix3<f64>) -> [[f64; 3]; 3] {
    [[m[(0, 0)], m[(0, 1)], m[(0, 2)]], [m[(1, 0)], m[(1, 1)], m[(1, 2)]], [m[(2, 0)], m[(2, 1)], m[(2, 2)]]]
}

fn params_dict<'py>(py: Python<'py>, p: &StereoAugmentation, seeds: Option<(u64, u64)>) -> PyResult<Bound<'py, PyAny>> {
    let mut v = serde_json::to_value(p).map_err(|e| bad("params", e))?;
    if let serde_json::Value::Object(o) = &mut v {
        o.insert("homography_left".into(), serde_json::json!(rows(&p.left.homography())));
        o.insert("homography_right".into(), serde_json::json!(rows(&p.right.homography())));
        if let Some((s, ss)) = seeds {
            o.insert("seed".into(), serde_json::json!(s));
            o.insert("sample_seed".into(), serde_json::json!(ss));
        }
    }
    json_to_py(py, &v)
}

fn image_u8(obj: &Bound<'_, PyAny>, arg: &str) -> PyResult<Image<u8>> {
    let a = u8_array(obj, arg)?;
    let (h, w, c) = a.hwc(arg)?;
    Image::from_vec(w, h, c, a.data).map_err(|e| bad(arg, e))
}

fn disparity_f32(obj: &Bound<'_, PyAny>, arg: &str, w: usize, h: usize) -> PyResult<Image<f32>> {
    let a = f32_array(obj, arg)?;
    let (hh, ww) = a.hw(arg)?;
    if (ww, hh) != (w, h) {
        return Err(bad(arg, format!("shape ({hh}, {ww}) differs from the image's ({h}, {w})")));
    }
    Image::from_vec(w, h, 1, a.data).map_err(|e| bad(arg, e))
}

fn disp_out<'py>(
    py: Python<'py>,
    d: &mut Bound<'py, PyDict>,
    name: &str,
    a: Option<AugmentedDisparity>,
) -> PyResult<()> {
    if let Some(a) = a {
        d.set_item(format!("disp_{name}"), image_to_numpy(py, a.disparity)?)?;
        d.set_item(format!("disp_{name}_valid"), image_to_numpy(py, a.valid)?)?;
        if let Some(r) = a.vertical_residual {
            d.set_item(format!("disp_{name}_vertical_residual"), image_to_numpy(py, r)?)?;
        }
    }
    Ok(())
}

fn augment_to_dict<'py>(
    py: Python<'py>,
    s: StereoSample,
    p: &StereoAugmentation,
    rule: GtRule,
    seeds: Option<(u64, u64)>,
) -> PyResult<Bound<'py, PyDict>> {
    let a = par(py, || augment_stereo(&s, p, rule)).map_err(lib_err)?;
    let mut d = PyDict::new(py);
    d.set_item("left", image_to_numpy(py, a.left.image)?)?;
    d.set_item("right", image_to_numpy(py, a.right.image)?)?;
    d.set_item("valid_left", image_to_numpy(py, a.left.valid)?)?;
    d.set_item("valid_right", image_to_numpy(py, a.right.valid)?)?;
    disp_out(py, &mut d, "left", a.disp_left)?;
    disp_out(py, &mut d, "right", a.disp_right)?;
    d.set_item("params", params_dict(py, p, seeds)?)?;
    Ok(d)
}

fn parse_rule(s: &str) -> PyResult<GtRule> {
    s.parse::<GtRule>().map_err(|e| bad("gt_rule", e))
}

/// Augment one stereo sample. `params` is a dict (a sidecar's, `sample_params`', or hand-written
/// as for `laparo cats apply`); or draw them from `config` with (seed, sample_id, epoch).
#[pyfunction]
#[pyo3(signature = (left, right, disp_left = None, disp_right = None, params = None, config = None, seed = 0, sample_id = "sample", epoch = 0, k_left = None, k_right = None, gt_rule = "exact"))]
#[allow(clippy::too_many_arguments)]
pub fn cats_augment<'py>(
    py: Python<'py>,
    left: &Bound<'py, PyAny>,
    right: &Bound<'py, PyAny>,
    disp_left: Option<&Bound<'py, PyAny>>,
    disp_right: Option<&Bound<'py, PyAny>>,
    params: Option<&Bound<'py, PyAny>>,
    config: Option<&PyCatsConfig>,
    seed: u64,
    sample_id: &str,
    epoch: u64,
    k_left: Option<&Bound<'py, PyAny>>,
    k_right: Option<&Bound<'py, PyAny>>,
    gt_rule: &str,
) -> PyResult<Bound<'py, PyDict>> {
    guard(|| {
        let rule = parse_rule(gt_rule)?;
        let l = image_u8(left, "left")?;
        let r = image_u8(right, "right")?;
        if (l.width, l.height, l.channels) != (r.width, r.height, r.channels) {
            return Err(bad("right", format!("shape ({}, {}, {}) differs from left's", r.height, r.width, r.channels)));
        }
        let (w, h) = (l.width, l.height);
        let dl = disp_left.map(|d| disparity_f32(d, "disp_left", w, h)).transpose()?;
        let dr = disp_right.map(|d| disparity_f32(d, "disp_right", w, h)).transpose()?;
        let (p, seeds) = match (params, config) {
            (Some(_), Some(_)) => return Err(bad("params", "give params or config, not both")),
            (Some(pd), None) => {
                let text = py_to_json(pd, "params")?.to_string();
                (laparo_stereo::parse_params(&text, w, h).map_err(|e| bad("params", e))?, None)
            }
            (None, cfg) => {
                let thesis;
                let cfg = match cfg {
                    Some(c) => &c.inner,
                    None => {
                        thesis = CatsConfig::thesis("SCARED+StMIS").map_err(lib_err)?;
                        &thesis
                    }
                };
                let (kl, kr) = cameras(cfg, w, h, k_left, k_right)?;
                let id = epoch_id(sample_id, epoch);
                (sample_params(cfg, seed, &id, &kl, &kr), Some((seed, sample_seed(seed, &id))))
            }
        };
        laparo_stereo::check_homographies(&p).map_err(|e| bad("params", e))?;
        let s = StereoSample { left: l, right: r, disp_left: dl, disp_right: dr, occ_left: None, occ_right: None };
        augment_to_dict(py, s, &p, rule, seeds)
    })
}

fn parse_layout(s: &str) -> PyResult<Layout> {
    s.parse::<Layout>().map_err(|e| bad("layout", e))
}

/// The samples of a dataset folder (as `laparo cats augment` finds them, sorted by id).
#[pyfunction]
pub fn cats_discover<'py>(py: Python<'py>, root: PathBuf, layout: &str) -> PyResult<Bound<'py, PyList>> {
    guard(|| {
        let lay = parse_layout(layout)?;
        let files = laparo_stereo::discover(&root, lay).map_err(lib_err)?;
        let out = PyList::empty(py);
        for f in files {
            let d = PyDict::new(py);
            d.set_item("id", &f.id)?;
            d.set_item("left", &f.left)?;
            d.set_item("right", &f.right)?;
            d.set_item("disp_left", &f.disp_left)?;
            d.set_item("disp_right", &f.disp_right)?;
            d.set_item("calib", &f.calib)?;
            out.append(d)?;
        }
        Ok(out)
    })
}

fn augment_files<'py>(
    py: Python<'py>,
    f: &laparo_stereo::SampleFiles,
    lay: Layout,
    config: Option<&PyCatsConfig>,
    seed: u64,
    epoch: u64,
    gt_rule: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let rule = parse_rule(gt_rule)?;
    let cfg = match config {
        Some(c) => c.inner.clone(),
        None => CatsConfig::thesis("SCARED+StMIS").map_err(lib_err)?,
    };
    let s = laparo_stereo::load_sample(f).map_err(lib_err)?;
    let (kl, kr) = laparo_stereo::source_cameras(f, lay, &cfg, s.left.width, s.left.height).map_err(lib_err)?;
    let id = epoch_id(&f.id, epoch);
    let p = sample_params(&cfg, seed, &id, &kl, &kr);
    laparo_stereo::check_homographies(&p).map_err(|e| bad("params", e))?;
    let d = augment_to_dict(py, s, &p, rule, Some((seed, sample_seed(seed, &id))))?;
    d.set_item("id", &f.id)?;
    Ok(d)
}

/// Load and augment sample `index` of a dataset folder exactly as `laparo cats augment` does
/// (epoch 0), or with the generator of (seed, id, epoch).
#[pyfunction]
#[pyo3(signature = (root, layout, index, config = None, seed = 0, epoch = 0, gt_rule = "exact"))]
#[allow(clippy::too_many_arguments)]
pub fn cats_augment_folder_sample<'py>(
    py: Python<'py>,
    root: PathBuf,
    layout: &str,
    index: usize,
    config: Option<&PyCatsConfig>,
    seed: u64,
    epoch: u64,
    gt_rule: &str,
) -> PyResult<Bound<'py, PyDict>> {
    guard(|| {
        let lay = parse_layout(layout)?;
        let files = laparo_stereo::discover(&root, lay).map_err(lib_err)?;
        let f =
            files.get(index).ok_or_else(|| bad("index", format!("{index} out of range ({} samples)", files.len())))?;
        augment_files(py, f, lay, config, seed, epoch, gt_rule)
    })
}

/// Augment one sample given as a dict of `cats_discover` (no folder walk: for DataLoaders).
#[pyfunction]
#[pyo3(signature = (sample, layout, config = None, seed = 0, epoch = 0, gt_rule = "exact"))]
pub fn cats_augment_sample_files<'py>(
    py: Python<'py>,
    sample: &Bound<'py, PyDict>,
    layout: &str,
    config: Option<&PyCatsConfig>,
    seed: u64,
    epoch: u64,
    gt_rule: &str,
) -> PyResult<Bound<'py, PyDict>> {
    guard(|| {
        let lay = parse_layout(layout)?;
        let get = |k: &str| -> PyResult<Option<PathBuf>> {
            match sample.get_item(k)? {
                Some(v) if !v.is_none() => {
                    Ok(Some(v.extract().map_err(|_| bad(&format!("sample['{k}']"), "not a path"))?))
                }
                _ => Ok(None),
            }
        };
        let id: String = sample
            .get_item("id")?
            .ok_or_else(|| bad("sample", "missing key 'id'"))?
            .extract()
            .map_err(|_| bad("sample['id']", "not a string"))?;
        let f = laparo_stereo::SampleFiles {
            id,
            left: get("left")?.ok_or_else(|| bad("sample", "missing key 'left'"))?,
            right: get("right")?.ok_or_else(|| bad("sample", "missing key 'right'"))?,
            disp_left: get("disp_left")?,
            disp_right: get("disp_right")?,
            calib: get("calib")?,
        };
        augment_files(py, &f, lay, config, seed, epoch, gt_rule)
    })
}

/// The seed of one sample's generator (FNV-1a of the id mixed with the run seed).
#[pyfunction]
pub fn cats_sample_seed(seed: u64, sample_id: &str) -> u64 {
    sample_seed(seed, sample_id)
}

// ------------------------------------------------------------------------------------------
// Stereo geometry.

/// A stereo calibration read from a file (laparo JSON, OpenCV YAML, EndoVis txt) as a dict.
#[pyfunction]
#[pyo3(signature = (path, path2 = None, width = None, height = None))]
pub fn stereo_read_calibration<'py>(
    py: Python<'py>,
    path: PathBuf,
    path2: Option<PathBuf>,
    width: Option<usize>,
    height: Option<usize>,
) -> PyResult<Bound<'py, PyAny>> {
    guard(|| {
        let c = read_calib(&path, path2.as_deref(), width, height)?;
        calib_dict(py, &c)
    })
}

fn read_calib(
    path: &std::path::Path,
    path2: Option<&std::path::Path>,
    width: Option<usize>,
    height: Option<usize>,
) -> PyResult<StereoCalibration> {
    let files: Vec<&std::path::Path> = std::iter::once(path).chain(path2).collect();
    let size = match (width, height) {
        (Some(w), Some(h)) => Some((w, h)),
        (None, None) => None,
        _ => return Err(bad("width/height", "give both or neither")),
    };
    laparo_core::io::read_stereo_calibration(&files, size).map_err(lib_err)
}

fn calib_dict<'py>(py: Python<'py>, c: &StereoCalibration) -> PyResult<Bound<'py, PyAny>> {
    let d = PyDict::new(py);
    d.set_item("width", c.width)?;
    d.set_item("height", c.height)?;
    d.set_item("k_left", to_numpy(py, rows(&c.left.matrix()).concat(), &[3, 3])?)?;
    d.set_item("k_right", to_numpy(py, rows(&c.right.matrix()).concat(), &[3, 3])?)?;
    let dist = |x: &Distortion| vec![x.k1, x.k2, x.p1, x.p2, x.k3];
    d.set_item("dist_left", to_numpy(py, dist(&c.left_dist), &[5])?)?;
    d.set_item("dist_right", to_numpy(py, dist(&c.right_dist), &[5])?)?;
    d.set_item("r", to_numpy(py, rows(&c.r).concat(), &[3, 3])?)?;
    d.set_item("t_mm", to_numpy(py, vec![c.t_mm.x, c.t_mm.y, c.t_mm.z], &[3])?)?;
    Ok(d.into_any())
}

fn calib_from_dict(d: &Bound<'_, PyAny>) -> PyResult<StereoCalibration> {
    let get = |k: &str| d.get_item(k).map_err(|_| bad("calib", format!("missing key '{k}'")));
    let width: usize = get("width")?.extract().map_err(|e| bad("calib['width']", e))?;
    let height: usize = get("height")?.extract().map_err(|e| bad("calib['height']", e))?;
    let left = intrinsics_from(&get("k_left")?, "calib['k_left']", width, height)?;
    let right = intrinsics_from(&get("k_right")?, "calib['k_right']", width, height)?;
    let dist = |k: &str| -> PyResult<Distortion> {
        match d.get_item(k) {
            Ok(v) if !v.is_none() => {
                let a = f64_array(&v, &format!("calib['{k}']"))?;
                a.require_finite(&format!("calib['{k}']"))?;
                Distortion::from_opencv(&a.data).map_err(|e| bad(&format!("calib['{k}']"), e))
            }
            _ => Ok(Distortion::default()),
        }
    };
    let r = mat3(&get("r")?, "calib['r']")?;
    let t = f64_array(&get("t_mm")?, "calib['t_mm']")?;
    if t.data.len() != 3 {
        return Err(bad("calib['t_mm']", format!("expected 3 values, got shape {:?}", t.shape)));
    }
    t.require_finite("calib['t_mm']")?;
    Ok(StereoCalibration {
        width,
        height,
        left,
        left_dist: dist("dist_left")?,
        right,
        right_dist: dist("dist_right")?,
        r,
        t_mm: nalgebra::Vector3::new(t.data[0], t.data[1], t.data[2]),
    })
}

/// Rectify a calibrated pair: (left, right, valid_left, valid_right, info dict).
#[pyfunction]
#[pyo3(signature = (left, right, calib, alpha = 0.0, align_principal_points = true))]
pub fn stereo_rectify<'py>(
    py: Python<'py>,
    left: &Bound<'py, PyAny>,
    right: &Bound<'py, PyAny>,
    calib: &Bound<'py, PyAny>,
    alpha: f64,
    align_principal_points: bool,
) -> PyResult<Bound<'py, PyDict>> {
    guard(|| {
        let c = calib_from_dict(calib)?;
        if !alpha.is_finite() {
            return Err(bad("alpha", "not finite"));
        }
        let rect =
            Rectification::new(&c, RectifyOptions { alpha, align_principal_points }).map_err(|e| bad("calib", e))?;
        let d = PyDict::new(py);
        for (name, side, obj) in [("left", Side::Left, left), ("right", Side::Right, right)] {
            let (img, valid) = if let Ok(a) = u8_array(obj, name) {
                let (h, w, ch) = a.hwc(name)?;
                let im = Image::from_vec(w, h, ch, a.data).map_err(|e| bad(name, e))?;
                let (o, v) = par(py, || rect.rectify_image(side, &im)).map_err(|e| bad(name, e))?;
                (image_to_numpy(py, o)?, v)
            } else {
                let a = f64_array(obj, name)?;
                let (h, w, ch) = a.hwc(name)?;
                let im = Image::from_vec(w, h, ch, a.data).map_err(|e| bad(name, e))?;
                let (o, v) = par(py, || rect.rectify_image(side, &im)).map_err(|e| bad(name, e))?;
                (image_to_numpy(py, o)?, v)
            };
            d.set_item(name, img)?;
            d.set_item(format!("valid_{name}"), image_to_numpy(py, valid)?)?;
        }
        d.set_item("info", to_py(py, &rect.info())?)?;
        Ok(d)
    })
}

fn geometry(f_px: f64, baseline_mm: f64, cx_left: f64, cx_right: f64) -> PyResult<DisparityGeometry> {
    for (n, v) in [("f_px", f_px), ("baseline_mm", baseline_mm), ("cx_left", cx_left), ("cx_right", cx_right)] {
        if !v.is_finite() {
            return Err(bad(n, format!("{v} is not finite")));
        }
    }
    if f_px <= 0.0 || baseline_mm <= 0.0 {
        return Err(bad("f_px/baseline_mm", "must be > 0"));
    }
    Ok(DisparityGeometry { f_px, fy_px: f_px, baseline_mm, cx_left, cx_right, cy: 0.0 })
}

/// Depth (mm) of disparities (px): z = f b / (d − (c_x^L − c_x^R)) (§3.3.8); NaN where invalid.
#[pyfunction]
pub fn stereo_disparity_to_depth<'py>(
    py: Python<'py>,
    disparity: &Bound<'py, PyAny>,
    f_px: f64,
    baseline_mm: f64,
    cx_left: f64,
    cx_right: f64,
) -> PyResult<Bound<'py, PyAny>> {
    guard(|| {
        let g = geometry(f_px, baseline_mm, cx_left, cx_right)?;
        with_f64(disparity, "disparity", |s, d| to_numpy(py, d.iter().map(|&v| g.depth_mm(v)).collect(), s))
    })
}

/// Disparity (px) of depths (mm): d = f b / z + (c_x^L − c_x^R) (§3.3.8); NaN where z ≤ 0.
#[pyfunction]
pub fn stereo_depth_to_disparity<'py>(
    py: Python<'py>,
    depth_mm: &Bound<'py, PyAny>,
    f_px: f64,
    baseline_mm: f64,
    cx_left: f64,
    cx_right: f64,
) -> PyResult<Bound<'py, PyAny>> {
    guard(|| {
        let g = geometry(f_px, baseline_mm, cx_left, cx_right)?;
        with_f64(depth_mm, "depth_mm", |s, d| to_numpy(py, d.iter().map(|&v| g.disparity_px(v)).collect(), s))
    })
}

/// EPE, Bad-k and (with a geometry) depth MAE/RMSE/AbsRel/δ of a predicted left disparity.
#[pyfunction]
#[pyo3(signature = (pred, gt, mask = None, f_px = None, baseline_mm = None, cx_left = None, cx_right = None, bad_thresholds_px = vec![1.0, 2.0, 3.0], depth_range_mm = Some((10.0, 500.0)), zero_is_invalid = false))]
#[allow(clippy::too_many_arguments)]
pub fn stereo_evaluate<'py>(
    py: Python<'py>,
    pred: &Bound<'py, PyAny>,
    gt: &Bound<'py, PyAny>,
    mask: Option<&Bound<'py, PyAny>>,
    f_px: Option<f64>,
    baseline_mm: Option<f64>,
    cx_left: Option<f64>,
    cx_right: Option<f64>,
    bad_thresholds_px: Vec<f64>,
    depth_range_mm: Option<(f64, f64)>,
    zero_is_invalid: bool,
) -> PyResult<Bound<'py, PyAny>> {
    guard(|| {
        let p = f64_array(pred, "pred")?;
        let g = f64_array(gt, "gt")?;
        let (h, w) = g.hw("gt")?;
        if p.shape != g.shape {
            return Err(bad("pred", format!("shape {:?} differs from gt shape {:?}", p.shape, g.shape)));
        }
        let m = match mask {
            Some(m) => {
                let a = bool_array(m, "mask")?;
                if a.shape != g.shape {
                    return Err(bad("mask", format!("shape {:?} differs from gt shape {:?}", a.shape, g.shape)));
                }
                Some(Image::from_vec(w, h, 1, a.data).map_err(|e| bad("mask", e))?)
            }
            None => None,
        };
        let geo = match (f_px, baseline_mm) {
            (Some(f), Some(b)) => Some(geometry(f, b, cx_left.unwrap_or(0.0), cx_right.unwrap_or(0.0))?),
            (None, None) => None,
            _ => return Err(bad("f_px/baseline_mm", "give both or neither")),
        };
        let opts = EvalOptions { bad_thresholds_px, depth_range_mm, zero_is_invalid };
        let pi = Image::from_vec(w, h, 1, p.data).map_err(|e| bad("pred", e))?;
        let gi = Image::from_vec(w, h, 1, g.data).map_err(|e| bad("gt", e))?;
        let r = par(py, || evaluate(&pi, &gi, m.as_ref(), geo.as_ref(), &opts)).map_err(lib_err)?;
        to_py(py, &r)
    })
}

/// Augment the samples of shard (index, count) of a dataset folder into `out`, writing exactly
/// the files of `laparo cats augment` (images, disparities, sidecars). Returns
/// (number augmented, list of "id: error" failures).
#[pyfunction]
#[pyo3(signature = (input, layout, out, config = None, seed = 0, gt_rule = "exact", shard_index = 0, shard_count = 1))]
#[allow(clippy::too_many_arguments)]
pub fn cats_augment_dataset(
    py: Python<'_>,
    input: PathBuf,
    layout: &str,
    out: PathBuf,
    config: Option<&PyCatsConfig>,
    seed: u64,
    gt_rule: &str,
    shard_index: usize,
    shard_count: usize,
) -> PyResult<(usize, Vec<String>)> {
    use rayon::prelude::*;
    guard(|| {
        let lay = parse_layout(layout)?;
        let rule = parse_rule(gt_rule)?;
        let shard = laparo_core::shard::Shard::new(shard_index, shard_count).map_err(|e| bad("shard", e))?;
        let cfg = match config {
            Some(c) => c.inner.clone(),
            None => CatsConfig::thesis("SCARED+StMIS").map_err(lib_err)?,
        };
        laparo_core::atomic::refuse_overwrite(&out, &[&input], true).map_err(|e| bad("out", e))?;
        let files = shard.select(laparo_stereo::discover(&input, lay).map_err(lib_err)?);
        std::fs::create_dir_all(&out)
            .map_err(|e| pyo3::exceptions::PyOSError::new_err(format!("{}: {e}", out.display())))?;
        let results: Vec<Result<(), String>> = par(py, || {
            files
                .par_iter()
                .map(|f| {
                    laparo_stereo::augment_sample(f, &input, &out, lay, &cfg, seed, rule)
                        .map(|_| ())
                        .map_err(|e| format!("{}: {e}", f.id))
                })
                .collect()
        });
        let failures: Vec<String> = results.iter().filter_map(|r| r.clone().err()).collect();
        Ok((results.len() - failures.len(), failures))
    })
}
