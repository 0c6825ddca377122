//! Stereo evaluation as in thesis Tables 3.7–3.8: disparity EPE and Bad-k (px) over valid
//! ground truth, and — with a calibration — depth MAE, RMSE (mm), Abs Rel (eq. 3.1) and
//! δ_0.25 (eq. 3.2) from the disparities through d = f b / z + (c_x^L − c_x^R) (§3.3.8).
//!
//! Conventions (stated because every benchmark picks its own):
//! - A ground-truth pixel is valid when its disparity is finite, it is inside the optional mask
//!   and (with [`EvalOptions::zero_is_invalid`], KITTI-style PNGs) non-zero. Negative disparities
//!   are valid: uncalibrated laparoscope pairs have them (§3.3.4).
//! - A non-finite prediction on a valid pixel is *missing*: it counts as bad for every Bad-k, is
//!   left out of the EPE mean, and its depth is the far clamp. `n_pred_missing` reports them.
//! - EPE = mean |d − d*|; Bad-k = 100 · fraction of valid pixels with |d − d*| > k (percent, as
//!   the tables print it).
//! - Depth: z* = f b / (d* − off) on valid pixels with d* > off (others are left out of the
//!   depth metrics, GT is not clamped); z = f b / (d − off), +∞ when d ≤ off, then clamped to
//!   [`EvalOptions::depth_range_mm`] (default [10, 500] mm, the MIS range of §3.2.7).
//!   MAE = mean |z − z*|, RMSE = sqrt(mean (z − z*)²), Abs Rel = mean |z − z*| / z*,
//!   δ_0.25 = fraction with max(z/z*, z*/z) < 1.25^0.25 (strict).
use crate::error::{Result, StereoError};
use crate::rectify::DisparityGeometry;
use laparo_core::image::{Image, Mask};
use serde::{Deserialize, Serialize};

/// Options of [`evaluate`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EvalOptions {
    /// Bad-k thresholds (px). Default 1, 2, 3.
    pub bad_thresholds_px: Vec<f64>,
    /// Predicted depth is clamped to `[min, max]` mm; `None` = no clamp (then a prediction at or
    /// beyond infinity makes the depth errors infinite). Default [10, 500] mm (§3.2.7).
    pub depth_range_mm: Option<(f64, f64)>,
    /// Treat GT disparity 0 as invalid (KITTI/16-bit PNG convention). Default false.
    pub zero_is_invalid: bool,
}

impl Default for EvalOptions {
    fn default() -> Self {
        EvalOptions {
            bad_thresholds_px: vec![1.0, 2.0, 3.0],
            depth_range_mm: Some((10.0, 500.0)),
            zero_is_invalid: false,
        }
    }
}

/// One Bad-k figure.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct BadK {
    /// Threshold k (px).
    pub threshold_px: f64,
    /// Percentage of valid GT pixels with |d − d*| > k (missing predictions included).
    pub percent: f64,
}

/// Depth metrics (Tables 3.7–3.8, right half).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct DepthMetrics {
    /// Pixels with valid GT depth.
    pub n_valid: usize,
    /// Mean |z − z*| (mm).
    pub mae_mm: f64,
    /// Root-mean-square z − z* (mm).
    pub rmse_mm: f64,
    /// Mean |z − z*| / z*.
    pub abs_rel: f64,
    /// Fraction (0..1) with max(z/z*, z*/z) < 1.25^0.25.
    pub delta_0_25: f64,
    /// Clamp applied to predicted depth (mm).
    pub depth_range_mm: Option<(f64, f64)>,
    /// The geometry used (f, b, principal points).
    pub geometry: DisparityGeometry,
}

/// All metrics of one prediction.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StereoMetrics {
    /// Image width (px).
    pub width: usize,
    /// Image height (px).
    pub height: usize,
    /// Valid GT pixels.
    pub n_valid: usize,
    /// Valid GT pixels without a finite prediction.
    pub n_pred_missing: usize,
    /// Mean |d − d*| (px) over valid GT pixels with a finite prediction.
    pub epe_px: f64,
    /// Bad-k fractions for each threshold k.
    pub bad: Vec<BadK>,
    /// Depth metrics, when a geometry was given.
    pub depth: Option<DepthMetrics>,
}

impl StereoMetrics {
    /// Bad-k percentage for threshold `k`, if computed.
    pub fn bad_percent(&self, k: f64) -> Option<f64> {
        self.bad.iter().find(|b| b.threshold_px == k).map(|b| b.percent)
    }

