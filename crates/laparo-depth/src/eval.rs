//! Evaluation of files and of whole manifests (thesis §3.2.7): read predictions, ground truth
//! and masks, align and score every (frame, method) pair in parallel (rayon) with a
//! deterministic output order (frame order of the manifest, then method order).
use crate::align::{Alignment, DepthRange, PredKind};
use crate::error::{DepthError, Result};
use crate::manifest::{Manifest, MethodSpec, ResolvedFrame};
use crate::metrics::{evaluate_valid, select_valid, InvalidPredPolicy, PairMetrics, PairOptions, ValidPixels};
use crate::robustness::Layout;
use laparo_core::image::{Image, Mask};
pub use laparo_core::shard::Shard;
use laparo_core::stats::median;
use laparo_core::DepthUnit;
use rayon::prelude::*;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

/// Read a single-channel prediction map (npy, npz, pfm, tif, png16).
pub fn read_prediction(path: &Path) -> Result<Image<f64>> {
    let img = laparo_core::io::read_float_map(path)?;
    if img.channels != 1 {
        return Err(DepthError::file(path, format!("prediction has {} channels, expected 1", img.channels)));
    }
    if img.width == 0 || img.height == 0 {
        return Err(DepthError::file(path, "prediction is empty"));
    }
    Ok(img)
}

/// Read a GT depth map stored in `unit`, returned in metres (invalid → NaN).
pub fn read_gt_m(path: &Path, unit: DepthUnit) -> Result<Image<f64>> {
    let d = laparo_core::io::read_depth(path, unit)?;
    Ok(d.to_unit(DepthUnit::M).to_image())
}

/// Read an ROI mask with the shared reader ([`laparo_core::io::read_mask`]): image files are
/// inside where channel 0 is non-zero, float maps (npy/npz/pfm/exr/float TIFF) where finite and non-zero.
pub fn read_mask(path: &Path) -> Result<Mask> {
    Ok(laparo_core::io::read_mask(path)?)
}

/// Attach file names to the in-memory errors of [`select_valid`].
fn name_files(e: DepthError, pred: &Path, gt: &Path, mask: Option<&Path>) -> DepthError {
    match e {
        DepthError::Invalid { what, msg } => match what.as_str() {
            "prediction" => DepthError::file(pred, format!("prediction {msg} (ground truth {})", gt.display())),
            "ground truth" => DepthError::file(gt, format!("ground truth {msg}")),
            "mask" => match mask {
                Some(m) => DepthError::file(m, format!("mask {msg} (ground truth {})", gt.display())),
                None => DepthError::file(gt, format!("mask {msg}")),
            },
            _ => DepthError::file(pred, format!("{what}: {msg} (ground truth {})", gt.display())),
        },
        other => other,
    }
}

fn check_size(a: (usize, usize), a_path: &Path, b: (usize, usize), b_path: &Path, what: &str) -> Result<()> {
    if a != b {
        return Err(DepthError::file(
            a_path,
            format!("size mismatch: {what} is {}x{}, ground truth {} is {}x{}", a.0, a.1, b_path.display(), b.0, b.1),
        ));
    }
    Ok(())
}

/// Loaded ground truth of one frame.
pub struct LoadedGt {
    /// Ground-truth depth (m), 0 / non-finite = invalid.
    pub gt_m: Image<f64>,
    /// ROI mask, if any (true = evaluated).
    pub mask: Option<Mask>,
}

/// Read GT (converted to metres) and the optional mask, checking their sizes.
pub fn load_gt(gt: &Path, unit: DepthUnit, mask: Option<&Path>) -> Result<LoadedGt> {
    let gt_m = read_gt_m(gt, unit)?;
    let mask = match mask {
        Some(m) => {
            let mk = read_mask(m)?;
            check_size(mk.size(), m, gt_m.size(), gt, "mask")?;
            Some(mk)
        }
        None => None,
    };
    Ok(LoadedGt { gt_m, mask })
}

