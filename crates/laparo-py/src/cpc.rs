//! `laparo.cpc`: Conformal Perspective Correction of one frame (thesis Ch. 4, §4.4.6) and point
//! mapping between the original image and the warped canvas.
use crate::arrays::*;
use laparo_core::{DepthMap, DepthUnit, Image, Intrinsics};
use laparo_cpc::conformal::ConformalParams;
use laparo_cpc::mesh::MeshParams;
use laparo_cpc::pipeline::{cpc_warp, CpcParams, LambdaChoice, DEFAULT_LAMBDA};
use laparo_cpc::warp::Warp;
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// The piecewise-affine warp of one CPC run: maps points both ways.
#[pyclass(name = "CpcWarp", module = "laparo._laparo", frozen)]
pub struct PyCpcWarp {
    warp: Warp,
}

fn points(obj: &Bound<'_, PyAny>, arg: &str) -> PyResult<(Vec<f64>, Vec<usize>)> {
    let a = f64_array(obj, arg)?;
    let shape = a.shape.clone();
    match shape.as_slice() {
        [2] | [_, 2] => Ok((a.data, shape)),
        s => Err(bad(arg, format!("expected shape (N, 2) or (2,), got {s:?}"))),
    }
}

impl PyCpcWarp {
    fn map_points<'py>(
        &self,
        py: Python<'py>,
        pts: &Bound<'py, PyAny>,
        f: impl Fn(&Warp, f64, f64) -> Option<[f64; 2]> + Sync,
    ) -> PyResult<Bound<'py, PyAny>> {
        guard(|| {
            let (d, shape) = points(pts, "points")?;
            let out: Vec<f64> = par(py, || {
                d.chunks(2)
                    .flat_map(|p| {
                        if p[0].is_finite() && p[1].is_finite() {
                            f(&self.warp, p[0], p[1]).unwrap_or([f64::NAN; 2])
                        } else {
                            [f64::NAN; 2]
                        }
                    })
                    .collect()
            });
            to_numpy(py, out, &shape)
        })
    }
}

#[pymethods]
impl PyCpcWarp {
    /// Canvas (x, y) of original-image points (N, 2); NaN outside the mesh.
    fn original_to_warped<'py>(&self, py: Python<'py>, points: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
        self.map_points(py, points, |w, x, y| w.original_to_warped(x, y))
    }
    /// Original-image (x, y) of canvas points (N, 2); NaN outside the flattened mesh.
    fn warped_to_original<'py>(&self, py: Python<'py>, points: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
        self.map_points(py, points, |w, x, y| w.warped_to_original(x, y))
    }
    /// Dense maps: (backward (Hc, Wc, 2): canvas → original, forward (H, W, 2): original → canvas).
    fn maps<'py>(&self, py: Python<'py>) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
        guard(|| {
            let m = par(py, || self.warp.maps());
            Ok((image_to_numpy(py, m.backward)?, image_to_numpy(py, m.forward)?))
        })
    }
    /// Canvas size (width, height) px.
    #[getter]
    fn canvas_size(&self) -> (usize, usize) {
        (self.warp.width, self.warp.height)
    }
    /// Flattened coordinates of canvas pixel (0, 0).
    #[getter]
    fn canvas_origin(&self) -> (f64, f64) {
        (self.warp.origin[0], self.warp.origin[1])
    }
}

