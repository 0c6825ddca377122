//! Evaluation of files and of whole manifests (thesis §3.2.7): read predictions, ground truth
//! and masks, align and score every (frame, method) pair in parallel (rayon) with a
//! deterministic output order (frame order of the manifest, then method order).
use crate::align::{Alignment, PredKind};
use crate::error::{DepthError, Result};
use crate::manifest::{Manifest, MethodSpec, ResolvedFrame};
use crate::metrics::{evaluate_valid, select_valid, InvalidPredPolicy, PairMetrics, PairOptions, ValidPixels};
use crate::robustness::Layout;
use laparo_core::image::{Image, Mask};
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
    opts.range.validate()?;
    let gt = load_gt(gt_path, gt_unit, mask_path)?;
    let pred = read_prediction(pred_path)?;
    let v = valid_pixels(&pred, pred_path, kind, &gt, gt_path, mask_path, opts.invalid_pred)?;
    Ok(evaluate_valid(&v, opts))
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
}

impl Default for EvalConfig {
    fn default() -> Self {
        EvalConfig { methods: Vec::new(), alignments: Alignment::ALL.to_vec(), invalid_pred: Default::default() }
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
}

fn evaluate_frame(
    m: &Manifest,
    f: &ResolvedFrame,
    methods: &[(usize, &MethodSpec)],
    opts: &PairOptions,
) -> Result<Vec<ImageResult>> {
    let gt = load_gt(&f.gt, f.gt_unit, f.mask.as_deref())?;
    let spec = &m.frames[f.index];
    let mut out = Vec::with_capacity(methods.len());
    for (k, (_, ms)) in methods.iter().enumerate() {
        let pp = m.prediction_path(ms, f, spec);
        let pred = read_prediction(&pp)?;
        let v = valid_pixels(&pred, &pp, ms.kind, &gt, &f.gt, f.mask.as_deref(), opts.invalid_pred)?;
        out.push(ImageResult { frame: f.index, method: k, metrics: evaluate_valid(&v, opts) });
    }
    Ok(out)
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
    let opts =
        PairOptions { alignments: cfg.alignments.clone(), range: resolved.range, invalid_pred: cfg.invalid_pred };
    let done = AtomicUsize::new(0);
    let results: Vec<Result<Vec<ImageResult>>> = resolved
        .frames
        .par_iter()
        .map(|f| {
            let r = evaluate_frame(manifest, f, &methods, &opts);
            progress(done.fetch_add(1, Ordering::Relaxed) + 1);
            r
        })
        .collect();
    let mut images = Vec::with_capacity(results.len() * methods.len());
    let mut errors = Vec::new();
    for r in results {
        match r {
            Ok(v) => images.extend(v),
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
    Ok(EvalOutput {
        methods: methods.iter().map(|(_, m)| (*m).clone()).collect(),
        alignments: cfg.alignments.clone(),
        layout: resolved.layout,
        frames: resolved.frames,
        images,
        options: opts,
        manifest: manifest.source.clone(),
    })
}