/// Select the valid pixels of a prediction file against loaded GT (errors name the files).
pub fn valid_pixels(
    pred: &Image<f64>,
    pred_path: &Path,
    kind: PredKind,
    gt: &LoadedGt,
    gt_path: &Path,
    mask_path: Option<&Path>,
    policy: InvalidPredPolicy,
) -> Result<ValidPixels> {
    check_size(pred.size(), pred_path, gt.gt_m.size(), gt_path, "prediction")?;
    select_valid(&pred.data, kind, &gt.gt_m.data, gt.mask.as_ref().map(|m| m.data.as_slice()), policy)
        .map_err(|e| name_files(e, pred_path, gt_path, mask_path))
}

/// Evaluate one prediction file against one GT file (the `eval-pair` command).
pub fn evaluate_files(
    pred_path: &Path,
    kind: PredKind,
    gt_path: &Path,
    gt_unit: DepthUnit,
    mask_path: Option<&Path>,
    opts: &PairOptions,
) -> Result<PairMetrics> {
    Ok(evaluate_files_checked(pred_path, kind, gt_path, gt_unit, mask_path, opts, None)?.0)
}

/// [`evaluate_files`], optionally resizing the prediction to the GT size first (`resize`), and
/// returning the range check of the GT ([`GtRangeCheck`]) for the caller to report.
pub fn evaluate_files_checked(
    pred_path: &Path,
    kind: PredKind,
    gt_path: &Path,
    gt_unit: DepthUnit,
    mask_path: Option<&Path>,
    opts: &PairOptions,
    resize: Option<ResizeFilter>,
) -> Result<(PairMetrics, GtRangeCheck)> {
    opts.range.validate()?;
    let gt = load_gt(gt_path, gt_unit, mask_path)?;
    let mut pred = read_prediction(pred_path)?;
    if let Some(f) = resize {
        if pred.size() != gt.gt_m.size() {
            pred = resize_map(&pred, gt.gt_m.width, gt.gt_m.height, f)?;
        }
    }
    let check = GtRangeCheck::new(&gt.gt_m.data, gt.mask.as_ref().map(|m| m.data.as_slice()), opts.range);
    let v = valid_pixels(&pred, pred_path, kind, &gt, gt_path, mask_path, opts.invalid_pred)?;
    Ok((evaluate_valid(&v, opts), check))
}

/// Interpolation used to bring a prediction at network resolution to the GT size.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ResizeFilter {
    /// Bilinear between the four nearest pixel centres (NaN propagates: invalid stays invalid).
    Bilinear,
    /// Nearest pixel centre.
    Nearest,
}

impl std::str::FromStr for ResizeFilter {
    type Err = DepthError;
    fn from_str(s: &str) -> Result<Self> {
        match s.to_ascii_lowercase().as_str() {
            "bilinear" | "linear" => Ok(ResizeFilter::Bilinear),
            "nearest" => Ok(ResizeFilter::Nearest),
            _ => Err(DepthError::invalid("resize filter", format!("'{s}' (expected bilinear or nearest)"))),
        }
    }
}

/// Resize a single-channel map to `width`×`height` px with pixel centres aligned
/// (`x_src = (x + 0.5)·w_src/w − 0.5`, OpenCV's `resize` convention), clamped to the source:
/// `laparo_core::remap::resize` (positions in f32 as in every `CoordMap`); invalid samples NaN.
pub fn resize_map(img: &Image<f64>, width: usize, height: usize, filter: ResizeFilter) -> Result<Image<f64>> {
    let interp = match filter {
        ResizeFilter::Bilinear => laparo_core::remap::Interp::Bilinear,
        ResizeFilter::Nearest => laparo_core::remap::Interp::Nearest,
    };
    let (out, _) = laparo_core::remap::resize(img, width, height, interp, f64::NAN)
        .map_err(|e| DepthError::invalid("resize", e.to_string()))?;
    Ok(out)
}

