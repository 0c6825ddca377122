//! `laparo.depth`: RoDEM metrics (thesis §3.2.7, eqs. 3.1–3.2) and perturbations (§3.2.6).
use crate::arrays::*;
use laparo_core::{DepthMap, DepthUnit, Image};
use laparo_depth::align::{Alignment, DepthRange, PredKind};
use laparo_depth::metrics::{evaluate_pair, PairOptions};
use laparo_depth::perturb::{self, Perturbation};
use pyo3::prelude::*;
use pyo3::types::PyList;
use rayon::prelude::*;

fn parse<T: std::str::FromStr>(s: &str, arg: &str) -> PyResult<T>
where
    T::Err: std::fmt::Display,
{
    s.parse::<T>().map_err(|e| bad(arg, e))
}

fn options(alignments: &str, depth_min_m: f64, depth_max_m: f64, invalid_pred: &str) -> PyResult<PairOptions> {
    Ok(PairOptions {
        alignments: Alignment::parse_list(alignments).map_err(|e| bad("alignments", e))?,
        range: DepthRange::new(depth_min_m, depth_max_m).map_err(|e| bad("depth_min_m/depth_max_m", e))?,
        invalid_pred: parse(invalid_pred, "invalid_pred")?,
    })
}

/// GT values in `unit` → metres, exactly as `laparo depth eval-pair` reads a GT file.
fn gt_metres(shape: &[usize], data: &[f64], unit: DepthUnit) -> PyResult<Vec<f64>> {
    if unit == DepthUnit::M {
        return Ok(data.to_vec());
    }
    let (h, w) = match shape {
        [h, w] => (*h, *w),
        _ => (1, data.len()),
    };
    let d = DepthMap::new(w, h, unit, data.to_vec()).map_err(|e| bad("gt", e))?;
    Ok(d.to_unit(DepthUnit::M).data)
}

fn check_pair_shapes(p: &[usize], g: &[usize]) -> PyResult<()> {
    if p.is_empty() || p.contains(&0) {
        return Err(bad("pred", format!("empty array of shape {p:?}")));
    }
    if p != g {
        return Err(bad("pred", format!("shape {p:?} differs from gt shape {g:?}")));
    }
    Ok(())
}

/// evaluate_pair(pred, gt, mask, pred_kind, gt_unit, alignments, depth_min_m, depth_max_m,
/// invalid_pred) → dict with the keys of `laparo depth eval-pair --json`.
#[pyfunction]
#[pyo3(signature = (pred, gt, mask, pred_kind, gt_unit, alignments, depth_min_m, depth_max_m, invalid_pred))]
#[allow(clippy::too_many_arguments)]
pub fn depth_evaluate_pair<'py>(
    py: Python<'py>,
    pred: &Bound<'py, PyAny>,
    gt: &Bound<'py, PyAny>,
    mask: Option<&Bound<'py, PyAny>>,
    pred_kind: &str,
    gt_unit: &str,
    alignments: &str,
    depth_min_m: f64,
    depth_max_m: f64,
    invalid_pred: &str,
) -> PyResult<Bound<'py, PyAny>> {
    guard(|| {
        let kind: PredKind = parse(pred_kind, "pred_kind")?;
        let unit: DepthUnit = parse(gt_unit, "gt_unit")?;
        let opts = options(alignments, depth_min_m, depth_max_m, invalid_pred)?;
        let mask = mask.map(|m| bool_array(m, "mask")).transpose()?;
        let r = with_f64(gt, "gt", |gs, gd| {
            let gt_m = gt_metres(gs, gd, unit)?;
            with_f64(pred, "pred", |ps, pd| {
                check_pair_shapes(ps, gs)?;
                if let Some(m) = &mask {
                    if m.shape != gs {
                        return Err(bad("mask", format!("shape {:?} differs from gt shape {gs:?}", m.shape)));
                    }
                }
                let md = mask.as_ref().map(|m| m.data.as_slice());
                par(py, || evaluate_pair(pd, kind, &gt_m, md, &opts)).map_err(lib_err)
            })
        })?;
        to_py(py, &r)
    })
}