/// CPC warp of one frame. `lam`: None (0.95), a float in [0, 1), or "auto" (§4.5.4).
/// Returns dict(warped, mask, stats, warp[, sweep]).
#[pyfunction]
#[pyo3(signature = (image, depth, k, mask = None, lam = None, depth_unit = "mm", grid_step_px = 4, max_view_angle_deg = 85.0, max_depth_jump = 0.1, theta_deg = 90.0, equiareal = false))]
#[allow(clippy::too_many_arguments)]
pub fn cpc_warp_frame<'py>(
    py: Python<'py>,
    image: &Bound<'py, PyAny>,
    depth: &Bound<'py, PyAny>,
    k: &Bound<'py, PyAny>,
    mask: Option<&Bound<'py, PyAny>>,
    lam: Option<&Bound<'py, PyAny>>,
    depth_unit: &str,
    grid_step_px: usize,
    max_view_angle_deg: f64,
    max_depth_jump: f64,
    theta_deg: f64,
    equiareal: bool,
) -> PyResult<Bound<'py, PyDict>> {
    guard(|| {
        let img = u8_array(image, "image")?;
        let (h, w, c) = img.hwc("image")?;
        let img = Image::from_vec(w, h, c, img.data).map_err(|e| bad("image", e))?;
        let d = f64_array(depth, "depth")?;
        let (dh, dw) = d.hw("depth")?;
        if (dh, dw) != (h, w) {
            return Err(bad("depth", format!("shape ({dh}, {dw}) differs from the image's ({h}, {w})")));
        }
        if d.data.iter().any(|v| v.is_infinite()) {
            return Err(bad("depth", "contains an infinite value (use NaN or 0 for invalid depth)"));
        }
        let unit: DepthUnit = depth_unit.parse().map_err(|e| bad("depth_unit", e))?;
        let depth = DepthMap::new(w, h, unit, d.data).map_err(|e| bad("depth", e))?;
        let km = mat3(k, "k")?;
        let k = Intrinsics::from_matrix(&km, w, h).map_err(|e| bad("k", e))?;
        let roi = match mask {
            Some(m) => {
                let a = bool_array(m, "mask")?;
                if a.shape != [h, w] {
                    return Err(bad("mask", format!("shape {:?} differs from the image's ({h}, {w})", a.shape)));
                }
                Image::from_vec(w, h, 1, a.data).map_err(|e| bad("mask", e))?
            }
            None => depth.valid_mask(),
        };
        let lambda = match lam {
            None => LambdaChoice::Fixed(DEFAULT_LAMBDA),
            Some(l) if l.is_none() => LambdaChoice::Fixed(DEFAULT_LAMBDA),
            Some(l) => {
                if let Ok(s) = l.extract::<String>() {
                    if s != "auto" {
                        return Err(bad("lam", format!("'{s}' (expected None, a float in [0, 1) or \"auto\")")));
                    }
                    CpcParams::auto_lambda()
                } else {
                    let v: f64 = l.extract().map_err(|_| {
                        pyo3::exceptions::PyTypeError::new_err("lam: expected None, a float or \"auto\"")
                    })?;
                    if !(0.0..1.0).contains(&v) {
                        return Err(bad("lam", format!("{v} (expected 0 <= lam < 1)")));
                    }
                    LambdaChoice::Fixed(v)
                }
            }
        };
        for (n, v) in
            [("max_view_angle_deg", max_view_angle_deg), ("max_depth_jump", max_depth_jump), ("theta_deg", theta_deg)]
        {
            if !v.is_finite() {
                return Err(bad(n, format!("{v} is not finite")));
            }
        }
        if grid_step_px == 0 {
            return Err(bad("grid_step_px", "must be >= 1"));
        }
        let params = CpcParams {
            mesh: MeshParams {
                grid_step_px,
                max_rel_depth_jump: max_depth_jump,
                max_view_angle_deg: if max_view_angle_deg >= 90.0 { None } else { Some(max_view_angle_deg) },
                ..MeshParams::default()
            },
            conformal: ConformalParams { theta_rad: theta_deg.to_radians(), ..ConformalParams::default() },
            lambda,
            equiareal: if equiareal { Some(Default::default()) } else { None },
            // the CLI's default magnification limit (rim spikes masked out, issue 11)
            ..CpcParams::default()
        };
        let r = par(py, || cpc_warp(&img, &depth, &k, &roi, &params)).map_err(lib_err)?;
        let out = PyDict::new(py);
        out.set_item("stats", to_py(py, &r.stats)?)?;
        if let Some(s) = &r.sweep {
            out.set_item("sweep", to_py(py, s)?)?;
        }
        out.set_item("warped", image_to_numpy(py, r.warped)?)?;
        out.set_item("mask", image_to_numpy(py, r.mask)?)?;
        out.set_item("warp", Py::new(py, PyCpcWarp { warp: r.warp })?)?;
        Ok(out)
    })
}