/// Where the valid GT depth lies with respect to the clamp range of aligned predictions, and
/// whether its magnitude is plausible for the declared unit (all depths in metres).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct GtRangeCheck {
    /// Valid GT pixels (finite, > 0, inside the mask).
    pub n_valid: usize,
    /// Valid GT pixels nearer than the clamp range.
    pub n_below: usize,
    /// Valid GT pixels farther than the clamp range.
    pub n_above: usize,
    /// Median valid GT depth (m); NaN without valid pixels.
    pub median_m: f64,
    /// The clamp range checked against.
    pub min_m: f64,
    /// The clamp range checked against.
    pub max_m: f64,
}

/// Fraction of valid GT outside the clamp range above which a warning is due.
pub const GT_OUTSIDE_WARN_FRACTION: f64 = 0.05;
/// Median GT depth (m) below which the GT unit is implausible (metres read as millimetres):
/// nearer than the 1 cm near clamp of the surgical default.
pub const GT_MEDIAN_MIN_PLAUSIBLE_M: f64 = 0.01;
/// Median GT depth (m) above which the GT unit is implausible (millimetres read as metres).
pub const GT_MEDIAN_MAX_PLAUSIBLE_M: f64 = 20.0;

impl GtRangeCheck {
    /// Count the valid GT values (metres) of `gt_m` (inside `mask` when given) outside `range`.
    pub fn new(gt_m: &[f64], mask: Option<&[bool]>, range: DepthRange) -> Self {
        let mut valid: Vec<f64> = match mask {
            Some(m) => gt_m.iter().zip(m).filter(|(z, &k)| k && z.is_finite() && **z > 0.0).map(|(z, _)| *z).collect(),
            None => gt_m.iter().copied().filter(|z| z.is_finite() && *z > 0.0).collect(),
        };
        let n_below = valid.iter().filter(|&&z| z < range.min_m).count();
        let n_above = valid.iter().filter(|&&z| z > range.max_m).count();
        GtRangeCheck {
            n_valid: valid.len(),
            n_below,
            n_above,
            median_m: median(&mut valid),
            min_m: range.min_m,
            max_m: range.max_m,
        }
    }

    /// Fraction of the valid GT outside the clamp range (0 without valid pixels).
    pub fn fraction_outside(&self) -> f64 {
        if self.n_valid == 0 {
            0.0
        } else {
            (self.n_below + self.n_above) as f64 / self.n_valid as f64
        }
    }

    /// Totals over frames; the median is the median of the per-frame medians.
    pub fn merge_all(checks: &[GtRangeCheck]) -> GtRangeCheck {
        let mut meds: Vec<f64> = checks.iter().map(|c| c.median_m).filter(|m| m.is_finite()).collect();
        GtRangeCheck {
            n_valid: checks.iter().map(|c| c.n_valid).sum(),
            n_below: checks.iter().map(|c| c.n_below).sum(),
            n_above: checks.iter().map(|c| c.n_above).sum(),
            median_m: median(&mut meds),
            min_m: checks.first().map_or(f64::NAN, |c| c.min_m),
            max_m: checks.first().map_or(f64::NAN, |c| c.max_m),
        }
    }

    /// Human-readable warnings (empty when the GT looks consistent with the range and unit).
    /// `what` names the GT (a file or "the manifest's GT"); `flags` names the options to change.
    pub fn warnings(&self, what: &str, range_flags: &str) -> Vec<String> {
        let mut w = Vec::new();
        if self.median_m.is_finite() && self.median_m > GT_MEDIAN_MAX_PLAUSIBLE_M {
            w.push(format!(
                "{what}: median ground-truth depth is {:.1} m, implausible: millimetres read as metres? (check the GT unit)",
                self.median_m
            ));
        } else if self.median_m.is_finite() && self.median_m < GT_MEDIAN_MIN_PLAUSIBLE_M {
            w.push(format!(
                "{what}: median ground-truth depth is {:.3} mm, implausible: metres read as millimetres? (check the GT unit)",
                self.median_m * 1e3
            ));
        }
        let f = self.fraction_outside();
        if f > GT_OUTSIDE_WARN_FRACTION {
            w.push(format!(
                "{what}: {:.1} % of the valid ground truth lies outside the clamp range [{}, {}] m of aligned predictions \
                 ({} nearer, {} farther; median {:.3} m); metrics are meaningless unless the range fits the scene: set {range_flags}",
                100.0 * f,
                self.min_m,
                self.max_m,
                self.n_below,
                self.n_above,
                self.median_m
            ));
        }
        w
    }
}