/// Batched evaluate_pair over stacks (B, H, W) (or lists of arrays), in parallel; a list of dicts.
#[pyfunction]
#[pyo3(signature = (preds, gts, masks, pred_kind, gt_unit, alignments, depth_min_m, depth_max_m, invalid_pred))]
#[allow(clippy::too_many_arguments)]
pub fn depth_evaluate_batch<'py>(
    py: Python<'py>,
    preds: Vec<Bound<'py, PyAny>>,
    gts: Vec<Bound<'py, PyAny>>,
    masks: Option<Vec<Option<Bound<'py, PyAny>>>>,
    pred_kind: &str,
    gt_unit: &str,
    alignments: &str,
    depth_min_m: f64,
    depth_max_m: f64,
    invalid_pred: &str,
) -> PyResult<Bound<'py, PyList>> {
    guard(|| {
        let kind: PredKind = parse(pred_kind, "pred_kind")?;
        let unit: DepthUnit = parse(gt_unit, "gt_unit")?;
        let opts = options(alignments, depth_min_m, depth_max_m, invalid_pred)?;
        if preds.len() != gts.len() {
            return Err(bad("preds", format!("{} predictions for {} ground truths", preds.len(), gts.len())));
        }
        if let Some(m) = &masks {
            if m.len() != gts.len() {
                return Err(bad("masks", format!("{} masks for {} ground truths", m.len(), gts.len())));
            }
        }
        let mut items = Vec::with_capacity(preds.len());
        for i in 0..preds.len() {
            let p = f64_array(&preds[i], &format!("preds[{i}]"))?;
            let g = f64_array(&gts[i], &format!("gts[{i}]"))?;
            check_pair_shapes(&p.shape, &g.shape).map_err(|e| bad(&format!("preds[{i}]"), e))?;
            let gm = gt_metres(&g.shape, &g.data, unit)?;
            let m = match masks.as_ref().and_then(|m| m[i].as_ref()) {
                Some(m) => {
                    let a = bool_array(m, &format!("masks[{i}]"))?;
                    if a.shape != g.shape {
                        return Err(bad(&format!("masks[{i}]"), format!("shape {:?} vs gt {:?}", a.shape, g.shape)));
                    }
                    Some(a.data)
                }
                None => None,
            };
            items.push((p.data, gm, m));
        }
        let results: Vec<_> =
            par(py, || items.par_iter().map(|(p, g, m)| evaluate_pair(p, kind, g, m.as_deref(), &opts)).collect());
        let out = PyList::empty(py);
        for (i, r) in results.into_iter().enumerate() {
            let r = r.map_err(|e| bad(&format!("item {i}"), e))?;
            out.append(to_py(py, &r)?)?;
        }
        Ok(out)
    })
}

fn perturbation(kind: &str) -> PyResult<Perturbation> {
    Perturbation::ALL.into_iter().find(|p| p.name() == kind || format!("{p:?}").eq_ignore_ascii_case(kind)).ok_or_else(
        || {
            let names: Vec<&str> = Perturbation::ALL.iter().map(|p| p.name()).collect();
            bad("kind", format!("'{kind}' (expected one of {})", names.join(", ")))
        },
    )
}

/// perturb(image uint8 (H, W[, C]), kind, severity, seed) → uint8 (H, W, 3).
#[pyfunction]
pub fn depth_perturb<'py>(
    py: Python<'py>,
    image: &Bound<'py, PyAny>,
    kind: &str,
    severity: i64,
    seed: u64,
) -> PyResult<Bound<'py, PyAny>> {
    guard(|| {
        let k = perturbation(kind)?;
        if !(1..=3).contains(&severity) {
            return Err(bad("severity", format!("{severity} (expected 1, 2 or 3)")));
        }
        let a = u8_array(image, "image")?;
        let (h, w, c) = a.hwc("image")?;
        if ![1, 3, 4].contains(&c) {
            return Err(bad("image", format!("{c} channels (expected 1, 3 or 4)")));
        }
        let img = Image::from_vec(w, h, c, a.data).map_err(|e| bad("image", e))?;
        let out = par(py, || perturb::apply(&img, k, severity as u8, seed)).map_err(|e| bad("image", e))?;
        image_to_numpy(py, out)
    })
}

/// The per-item seed of `laparo depth perturb` (so Python reproduces the CLI's files).
#[pyfunction]
pub fn depth_item_seed(base: u64, name: &str, kind: &str) -> PyResult<u64> {
    Ok(perturb::item_seed(base, name, perturbation(kind)?))
}

/// Names of the perturbation kinds.
#[pyfunction]
pub fn depth_perturbation_kinds() -> Vec<&'static str> {
    Perturbation::ALL.iter().map(|p| p.name()).collect()
}