    /// A markdown table shaped like Tables 3.7–3.8, one row labelled `label`.
    pub fn markdown(&self, label: &str) -> String {
        let mut s = String::from("| | EPE (px) |");
        let mut sep = String::from("|---|---|");
        for b in &self.bad {
            s.push_str(&format!(" Bad {:.1} (%) |", b.threshold_px));
            sep.push_str("---|");
        }
        if self.depth.is_some() {
            s.push_str(" MAE (mm) | RMSE (mm) | AbsRel | δ_0.25 |");
            sep.push_str("---|---|---|---|");
        }
        s.push('\n');
        s.push_str(&sep);
        s.push('\n');
        s.push_str(&format!("| {label} | {:.3} |", self.epe_px));
        for b in &self.bad {
            s.push_str(&format!(" {:.2} |", b.percent));
        }
        if let Some(d) = &self.depth {
            s.push_str(&format!(" {:.3} | {:.3} | {:.4} | {:.3} |", d.mae_mm, d.rmse_mm, d.abs_rel, d.delta_0_25));
        }
        s.push('\n');
        s
    }
}

/// Per-pixel maps produced by [`evaluate_maps`] (NaN where undefined).
#[derive(Clone, Debug, PartialEq)]
pub struct EvalMaps {
    /// |d − d*| (px) on valid GT pixels.
    pub disparity_error_px: Image<f64>,
    /// Predicted and GT depth (mm), when a geometry was given (prediction clamped).
    pub depth_pred_mm: Option<Image<f64>>,
    /// Ground-truth depth (mm).
    pub depth_gt_mm: Option<Image<f64>>,
    /// |z − z*| (mm) on pixels with valid GT depth.
    pub depth_error_mm: Option<Image<f64>>,
}

fn validate(pred: &Image<f64>, gt: &Image<f64>, mask: Option<&Mask>, opts: &EvalOptions) -> Result<()> {
    if pred.channels != 1 || gt.channels != 1 {
        return Err(StereoError::invalid(
            "disparity",
            format!("prediction has {} channels, GT {} (need 1)", pred.channels, gt.channels),
        ));
    }
    if (pred.width, pred.height) != (gt.width, gt.height) {
        return Err(StereoError::SizeMismatch(format!(
            "prediction is {}x{}, ground truth {}x{}",
            pred.width, pred.height, gt.width, gt.height
        )));
    }
    if let Some(m) = mask {
        if (m.width, m.height) != (gt.width, gt.height) {
            return Err(StereoError::SizeMismatch(format!(
                "mask is {}x{}, ground truth {}x{}",
                m.width, m.height, gt.width, gt.height
            )));
        }
    }
    if opts.bad_thresholds_px.iter().any(|k| !(k.is_finite() && *k >= 0.0)) {
        return Err(StereoError::invalid("Bad-k threshold", format!("{:?}", opts.bad_thresholds_px)));
    }
    if let Some((lo, hi)) = opts.depth_range_mm {
        if !(lo >= 0.0 && hi > lo) || lo.is_nan() || hi.is_nan() {
            return Err(StereoError::invalid("depth range", format!("[{lo}, {hi}] mm")));
        }
    }
    Ok(())
}

/// Whether GT pixel `i` is valid.
#[inline]
fn gt_valid(gt: &Image<f64>, mask: Option<&Mask>, opts: &EvalOptions, i: usize) -> bool {
    let g = gt.data[i];
    g.is_finite() && !(opts.zero_is_invalid && g == 0.0) && mask.is_none_or(|m| m.data[i])
}

/// Predicted depth (mm) of disparity `d`, far-clamped as documented.
#[inline]
fn pred_depth(geo: &DisparityGeometry, d: f64, range: Option<(f64, f64)>) -> f64 {
    let z = geo.depth_mm(d);
    let z = if z.is_finite() { z } else { f64::INFINITY };
    match range {
        Some((lo, hi)) => z.clamp(lo, hi),
        None => z,
    }
}

/// Evaluate a predicted left disparity map against ground truth (see the module docs).
/// Fails on size mismatches, multi-channel maps, bad options, or when no GT pixel is valid.
pub fn evaluate(
    pred: &Image<f64>,
    gt: &Image<f64>,
    mask: Option<&Mask>,
    geometry: Option<&DisparityGeometry>,
    opts: &EvalOptions,
) -> Result<StereoMetrics> {
    Ok(evaluate_maps(pred, gt, mask, geometry, opts)?.0)
}