/// Settings of a manifest evaluation.
#[derive(Clone, Debug)]
pub struct EvalConfig {
    /// Methods to evaluate (manifest names); all when empty.
    pub methods: Vec<String>,
    /// Alignments to evaluate.
    pub alignments: Vec<Alignment>,
    /// Handling of invalid predictions on valid GT pixels.
    pub invalid_pred: InvalidPredPolicy,
    /// Clamp range of aligned depth overriding the manifest's `depth_min_m`/`depth_max_m`.
    pub range: Option<DepthRange>,
}

impl Default for EvalConfig {
    fn default() -> Self {
        EvalConfig {
            methods: Vec::new(),
            alignments: Alignment::ALL.to_vec(),
            invalid_pred: Default::default(),
            range: None,
        }
    }
}

/// Metrics of one (frame, method) pair.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ImageResult {
    /// Index in [`EvalOutput::frames`].
    pub frame: usize,
    /// Index in [`EvalOutput::methods`].
    pub method: usize,
    /// Metrics of this image under every evaluated alignment.
    pub metrics: PairMetrics,
}

/// Everything an evaluation produced, in deterministic order.
#[derive(Clone, Debug)]
pub struct EvalOutput {
    /// The evaluated methods.
    pub methods: Vec<MethodSpec>,
    /// The evaluated alignments.
    pub alignments: Vec<Alignment>,
    /// Names of scenes and perturbations (indices of the frames).
    pub layout: Layout,
    /// The evaluated frames.
    pub frames: Vec<ResolvedFrame>,
    /// Sorted by (frame, method).
    pub images: Vec<ImageResult>,
    /// Options used for every image.
    pub options: PairOptions,
    /// The manifest that was evaluated.
    pub manifest: PathBuf,
    /// Range check of each frame's GT, in frame order (see [`GtRangeCheck`]).
    pub gt_checks: Vec<GtRangeCheck>,
}

fn evaluate_frame(
    m: &Manifest,
    f: &ResolvedFrame,
    methods: &[(usize, &MethodSpec)],
    opts: &PairOptions,
) -> Result<(Vec<ImageResult>, GtRangeCheck)> {
    let gt = load_gt(&f.gt, f.gt_unit, f.mask.as_deref())?;
    let check = GtRangeCheck::new(&gt.gt_m.data, gt.mask.as_ref().map(|m| m.data.as_slice()), opts.range);
    let spec = &m.frames[f.index];
    let mut out = Vec::with_capacity(methods.len());
    for (k, (_, ms)) in methods.iter().enumerate() {
        let pp = m.prediction_path(ms, f, spec);
        let pred = read_prediction(&pp)?;
        let v = valid_pixels(&pred, &pp, ms.kind, &gt, &f.gt, f.mask.as_deref(), opts.invalid_pred)?;
        out.push(ImageResult { frame: f.index, method: k, metrics: evaluate_valid(&v, opts) });
    }
    Ok((out, check))
}

/// Evaluate every frame of `manifest` for the chosen methods and alignments. `progress` is
/// called with the number of frames done (from worker threads). The manifest is validated
/// first (all missing files are reported at once); any failing image fails the run, and the
/// error lists the failing files in frame order.
pub fn evaluate_manifest(
    manifest: &Manifest,
    cfg: &EvalConfig,
    progress: &(dyn Fn(usize) + Sync),
) -> Result<EvalOutput> {
    let shard = evaluate_manifest_shard(manifest, cfg, Shard::ALL, progress)?;
    merge_eval_shards(manifest, cfg, &[shard])
}

/// File name of a manifest-evaluation shard: `eval-shard-I-of-N.json`.
pub fn shard_file_name(shard: Shard) -> String {
    format!("eval-shard-{}-of-{}.json", shard.index, shard.count)
}

