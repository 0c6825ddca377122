//! `laparo.stereo.match` / `self_rectify`: semi-global matching (laparo_stereo::match_pair, census cost,
//! signed disparity range, optional vertical tolerance; thesis §3.3) and self-rectification of a
//! raw pair from SIFT matches — the computations of `laparo stereo match` without the files.
use crate::arrays::*;
use laparo_core::Image;
use laparo_stereo::{match_pair_with, SgmParams, SgmWorkspace};
use laparo_stereo::{self_rectify, RectifyMethod, SelfRectifyOptions};
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// SGM buffers kept between calls of `laparo.stereo.match` (a Python loop over the frames of a
/// video reuses them instead of page-faulting 50–300 MB per pair). The libraries have no
/// process-wide state; the binding keeps this pool because Python callers cannot hold a
/// workspace. Concurrent calls each take their own workspace.
static SGM_WORKSPACES: std::sync::Mutex<Vec<SgmWorkspace>> = std::sync::Mutex::new(Vec::new());

fn take_workspace() -> SgmWorkspace {
    SGM_WORKSPACES.lock().ok().and_then(|mut p| p.pop()).unwrap_or_default()
}

fn give_back_workspace(ws: SgmWorkspace) {
    if let Ok(mut p) = SGM_WORKSPACES.lock() {
        if p.len() < 2 {
            p.push(ws);
        }
    }
}

fn image_u8(obj: &Bound<'_, PyAny>, arg: &str) -> PyResult<Image<u8>> {
    let a = u8_array(obj, arg)?;
    let (h, w, c) = a.hwc(arg)?;
    if c > 4 {
        return Err(bad(arg, format!("{c} channels (expected 1 to 4)")));
    }
    Image::from_vec(w, h, c, a.data).map_err(|e| bad(arg, e))
}

fn pair(left: &Bound<'_, PyAny>, right: &Bound<'_, PyAny>) -> PyResult<(Image<u8>, Image<u8>)> {
    let l = image_u8(left, "left")?;
    let r = image_u8(right, "right")?;
    if (l.width, l.height) != (r.width, r.height) {
        return Err(bad("right", format!("is {}x{}, left is {}x{}", r.width, r.height, l.width, l.height)));
    }
    Ok((l, r))
}

/// SGM parameters as `laparo stereo match` builds them from its options.
#[allow(clippy::too_many_arguments)]
fn sgm_params(
    d_min: i32,
    d_max: i32,
    mode: &str,
    vertical_tol: usize,
    p1: Option<u16>,
    p2: Option<u16>,
    uniqueness: Option<u8>,
    lr_max_diff: Option<i32>,
    speckle_window: Option<usize>,
) -> PyResult<SgmParams> {
    if d_max <= d_min {
        return Err(bad("d_max", format!("empty range [{d_min}, {d_max}) (need d_min < d_max)")));
    }
    let mut p = match mode {
        "default" => SgmParams::new(d_min, d_max),
        "accurate" => SgmParams::accurate(d_min, d_max),
        m => return Err(bad("mode", format!("{m:?}: expected default or accurate"))),
    };
    p.vertical_tol = vertical_tol;
    if let Some(v) = p1 {
        p.p1 = v;
    }
    if let Some(v) = p2 {
        p.p2 = v;
    }
    if let Some(v) = uniqueness {
        p.uniqueness_pct = v;
    }
    if let Some(v) = lr_max_diff {
        p.lr_max_diff = (v >= 0).then_some(v);
    }
    if let Some(v) = speckle_window {
        p.speckle_window = v;
    }
    Ok(p)
}

use laparo_stereo::{match_self_rectified, sift_matches};

/// Semi-global matching of a stereo pair (8-bit grey/RGB/RGBA, same size) over the disparity
/// range [d_min, d_max) px, d = x_L − x_R of either sign. Returns `disparity` (float32, +inf where
/// invalid), `confidence` (float32 in [0, 1]), `dy` (vertical offset, px, NaN where invalid) when
/// `vertical_tol > 0` or `self_rectify`, `disparity_filled` with `fill_holes`, `stats` and
/// `params`; with `self_rectify`, the raw pair is rectified from SIFT matches first and the
/// outputs are in the raw left frame (plus `rectification`, the rectified images and disparity).
#[pyfunction]
#[pyo3(signature = (left, right, d_min, d_max, mode = "default", vertical_tol = 0, p1 = None, p2 = None, uniqueness = None, lr_max_diff = None, speckle_window = None, fill_holes = false, self_rectify = false))]
#[allow(clippy::too_many_arguments)]
pub fn stereo_match<'py>(
    py: Python<'py>,
    left: &Bound<'py, PyAny>,
    right: &Bound<'py, PyAny>,
    d_min: i32,
    d_max: i32,
    mode: &str,
    vertical_tol: usize,
    p1: Option<u16>,
    p2: Option<u16>,
    uniqueness: Option<u8>,
    lr_max_diff: Option<i32>,
    speckle_window: Option<usize>,
    fill_holes: bool,
    self_rectify: bool,
) -> PyResult<Bound<'py, PyDict>> {
    guard(|| {
        let p = sgm_params(d_min, d_max, mode, vertical_tol, p1, p2, uniqueness, lr_max_diff, speckle_window)?;
        let (l, r) = pair(left, right)?;
        let (w, h) = l.size();
        let d = PyDict::new(py);
        let out = if self_rectify {
            let s = par(py, || match_self_rectified(&l, &r, &p).map_err(|e| e.to_string()))
                .map_err(|e| bad("self_rectify", e))?;
            d.set_item("rectification", to_py(py, &s.rectification)?)?;
            d.set_item("n_matches", s.n_matches)?;
            d.set_item("rectified_range_px", s.rectified_range_px)?;
            d.set_item("median_disparity_shift_px", s.median_disparity_shift_px)?;
            d.set_item("left_rectified", image_to_numpy(py, s.left_rectified)?)?;
            d.set_item("right_rectified", image_to_numpy(py, s.right_rectified)?)?;
            d.set_item("disparity_rectified", image_to_numpy(py, s.disparity_rectified)?)?;
            s.output
        } else {
            par(py, || {
                let mut ws = take_workspace();
                let out = match_pair_with(&mut ws, &l, &r, &p);
                give_back_workspace(ws);
                out
            })
            .map_err(|e| bad("stereo match", e))?
        };
        if fill_holes {
            let mut f = out.disparity.data.clone();
            laparo_stereo::fill_background(&mut f, w, h);
            d.set_item("disparity_filled", to_numpy(py, f, &[h, w])?)?;
        }
        d.set_item("disparity", image_to_numpy(py, out.disparity)?)?;
        d.set_item("confidence", image_to_numpy(py, out.confidence)?)?;
        if let Some(dy) = out.dy {
            d.set_item("dy", image_to_numpy(py, dy)?)?;
        }
        d.set_item("stats", to_py(py, &out.stats)?)?;
        d.set_item("params", to_py(py, &p)?)?;
        Ok(d)
    })
}