/// [`evaluate`] plus the per-pixel error and depth maps.
pub fn evaluate_maps(
    pred: &Image<f64>,
    gt: &Image<f64>,
    mask: Option<&Mask>,
    geometry: Option<&DisparityGeometry>,
    opts: &EvalOptions,
) -> Result<(StereoMetrics, EvalMaps)> {
    validate(pred, gt, mask, opts)?;
    let (w, h) = (gt.width, gt.height);
    let n_px = w * h;
    let mut err_map = Image::filled(w, h, 1, f64::NAN);
    let mut n_valid = 0usize;
    let mut n_missing = 0usize;
    let mut sum_abs = 0.0;
    let mut n_bad = vec![0usize; opts.bad_thresholds_px.len()];
    for i in 0..n_px {
        if !gt_valid(gt, mask, opts, i) {
            continue;
        }
        n_valid += 1;
        let p = pred.data[i];
        if !p.is_finite() {
            n_missing += 1;
            for b in n_bad.iter_mut() {
                *b += 1;
            }
            continue;
        }
        let e = (p - gt.data[i]).abs();
        err_map.data[i] = e;
        sum_abs += e;
        for (b, k) in n_bad.iter_mut().zip(&opts.bad_thresholds_px) {
            if e > *k {
                *b += 1;
            }
        }
    }
    if n_valid == 0 {
        return Err(StereoError::invalid("ground truth", "no valid disparity pixel (all non-finite or masked out)"));
    }
    let n_fin = n_valid - n_missing;
    let epe_px = if n_fin > 0 { sum_abs / n_fin as f64 } else { f64::NAN };
    let bad = opts
        .bad_thresholds_px
        .iter()
        .zip(&n_bad)
        .map(|(k, n)| BadK { threshold_px: *k, percent: 100.0 * *n as f64 / n_valid as f64 })
        .collect();
    let mut maps =
        EvalMaps { disparity_error_px: err_map, depth_pred_mm: None, depth_gt_mm: None, depth_error_mm: None };
    let depth = match geometry {
        None => None,
        Some(geo) => {
            if !(geo.f_px.is_finite() && geo.f_px > 0.0 && geo.baseline_mm.is_finite() && geo.baseline_mm > 0.0) {
                return Err(StereoError::invalid(
                    "calibration",
                    format!("f = {} px, b = {} mm", geo.f_px, geo.baseline_mm),
                ));
            }
            let range = opts.depth_range_mm;
            let mut zp = Image::filled(w, h, 1, f64::NAN);
            let mut zg = Image::filled(w, h, 1, f64::NAN);
            let mut ze = Image::filled(w, h, 1, f64::NAN);
            let (mut n, mut s_abs, mut s_sq, mut s_rel, mut n_delta) = (0usize, 0.0, 0.0, 0.0, 0usize);
            let thr = 1.25f64.powf(0.25);
            for i in 0..n_px {
                let p = pred_depth(geo, pred.data[i], range);
                zp.data[i] = if pred.data[i].is_finite() { p } else { f64::NAN };
                if !gt_valid(gt, mask, opts, i) {
                    continue;
                }
                let g = geo.depth_mm(gt.data[i]);
                if !g.is_finite() {
                    continue;
                }
                zg.data[i] = g;
                let e = (p - g).abs();
                ze.data[i] = e;
                n += 1;
                s_abs += e;
                s_sq += e * e;
                s_rel += e / g;
                if (p / g).max(g / p) < thr {
                    n_delta += 1;
                }
            }
            maps.depth_pred_mm = Some(zp);
            maps.depth_gt_mm = Some(zg);
            maps.depth_error_mm = Some(ze);
            if n == 0 {
                return Err(StereoError::invalid(
                    "ground truth",
                    format!(
                        "no pixel with a valid GT depth (GT disparity must exceed c_x^L − c_x^R = {})",
                        geo.offset_px()
                    ),
                ));
            }
            let nf = n as f64;
            Some(DepthMetrics {
                n_valid: n,
                mae_mm: s_abs / nf,
                rmse_mm: (s_sq / nf).sqrt(),
                abs_rel: s_rel / nf,
                delta_0_25: n_delta as f64 / nf,
                depth_range_mm: range,
                geometry: *geo,
            })
        }
    };
    Ok((StereoMetrics { width: w, height: h, n_valid, n_pred_missing: n_missing, epe_px, bad, depth }, maps))
}