/// The per-frame results of one shard of a manifest evaluation ([`evaluate_manifest_shard`]);
/// [`merge_eval_shards`] turns all shards into the [`EvalOutput`] of one unsharded run.
#[derive(Clone, Debug, PartialEq)]
pub struct EvalShard {
    /// Which shard.
    pub shard: Shard,
    /// Number of frames of the manifest.
    pub n_frames: usize,
    /// Evaluated method names, in order.
    pub methods: Vec<String>,
    /// Frame indices of this shard, ascending.
    pub frames: Vec<usize>,
    /// Results of these frames, sorted by (frame, method).
    pub images: Vec<ImageResult>,
    /// GT range check of each frame of `frames`.
    pub gt_checks: Vec<GtRangeCheck>,
}

fn bits(v: f64) -> String {
    format!("{:016x}", v.to_bits())
}

fn unbits(v: &serde_json::Value) -> Option<f64> {
    u64::from_str_radix(v.as_str()?, 16).ok().map(f64::from_bits)
}

fn metrics_from_values(v: &[f64; 12]) -> crate::metrics::Metrics {
    crate::metrics::Metrics {
        abs_rel: v[0],
        sq_rel: v[1],
        rmse: v[2],
        rmse_log: v[3],
        silog: v[4],
        delta_0_25: v[5],
        delta_0_5: v[6],
        delta_1: v[7],
        delta_2: v[8],
        delta_3: v[9],
        scale: v[10],
        shift: v[11],
    }
}

impl EvalShard {
    /// JSON text; every float is stored as its IEEE-754 bit pattern (hex) so that merging
    /// shards reproduces an unsharded run bit for bit (NaN included).
    pub fn to_json_string(&self) -> String {
        let m = |m: &Option<crate::metrics::Metrics>| match m {
            Some(m) => serde_json::Value::Array(m.values().iter().map(|&v| bits(v).into()).collect()),
            None => serde_json::Value::Null,
        };
        let v = serde_json::json!({
            "format": "laparo depth eval shard v1",
            "shard": self.shard,
            "n_frames": self.n_frames,
            "methods": self.methods,
            "frames": self.frames,
            "images": self.images.iter().map(|r| serde_json::json!({
                "frame": r.frame, "method": r.method, "n_valid": r.metrics.n_valid,
                "n_invalid_pred": r.metrics.n_invalid_pred, "none": m(&r.metrics.none),
                "scale": m(&r.metrics.scale), "scale_shift": m(&r.metrics.scale_shift),
            })).collect::<Vec<_>>(),
            "gt_checks": self.gt_checks.iter().map(|c| serde_json::json!({
                "n_valid": c.n_valid, "n_below": c.n_below, "n_above": c.n_above,
                "median_m": bits(c.median_m), "min_m": bits(c.min_m), "max_m": bits(c.max_m),
            })).collect::<Vec<_>>(),
        });
        serde_json::to_string_pretty(&v).expect("JSON values serialise") + "\n"
    }