/// Self-rectify a raw pair without a calibration: from `points_left`/`points_right` (N, 2) px
/// when given, else from SIFT matches (Lowe 0.8, mutual). Returns `rectification` (homographies,
/// F, diagnostics), the rectified `left`/`right` with `valid_left`/`valid_right`, and the points.
#[pyfunction]
#[pyo3(signature = (left, right, points_left = None, points_right = None, method = "quasi-euclidean", threshold_px = 1.0, min_inliers = 20, seed = 0))]
#[allow(clippy::too_many_arguments)]
pub fn stereo_self_rectify<'py>(
    py: Python<'py>,
    left: &Bound<'py, PyAny>,
    right: &Bound<'py, PyAny>,
    points_left: Option<&Bound<'py, PyAny>>,
    points_right: Option<&Bound<'py, PyAny>>,
    method: &str,
    threshold_px: f64,
    min_inliers: usize,
    seed: u64,
) -> PyResult<Bound<'py, PyDict>> {
    guard(|| {
        let method = match method {
            "quasi-euclidean" => RectifyMethod::QuasiEuclidean,
            "hartley" => RectifyMethod::Hartley,
            m => return Err(bad("method", format!("{m:?}: expected quasi-euclidean or hartley"))),
        };
        if !(threshold_px > 0.0 && threshold_px.is_finite()) {
            return Err(bad("threshold_px", format!("{threshold_px} (must be > 0)")));
        }
        let (l, r) = pair(left, right)?;
        let pts = |o: &Bound<'py, PyAny>, arg: &str| -> PyResult<Vec<[f64; 2]>> {
            let a = f64_array(o, arg)?;
            a.rows(arg, 2)?;
            a.require_finite(arg)?;
            Ok(a.data.chunks_exact(2).map(|p| [p[0], p[1]]).collect())
        };
        let given = match (points_left, points_right) {
            (Some(a), Some(b)) => {
                let (a, b) = (pts(a, "points_left")?, pts(b, "points_right")?);
                if a.len() != b.len() {
                    return Err(bad("points_right", format!("{} points, points_left has {}", b.len(), a.len())));
                }
                Some((a, b))
            }
            (None, None) => None,
            _ => return Err(bad("points_left", "points_left and points_right go together")),
        };
        let mut opts = SelfRectifyOptions { method, min_inliers, ..Default::default() };
        opts.ransac.threshold_px = threshold_px;
        opts.ransac.seed = seed;
        let (pl, pr, sr, imgs) = par(py, || -> Result<_, String> {
            let (pl, pr) = match given {
                Some(g) => g,
                None => sift_matches(&l, &r).map_err(|e| format!("SIFT matching: {e}"))?,
            };
            let sr = self_rectify(&pl, &pr, l.size(), &opts).map_err(|e| e.to_string())?;
            let imgs = sr.rectify_images(&l, &r).map_err(|e| e.to_string())?;
            Ok((pl, pr, sr, imgs))
        })
        .map_err(|e| bad("self_rectify", e))?;
        let ((li, lv), (ri, rv)) = imgs;
        let d = PyDict::new(py);
        d.set_item("rectification", to_py(py, &sr)?)?;
        d.set_item("left", image_to_numpy(py, li)?)?;
        d.set_item("right", image_to_numpy(py, ri)?)?;
        d.set_item("valid_left", image_to_numpy(py, lv)?)?;
        d.set_item("valid_right", image_to_numpy(py, rv)?)?;
        let n = pl.len();
        d.set_item("points_left", to_numpy(py, pl.into_iter().flatten().collect::<Vec<f64>>(), &[n, 2])?)?;
        d.set_item("points_right", to_numpy(py, pr.into_iter().flatten().collect::<Vec<f64>>(), &[n, 2])?)?;
        Ok(d)
    })
}