    /// Parse [`EvalShard::to_json_string`] output; `what` names the source in errors.
    pub fn from_json_str(text: &str, what: &str) -> Result<EvalShard> {
        let err = |m: &str| DepthError::invalid(what, format!("not a depth eval shard file ({m})"));
        let v: serde_json::Value = serde_json::from_str(text).map_err(|e| err(&e.to_string()))?;
        if v["format"] != "laparo depth eval shard v1" {
            return Err(err("format"));
        }
        let shard: Shard = serde_json::from_value(v["shard"].clone()).map_err(|e| err(&e.to_string()))?;
        let us = |x: &serde_json::Value, k: &str| x[k].as_u64().map(|u| u as usize).ok_or_else(|| err(k));
        let metrics = |x: &serde_json::Value| -> Result<Option<crate::metrics::Metrics>> {
            if x.is_null() {
                return Ok(None);
            }
            let a = x.as_array().filter(|a| a.len() == 12).ok_or_else(|| err("metrics"))?;
            let mut out = [0.0; 12];
            for (o, y) in out.iter_mut().zip(a) {
                *o = unbits(y).ok_or_else(|| err("metric value"))?;
            }
            Ok(Some(metrics_from_values(&out)))
        };
        let mut images = Vec::new();
        for r in v["images"].as_array().ok_or_else(|| err("images"))? {
            images.push(ImageResult {
                frame: us(r, "frame")?,
                method: us(r, "method")?,
                metrics: PairMetrics {
                    n_valid: us(r, "n_valid")?,
                    n_invalid_pred: us(r, "n_invalid_pred")?,
                    none: metrics(&r["none"])?,
                    scale: metrics(&r["scale"])?,
                    scale_shift: metrics(&r["scale_shift"])?,
                },
            });
        }
        let mut gt_checks = Vec::new();
        for c in v["gt_checks"].as_array().ok_or_else(|| err("gt_checks"))? {
            let f = |k: &str| unbits(&c[k]).ok_or_else(|| err(k));
            gt_checks.push(GtRangeCheck {
                n_valid: us(c, "n_valid")?,
                n_below: us(c, "n_below")?,
                n_above: us(c, "n_above")?,
                median_m: f("median_m")?,
                min_m: f("min_m")?,
                max_m: f("max_m")?,
            });
        }
        let frames: Vec<usize> = serde_json::from_value(v["frames"].clone()).map_err(|e| err(&e.to_string()))?;
        let methods: Vec<String> = serde_json::from_value(v["methods"].clone()).map_err(|e| err(&e.to_string()))?;
        if frames.len() != gt_checks.len() {
            return Err(err("frames vs gt_checks"));
        }
        Ok(EvalShard { shard, n_frames: us(&v, "n_frames")?, methods, frames, images, gt_checks })
    }
}

/// Settings shared by a shard evaluation and the merge.
struct Prepared<'a> {
    names: Vec<String>,
    methods: Vec<(usize, &'a MethodSpec)>,
    opts: PairOptions,
    resolved: crate::manifest::Resolved,
}

fn prepare<'a>(manifest: &'a Manifest, cfg: &EvalConfig) -> Result<Prepared<'a>> {
    let names: Vec<String> = if cfg.methods.is_empty() {
        manifest.methods.iter().map(|m| m.name.clone()).collect()
    } else {
        cfg.methods.clone()
    };
    let rep = manifest.validate(Some(&names));
    if !rep.ok() {
        return Err(DepthError::Manifest { path: manifest.source.clone(), problems: rep.problems });
    }
    if cfg.alignments.is_empty() {
        return Err(DepthError::invalid("alignment", "no alignment selected"));
    }
    let resolved = manifest.resolve()?;
    let methods: Vec<(usize, &MethodSpec)> =
        names.iter().map(|n| manifest.methods.iter().enumerate().find(|(_, m)| m.name == *n).unwrap()).collect();
    if let Some(r) = cfg.range {
        r.validate()?;
    }
    let range = cfg.range.unwrap_or(resolved.range);
    let opts = PairOptions { alignments: cfg.alignments.clone(), range, invalid_pred: cfg.invalid_pred };
    Ok(Prepared { names, methods, opts, resolved })
}

/// Evaluate the frames of one [`Shard`] of `manifest` (frame `i` belongs to shard `i % N`).
/// Errors as [`evaluate_manifest`].
pub fn evaluate_manifest_shard(
    manifest: &Manifest,
    cfg: &EvalConfig,
    shard: Shard,
    progress: &(dyn Fn(usize) + Sync),
) -> Result<EvalShard> {
    let shard = Shard::new(shard.index, shard.count).map_err(|e| DepthError::invalid("shard", e.to_string()))?;
    let p = prepare(manifest, cfg)?;
    let done = AtomicUsize::new(0);
    let mine: Vec<&ResolvedFrame> = p.resolved.frames.iter().filter(|f| shard.contains(f.index)).collect();
    let results: Vec<Result<(Vec<ImageResult>, GtRangeCheck)>> = mine
        .par_iter()
        .map(|f| {
            let r = evaluate_frame(manifest, f, &p.methods, &p.opts);
            progress(done.fetch_add(1, Ordering::Relaxed) + 1);
            r
        })
        .collect();
    let mut images = Vec::with_capacity(results.len() * p.methods.len());
    let mut errors = Vec::new();
    let mut gt_checks = Vec::with_capacity(results.len());
    for r in results {
        match r {
            Ok((v, c)) => {
                images.extend(v);
                gt_checks.push(c);
            }
            Err(e) => errors.push(e),
        }
    }
    if errors.len() == 1 {
        return Err(errors.pop().unwrap());
    }
    if !errors.is_empty() {
        let n = errors.len();
        let mut msg: Vec<String> = errors.iter().take(20).map(|e| e.to_string()).collect();
        if n > 20 {
            msg.push(format!("... and {} more", n - 20));
        }
        return Err(DepthError::invalid("evaluation", format!("{n} frames failed:\n  {}", msg.join("\n  "))));
    }
    Ok(EvalShard {
        shard,
        n_frames: p.resolved.frames.len(),
        methods: p.names,
        frames: mine.iter().map(|f| f.index).collect(),
        images,
        gt_checks,
    })
}

/// Merge the shards 0..N of one evaluation (any order) into the [`EvalOutput`] of an unsharded
/// run with the same manifest and configuration. Fails when a shard is missing, duplicated,
/// or was made with other methods or another manifest size.
pub fn merge_eval_shards(manifest: &Manifest, cfg: &EvalConfig, shards: &[EvalShard]) -> Result<EvalOutput> {
    let p = prepare(manifest, cfg)?;
    let n = p.resolved.frames.len();
    let count = shards.first().map(|s| s.shard.count).ok_or_else(|| DepthError::invalid("shards", "none given"))?;
    let mut seen = vec![false; count];
    let mut per_frame: Vec<Option<(Vec<ImageResult>, GtRangeCheck)>> = vec![None; n];
    for s in shards {
        if s.shard.count != count || s.shard.index >= count {
            return Err(DepthError::invalid("shards", format!("shard {} mixed with shards of {count}", s.shard)));
        }
        if std::mem::replace(&mut seen[s.shard.index], true) {
            return Err(DepthError::invalid("shards", format!("shard {} given twice", s.shard)));
        }
        if s.n_frames != n || s.methods != p.names {
            return Err(DepthError::invalid(
                "shards",
                format!(
                    "shard {} was made with {} frames and methods [{}], this run has {n} frames and methods [{}]",
                    s.shard,
                    s.n_frames,
                    s.methods.join(", "),
                    p.names.join(", ")
                ),
            ));
        }
        for (k, &f) in s.frames.iter().enumerate() {
            if f >= n || !s.shard.contains(f) {
                return Err(DepthError::invalid("shards", format!("shard {} lists frame {f}", s.shard)));
            }
            let imgs: Vec<ImageResult> = s.images.iter().filter(|r| r.frame == f).cloned().collect();
            per_frame[f] = Some((imgs, s.gt_checks[k]));
        }
    }
    if let Some(i) = seen.iter().position(|x| !x) {
        return Err(DepthError::invalid("shards", format!("shard {i}/{count} is missing")));
    }
    let mut images = Vec::with_capacity(n * p.methods.len());
    let mut gt_checks = Vec::with_capacity(n);
    for (f, r) in per_frame.into_iter().enumerate() {
        let (v, c) = r.ok_or_else(|| DepthError::invalid("shards", format!("frame {f} is in no shard")))?;
        images.extend(v);
        gt_checks.push(c);
    }
    Ok(EvalOutput {
        methods: p.methods.iter().map(|(_, m)| (*m).clone()).collect(),
        alignments: cfg.alignments.clone(),
        layout: p.resolved.layout,
        frames: p.resolved.frames,
        images,
        options: p.opts,
        manifest: manifest.source.clone(),
        gt_checks,
    })
}
