//! Depth metrics of the RoDEM protocol (thesis §3.2.7, eqs. 3.1–3.2) and validity masks.
//!
//! The definitions are those of the numpy reference `depth_eval_ref.py`, over the `N` valid
//! pixels, depth in metres, natural log:
//!
//! * `abs_rel  = mean(|z* − ẑ| / z*)` (eq. 3.1)
//! * `sq_rel   = mean((z* − ẑ)² / z*)` (metres)
//! * `rmse     = sqrt(mean((z* − ẑ)²))` (metres)
//! * `rmse_log = sqrt(mean((log z* − log ẑ)²))`
//! * `silog    = 100 · sqrt(mean(e²) − mean(e)²)`, `e = log ẑ − log z*` (KITTI/BTS form, λ = 1)
//! * `delta_t  = mean(max(z*/ẑ, ẑ/z*) < 1.25^t)`, `t ∈ {0.25, 0.5, 1, 2, 3}`, strict `<` (eq. 3.2)
//!
//! Valid pixels: ground truth finite and > 0, inside the optional ROI mask. A prediction
//! that is not finite (or, for a depth prediction, ≤ 0) on a valid pixel is *invalid*: it
//! is counted (`n_invalid_pred`) and handled by an explicit [`InvalidPredPolicy`].
//!
//! Length (~600 lines of code, ~210 of tests): the fused single-pass kernels stay next to the
//! reference definitions ([`metrics_reference`]) they are tested against bit for bit.
use crate::align::{fit, AlignParams, Alignment, DepthRange, PredKind};
use crate::error::{DepthError, Result};
use serde::{Deserialize, Serialize};

/// The exponents t of the accuracy thresholds `1.25^t` (thesis §3.2.7).
pub const DELTA_POWERS: [f64; 5] = [0.25, 0.5, 1.0, 2.0, 3.0];

/// All metrics of one prediction under one alignment, with the fitted scale and shift.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Metrics {
    /// mean(|z* − ẑ| / z*) (eq. 3.1).
    pub abs_rel: f64,
    /// mean((z* − ẑ)² / z*) (m).
    pub sq_rel: f64,
    /// sqrt(mean((z* − ẑ)²)) (m).
    pub rmse: f64,
    /// sqrt(mean((log z* − log ẑ)²)).
    pub rmse_log: f64,
    /// 100 · sqrt(mean(e²) − mean(e)²), e = log ẑ − log z*.
    pub silog: f64,
    /// Fraction with max(z*/ẑ, ẑ/z*) < 1.25^0.25 (eq. 3.2).
    #[serde(rename = "delta_0.25")]
    pub delta_0_25: f64,
    /// Fraction below 1.25^0.5.
    #[serde(rename = "delta_0.5")]
    pub delta_0_5: f64,
    /// Fraction below 1.25.
    #[serde(rename = "delta_1")]
    pub delta_1: f64,
    /// Fraction below 1.25².
    #[serde(rename = "delta_2")]
    pub delta_2: f64,
    /// Fraction below 1.25³.
    #[serde(rename = "delta_3")]
    pub delta_3: f64,
    /// Fitted disparity scale (NaN → JSON null when the prediction's median is 0).
    pub scale: f64,
    /// Fitted disparity shift.
    pub shift: f64,
}

/// Names of the metric columns, in output order (keys of depth_eval_ref.py).
pub const METRIC_NAMES: [&str; 12] = [
    "abs_rel",
    "sq_rel",
    "rmse",
    "rmse_log",
    "silog",
    "delta_0.25",
    "delta_0.5",
    "delta_1",
    "delta_2",
    "delta_3",
    "scale",
    "shift",
];

impl Metrics {
    /// delta_t for `DELTA_POWERS[i]`.
    pub fn delta(&self, i: usize) -> f64 {
        [self.delta_0_25, self.delta_0_5, self.delta_1, self.delta_2, self.delta_3][i]
    }

    /// Values in the order of [`METRIC_NAMES`].
    pub fn values(&self) -> [f64; 12] {
        [
            self.abs_rel,
            self.sq_rel,
            self.rmse,
            self.rmse_log,
            self.silog,
            self.delta_0_25,
            self.delta_0_5,
            self.delta_1,
            self.delta_2,
            self.delta_3,
            self.scale,
            self.shift,
        ]
    }

    /// The per-image error `E` used by the robustness measures (eqs. 3.3–3.4).
    pub fn error(&self, e: ErrorMetric) -> f64 {
        match e {
            ErrorMetric::AbsRel => self.abs_rel,
            ErrorMetric::OneMinusDelta025 => 1.0 - self.delta_0_25,
        }
    }
}

/// The error `E` of eqs. 3.3–3.4: Abs Rel, or 1 − δ_0.25 (thesis Tables 3.3–3.5).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ErrorMetric {
    /// Abs Rel (eq. 3.1).
    AbsRel,
    /// 1 − δ_0.25 (eq. 3.2).
    OneMinusDelta025,
}

impl ErrorMetric {
    /// Both, in the thesis' column order.
    pub const ALL: [ErrorMetric; 2] = [ErrorMetric::AbsRel, ErrorMetric::OneMinusDelta025];
    /// Column title.
    pub fn title(self) -> &'static str {
        match self {
            ErrorMetric::AbsRel => "Abs Rel",
            ErrorMetric::OneMinusDelta025 => "1 − δ0.25",
        }
    }
    /// JSON key.
    pub fn key(self) -> &'static str {
        match self {
            ErrorMetric::AbsRel => "abs_rel",
            ErrorMetric::OneMinusDelta025 => "one_minus_delta_0.25",
        }
    }
}

/// What to do with an invalid prediction (non-finite, or depth ≤ 0) on a valid GT pixel.
/// In every case the count is reported as `n_invalid_pred`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum InvalidPredPolicy {
    /// Disparity 0 ("infinitely far"), kept in the fit and the metrics: aligned depth goes to
    /// the far clamp without alignment (the reference's rule for depth predictions).
    #[default]
    Far,
    /// Removed from the valid set (fit and metrics); `n_valid` excludes them.
    Exclude,
    /// Refuse the image (the reference's rule for disparity predictions).
    Error,
}

impl std::str::FromStr for InvalidPredPolicy {
    type Err = DepthError;
    fn from_str(s: &str) -> Result<Self> {
        match s.to_ascii_lowercase().as_str() {
            "far" => Ok(InvalidPredPolicy::Far),
            "exclude" => Ok(InvalidPredPolicy::Exclude),
            "error" => Ok(InvalidPredPolicy::Error),
            _ => {
                Err(DepthError::invalid("invalid-prediction policy", format!("'{s}' (expected far, exclude or error)")))
            }
        }
    }
}

/// Options of a single prediction-vs-GT evaluation.
#[derive(Clone, Debug)]
pub struct PairOptions {
    /// Alignments to compute.
    pub alignments: Vec<Alignment>,
    /// Clamp range of aligned depth.
    pub range: DepthRange,
    /// Handling of invalid predictions.
    pub invalid_pred: InvalidPredPolicy,
}

impl Default for PairOptions {
    fn default() -> Self {
        PairOptions {
            alignments: Alignment::ALL.to_vec(),
            range: DepthRange::default(),
            invalid_pred: Default::default(),
        }
    }
}

/// The prediction (as disparity) and the ground truth on the valid pixels.
#[derive(Clone, Debug, Default)]
pub struct ValidPixels {
    /// Predicted disparity (any scale) per valid pixel.
    pub d: Vec<f64>,
    /// Ground-truth depth (m) per valid pixel.
    pub z_gt: Vec<f64>,
    /// Ground-truth disparity `1/z*` (1/m) per valid pixel.
    pub d_gt: Vec<f64>,
    /// Pixel index (row-major) of each valid pixel.
    pub index: Vec<u32>,
    /// Valid GT pixels whose prediction is invalid (non-finite, or depth ≤ 0).
    pub n_invalid_pred: usize,
    /// Pixels with a valid GT value that the ROI mask removed.
    pub n_masked_out: usize,
}

/// Select the valid pixels: GT `gt_m` (metres) finite and > 0, `mask` true if given; turn the
/// prediction into disparity. Errors (`what` = "size", "mask", "ground truth", "prediction")
/// leave the caller to name the file.
pub fn select_valid(
    pred: &[f64],
    kind: PredKind,
    gt_m: &[f64],
    mask: Option<&[bool]>,
    policy: InvalidPredPolicy,
) -> Result<ValidPixels> {
    let mut v = ValidPixels::default();
    select_valid_into(&mut v, pred, kind, gt_m, mask, policy)?;
    Ok(v)
}

fn grow<T: Copy + Default>(v: &mut Vec<T>, n: usize) {
    if v.len() < n {
        v.resize(n, T::default());
    }
}

/// [`select_valid`] into reused buffers (no allocation once they are large enough).
pub fn select_valid_into(
    v: &mut ValidPixels,
    pred: &[f64],
    kind: PredKind,
    gt_m: &[f64],
    mask: Option<&[bool]>,
    policy: InvalidPredPolicy,
) -> Result<()> {
    if pred.len() != gt_m.len() {
        return Err(DepthError::invalid(
            "size",
            format!("prediction has {} pixels, ground truth {}", pred.len(), gt_m.len()),
        ));
    }
    if let Some(m) = mask {
        if m.len() != gt_m.len() {
            return Err(DepthError::invalid(
                "size",
                format!("mask has {} pixels, ground truth {}", m.len(), gt_m.len()),
            ));
        }
        if !m.iter().any(|&b| b) {
            return Err(DepthError::invalid("mask", "selects no pixel (all false)"));
        }
    }
    let n = gt_m.len();
    grow(&mut v.d, n);
    grow(&mut v.z_gt, n);
    grow(&mut v.d_gt, n);
    grow(&mut v.index, n);
    // Branch-free stream compaction: write every pixel, advance only over valid ones.
    let mut k = 0usize;
    let mut n_gt_valid = 0usize;
    let mut n_bad = 0usize;
    let exclude = policy == InvalidPredPolicy::Exclude;
    {
        let (d_out, z_out, g_out, idx) = (&mut v.d[..n], &mut v.z_gt[..n], &mut v.d_gt[..n], &mut v.index[..n]);
        for i in 0..n {
            let z = gt_m[i];
            let p = pred[i];
            let gt_ok = z.is_finite() && z > 0.0;
            n_gt_valid += gt_ok as usize;
            let inside = gt_ok && (mask.is_none() || mask.is_some_and(|m| m[i]));
            let d = match kind {
                PredKind::Disparity => p,
                PredKind::Depth => {
                    if p.is_finite() && p > 0.0 {
                        1.0 / p
                    } else {
                        f64::NAN
                    }
                }
            };
            let bad = !d.is_finite();
            n_bad += (inside && bad) as usize;
            // k <= i < n: the slot exists.
            d_out[k] = if bad { 0.0 } else { d };
            z_out[k] = z;
            g_out[k] = 1.0 / z;
            idx[k] = i as u32;
            k += (inside && !(bad && exclude)) as usize;
        }
    }
    v.d.truncate(k);
    v.z_gt.truncate(k);
    v.d_gt.truncate(k);
    v.index.truncate(k);
    v.n_invalid_pred = n_bad;
    let n_in = v.d.len() + if policy == InvalidPredPolicy::Exclude { v.n_invalid_pred } else { 0 };
    v.n_masked_out = n_gt_valid - n_in;
    if n_gt_valid == 0 {
        return Err(DepthError::invalid("ground truth", "has no valid pixel (finite and > 0)"));
    }
    if n_in == 0 {
        return Err(DepthError::invalid(
            "mask",
            format!("leaves no valid ground-truth pixel (the GT has {n_gt_valid} valid pixels, none inside the mask)"),
        ));
    }
    if v.n_invalid_pred == n_in {
        return Err(DepthError::invalid(
            "prediction",
            format!(
                "has no valid value (all {n_in} values on valid ground-truth pixels are non-finite{})",
                if kind == PredKind::Depth { " or ≤ 0" } else { "" }
            ),
        ));
    }
    if policy == InvalidPredPolicy::Error && v.n_invalid_pred > 0 {
        return Err(DepthError::invalid(
            "prediction",
            format!("has {} invalid value(s) on valid ground-truth pixels (policy: error)", v.n_invalid_pred),
        ));
    }
    Ok(())
}

/// Pixels per chunk of the metric pass. Chunk boundaries are fixed, and the chunk sums are
/// added in chunk order, so the result is the same bit for bit whatever the thread count.
const CHUNK: usize = 1 << 15;

/// All metrics of disparity `d` aligned with `p` against GT depth `z_gt` (m), GT disparity
/// `d_gt = 1/z_gt` (eqs. 3.1–3.2). Fused passes over 4 interleaved lanes (vectorisable, inline
/// log) on fixed chunks of [`CHUNK`] pixels, in parallel (rayon) for large inputs; falls back to
/// [`metrics_reference`] if a depth ratio is outside the normal f64 range.
pub fn metrics(z_gt: &[f64], d_gt: &[f64], d: &[f64], p: AlignParams, range: DepthRange) -> Metrics {
    use rayon::prelude::*;
    assert!(z_gt.len() == d.len() && d_gt.len() == d.len(), "metrics: slices of different lengths");
    let thr: [f64; 5] = DELTA_POWERS.map(|t| 1.25f64.powf(t));
    let chunk_sums = |(zg, (ig, di)): (&[f64], (&[f64], &[f64]))| sums_fast(zg, ig, di, p, range, thr);
    let parts: Vec<Option<Sums>> = if d.len() >= 2 * CHUNK {
        z_gt.par_chunks(CHUNK).zip(d_gt.par_chunks(CHUNK).zip(d.par_chunks(CHUNK))).map(chunk_sums).collect()
    } else {
        z_gt.chunks(CHUNK).zip(d_gt.chunks(CHUNK).zip(d.chunks(CHUNK))).map(chunk_sums).collect()
    };
    let mut total = Sums::ZERO;
    for part in parts {
        match part {
            Some(s) => total.add(&s),
            None => return metrics_reference(z_gt, d_gt, d, p, range),
        }
    }
    total.finish(d.len(), p)
}

/// Metric sums of one chunk with the fastest code path of this CPU (`None`: a depth ratio is
/// outside the normal range, the caller must use the libm path).
fn sums_fast(z_gt: &[f64], d_gt: &[f64], d: &[f64], p: AlignParams, range: DepthRange, thr: [f64; 5]) -> Option<Sums> {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2 (checked just above); the function is otherwise safe.
            return unsafe { sums_avx2(z_gt, d_gt, d, p, range, thr) };
        }
    }
    sums_lanes(z_gt, d_gt, d, p, range, thr)
}

/// [`sums_lanes`] compiled for AVX2 (4 f64 lanes per instruction instead of 2). The same
/// IEEE operations in the same order per lane, so the result is bit-identical.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn sums_avx2(
    z_gt: &[f64],
    d_gt: &[f64],
    d: &[f64],
    p: AlignParams,
    range: DepthRange,
    thr: [f64; 5],
) -> Option<Sums> {
    sums_lanes(z_gt, d_gt, d, p, range, thr)
}

#[inline(always)]
#[allow(clippy::needless_range_loop)]
fn sums_lanes(z_gt: &[f64], d_gt: &[f64], d: &[f64], p: AlignParams, range: DepthRange, thr: [f64; 5]) -> Option<Sums> {
    const L: usize = 4;
    let mut s_abs = [0.0f64; L];
    let mut s_sqrel = [0.0f64; L];
    let mut s_sq = [0.0f64; L];
    let mut s_e = [0.0f64; L];
    let mut s_e2 = [0.0f64; L];
    let mut cnt = [[0u64; L]; 5];
    let mut normal = [true; L];
    let n = d.len();
    let body = n / L * L;
    let (zc, gc, dc) = (z_gt[..body].chunks_exact(L), d_gt[..body].chunks_exact(L), d[..body].chunks_exact(L));
    for ((zg, ig), di) in zc.zip(gc).zip(dc) {
        for j in 0..L {
            let dh = p.scale * di[j] + p.shift;
            let z = if dh > 0.0 { 1.0 / dh } else { f64::INFINITY };
            let z = z.max(range.min_m).min(range.max_m);
            let diff = zg[j] - z;
            let r = z * ig[j]; // ẑ / z*
            s_abs[j] += diff.abs() * ig[j];
            let d2 = diff * diff;
            s_sqrel[j] += d2 * ig[j];
            s_sq[j] += d2;
            normal[j] &= crate::fastmath::is_positive_normal(r);
            let e = crate::fastmath::ln_normal(r); // log ẑ − log z*
            s_e[j] += e;
            s_e2[j] += e * e;
            // max(z*/ẑ, ẑ/z*) < thr  <=>  ẑ/z* < thr and z* < thr·ẑ (no division).
            for k in 0..5 {
                cnt[k][j] += ((r < thr[k]) & (zg[j] < thr[k] * z)) as u64;
            }
        }
    }
    if !normal.iter().all(|&b| b) {
        return None;
    }
    let fold = |a: [f64; L]| (a[0] + a[1]) + (a[2] + a[3]);
    let tail = metrics_sums(&z_gt[body..], &d_gt[body..], &d[body..], p, range, thr);
    Some(Sums {
        abs: fold(s_abs) + tail.abs,
        sqrel: fold(s_sqrel) + tail.sqrel,
        sq: fold(s_sq) + tail.sq,
        e: fold(s_e) + tail.e,
        e2: fold(s_e2) + tail.e2,
        cnt: std::array::from_fn(|k| cnt[k].iter().sum::<u64>() + tail.cnt[k]),
    })
}

/// [`metrics`] for several alignments of the same prediction.
pub fn metrics_multi(z_gt: &[f64], d_gt: &[f64], d: &[f64], params: &[AlignParams], range: DepthRange) -> Vec<Metrics> {
    params.iter().map(|&p| metrics(z_gt, d_gt, d, p, range)).collect()
}

/// Sums of the metric terms.
struct Sums {
    abs: f64,
    sqrel: f64,
    sq: f64,
    e: f64,
    e2: f64,
    cnt: [u64; 5],
}

impl Sums {
    const ZERO: Sums = Sums { abs: 0.0, sqrel: 0.0, sq: 0.0, e: 0.0, e2: 0.0, cnt: [0; 5] };

    fn add(&mut self, o: &Sums) {
        self.abs += o.abs;
        self.sqrel += o.sqrel;
        self.sq += o.sq;
        self.e += o.e;
        self.e2 += o.e2;
        for (c, oc) in self.cnt.iter_mut().zip(o.cnt) {
            *c += oc;
        }
    }

    fn finish(&self, n: usize, p: AlignParams) -> Metrics {
        let n = n as f64;
        let me2 = self.e2 / n;
        let me = self.e / n;
        Metrics {
            abs_rel: self.abs / n,
            sq_rel: self.sqrel / n,
            rmse: (self.sq / n).sqrt(),
            rmse_log: me2.sqrt(),
            silog: 100.0 * (me2 - me * me).max(0.0).sqrt(),
            delta_0_25: self.cnt[0] as f64 / n,
            delta_0_5: self.cnt[1] as f64 / n,
            delta_1: self.cnt[2] as f64 / n,
            delta_2: self.cnt[3] as f64 / n,
            delta_3: self.cnt[4] as f64 / n,
            scale: p.scale,
            shift: p.shift,
        }
    }
}

#[allow(clippy::needless_range_loop)]
/// Sequential sums with the libm logarithm (tail of the fast loop, and the reference path).
fn metrics_sums(z_gt: &[f64], d_gt: &[f64], d: &[f64], p: AlignParams, range: DepthRange, thr: [f64; 5]) -> Sums {
    let mut s = Sums::ZERO;
    for ((&zg, &ig), &di) in z_gt.iter().zip(d_gt).zip(d) {
        let z = p.depth(di, range);
        let diff = zg - z;
        let r = z * ig;
        s.abs += diff.abs() * ig;
        let d2 = diff * diff;
        s.sqrel += d2 * ig;
        s.sq += d2;
        let e = r.ln();
        s.e += e;
        s.e2 += e * e;
        for k in 0..5 {
            s.cnt[k] += ((r < thr[k]) & (zg < thr[k] * z)) as u64;
        }
    }
    s
}

/// The plain sequential form of [`metrics`] (libm log), kept as its reference.
pub fn metrics_reference(z_gt: &[f64], d_gt: &[f64], d: &[f64], p: AlignParams, range: DepthRange) -> Metrics {
    let thr: [f64; 5] = DELTA_POWERS.map(|t| 1.25f64.powf(t));
    metrics_sums(z_gt, d_gt, d, p, range, thr).finish(d.len(), p)
}

/// Metrics of one prediction against one GT under several alignments (`None` = not computed).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PairMetrics {
    /// Number of pixels the metrics average over.
    pub n_valid: usize,
    /// Valid GT pixels with an invalid prediction (see [`InvalidPredPolicy`]).
    pub n_invalid_pred: usize,
    /// Metrics without alignment.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub none: Option<Metrics>,
    /// Metrics after s-alignment.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub scale: Option<Metrics>,
    /// Metrics after s&t-alignment.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub scale_shift: Option<Metrics>,
}

impl PairMetrics {
    /// The metrics of `a`, if computed.
    pub fn get(&self, a: Alignment) -> Option<&Metrics> {
        match a {
            Alignment::None => self.none.as_ref(),
            Alignment::Scale => self.scale.as_ref(),
            Alignment::ScaleShift => self.scale_shift.as_ref(),
        }
    }
}

/// Fit and evaluate the selected alignments on prepared valid pixels.
pub fn evaluate_valid(v: &ValidPixels, opts: &PairOptions) -> PairMetrics {
    let mut out = PairMetrics {
        n_valid: v.d.len(),
        n_invalid_pred: v.n_invalid_pred,
        none: None,
        scale: None,
        scale_shift: None,
    };
    // Buffers are taken out of their thread-local cells rather than borrowed: the fits and the
    // metric passes run rayon jobs, and a waiting thread may steal another image's evaluation.
    use rayon::prelude::*;
    let params: Vec<AlignParams> = opts
        .alignments
        .par_iter()
        .map(|&a| {
            let mut scratch = SCRATCH.with(|c| c.take());
            let p = fit(a, &v.d, &v.d_gt, &mut scratch);
            SCRATCH.with(|c| c.replace(scratch));
            p
        })
        .collect();
    let ms = metrics_multi(&v.z_gt, &v.d_gt, &v.d, &params, opts.range);
    for (&a, m) in opts.alignments.iter().zip(ms) {
        match a {
            Alignment::None => out.none = Some(m),
            Alignment::Scale => out.scale = Some(m),
            Alignment::ScaleShift => out.scale_shift = Some(m),
        }
    }
    out
}

/// Evaluate prediction `pred` (depth or disparity, any scale) against GT depth `gt_m`
/// (metres), optional ROI `mask`, all of the same size (row-major).
pub fn evaluate_pair(
    pred: &[f64],
    kind: PredKind,
    gt_m: &[f64],
    mask: Option<&[bool]>,
    opts: &PairOptions,
) -> Result<PairMetrics> {
    opts.range.validate()?;
    let mut w = WORKSPACE.with(|c| c.take());
    let out = select_valid_into(&mut w, pred, kind, gt_m, mask, opts.invalid_pred).map(|()| evaluate_valid(&w, opts));
    WORKSPACE.with(|c| c.replace(w));
    out
}

thread_local! {
    /// Per-thread buffers of [`evaluate_pair`]: large fresh allocations cost page faults that
    /// would dominate the evaluation time of an image.
    static WORKSPACE: std::cell::RefCell<ValidPixels> = std::cell::RefCell::new(ValidPixels::default());
    static SCRATCH: std::cell::RefCell<Vec<f64>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// Aligned, clamped predicted depth (m) per pixel (NaN outside the valid set) and the fit,
/// e.g. for error maps (thesis Fig. C.1).
pub fn aligned_depth_map(
    pred: &[f64],
    kind: PredKind,
    gt_m: &[f64],
    mask: Option<&[bool]>,
    alignment: Alignment,
    opts: &PairOptions,
) -> Result<(Vec<f64>, AlignParams)> {
    let v = select_valid(pred, kind, gt_m, mask, opts.invalid_pred)?;
    let p = fit(alignment, &v.d, &v.d_gt, &mut Vec::new());
    let mut out = vec![f64::NAN; gt_m.len()];
    for (&i, &d) in v.index.iter().zip(&v.d) {
        out[i as usize] = p.depth(d, opts.range);
    }
    Ok((out, p))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_distr::{Distribution, Normal};

    /// depth_eval_ref.py's timing input: GT depth U(0.03, 0.3) m with 10 % holes (0), predicted
    /// disparity `(1/z − 2)/5 + N(0, 0.2)`. Seeded (the same generator as `laparo-bench depth`).
    fn synthetic_pair(width: usize, height: usize, seed: u64) -> (Vec<f64>, Vec<f64>) {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let noise = Normal::new(0.0, 0.2).unwrap();
        let (mut pred, mut gt) = (Vec::new(), Vec::new());
        for _ in 0..width * height {
            let z: f64 = rng.gen_range(0.03..0.3);
            let z = if rng.gen::<f64>() < 0.1 { 0.0 } else { z };
            gt.push(z);
            pred.push((if z > 0.0 { 1.0 / z } else { 1.0 } - 2.0) / 5.0 + noise.sample(&mut rng));
        }
        (pred, gt)
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-12 * (1.0 + b.abs())
    }

    fn only(a: Alignment) -> PairOptions {
        PairOptions { alignments: vec![a], ..Default::default() }
    }

    #[test]
    fn every_metric_by_hand_without_alignment() {
        // z* = (1/8, 1/4) m, ẑ = (1/8, 5/16) m: one exact pixel, one 25 % too far.
        let gt = [0.125, 0.25];
        let pred = [0.125, 0.3125];
        let r = evaluate_pair(&pred, PredKind::Depth, &gt, None, &only(Alignment::None)).unwrap();
        let m = r.none.unwrap();
        assert_eq!(r.n_valid, 2);
        let l = 1.25f64.ln();
        assert!(close(m.abs_rel, 0.125)); // (0 + 0.0625/0.25) / 2
        assert!(close(m.sq_rel, 0.0078125)); // (0.0625² / 0.25) / 2
        assert!(close(m.rmse, 0.0625 / 2f64.sqrt()));
        assert!(close(m.rmse_log, l / 2f64.sqrt()));
        assert!(close(m.silog, 50.0 * l)); // 100 sqrt(l²/2 − l²/4)
                                           // ratio 1.25: fails 1.25^0.25, 1.25^0.5 and (strict <) 1.25^1; passes 1.25^2, 1.25^3.
        assert_eq!([m.delta_0_25, m.delta_0_5, m.delta_1, m.delta_2, m.delta_3], [0.5, 0.5, 0.5, 1.0, 1.0]);
        assert_eq!((m.scale, m.shift), (1.0, 0.0));
        assert_eq!(m.error(ErrorMetric::OneMinusDelta025), 0.5);
    }

    #[test]
    fn scale_alignment_by_hand() {
        // d = (1, 2, 3), d* = (10, 20, 25): s = 20 / 2 = 10, ẑ = (0.1, 0.05, 1/30).
        let gt = [0.1, 0.05, 0.04];
        let r = evaluate_pair(&[1.0, 2.0, 3.0], PredKind::Disparity, &gt, None, &only(Alignment::Scale)).unwrap();
        let m = r.scale.unwrap();
        assert!(close(m.scale, 10.0) && m.shift == 0.0);
        assert!(close(m.abs_rel, (1.0 / 6.0) / 3.0)); // |0.04 − 1/30| / 0.04 = 1/6
        assert!(close(m.rmse, ((0.04f64 - 1.0 / 30.0).powi(2) / 3.0).sqrt()));
        // ratio 1.2 on the third pixel: < 1.25 but > 1.25^0.5 = 1.118.
        assert!(close(m.delta_0_5, 2.0 / 3.0) && m.delta_1 == 1.0);
    }

    #[test]
    fn scale_shift_alignment_by_hand() {
        // d = (0, 1, 2), d* = (1, 2, 4) -> s = 3/2, t = 5/6 (see align.rs),
        // ẑ = (6/5 -> clamped 0.5, 3/7, 6/23), z* = (1, 0.5, 0.25).
        let gt = [1.0, 0.5, 0.25];
        let r = evaluate_pair(&[0.0, 1.0, 2.0], PredKind::Disparity, &gt, None, &only(Alignment::ScaleShift)).unwrap();
        let m = r.scale_shift.unwrap();
        assert!(close(m.scale, 1.5) && close(m.shift, 5.0 / 6.0));
        assert!(close(m.abs_rel, (0.5 + 1.0 / 7.0 + 1.0 / 23.0) / 3.0));
        let e = [(0.5f64).ln(), (6.0f64 / 7.0).ln(), (24.0f64 / 23.0).ln()];
        let me = e.iter().sum::<f64>() / 3.0;
        let me2 = e.iter().map(|x| x * x).sum::<f64>() / 3.0;
        assert!(close(m.rmse_log, me2.sqrt()));
        assert!(close(m.silog, 100.0 * (me2 - me * me).sqrt()));
    }

    #[test]
    fn invalid_predictions_are_counted_and_handled() {
        let gt = [0.1, 0.1, f64::NAN, 0.1];
        let pred = [0.1, f64::NAN, 0.3, 0.0]; // NaN and 0 depth on valid pixels; 0.3 on invalid GT
        let far = evaluate_pair(&pred, PredKind::Depth, &gt, None, &only(Alignment::None)).unwrap();
        assert_eq!((far.n_valid, far.n_invalid_pred), (3, 2));
        // Far: both invalid pixels at 0.5 m -> |0.1 − 0.5| / 0.1 = 4.
        assert!(close(far.none.unwrap().abs_rel, 8.0 / 3.0));
        let ex = PairOptions { invalid_pred: InvalidPredPolicy::Exclude, ..only(Alignment::None) };
        let r = evaluate_pair(&pred, PredKind::Depth, &gt, None, &ex).unwrap();
        assert_eq!((r.n_valid, r.n_invalid_pred), (1, 2));
        assert_eq!(r.none.unwrap().abs_rel, 0.0);
        let er = PairOptions { invalid_pred: InvalidPredPolicy::Error, ..only(Alignment::None) };
        assert!(evaluate_pair(&pred, PredKind::Depth, &gt, None, &er).is_err());
    }

    #[test]
    fn bad_inputs_are_refused() {
        let o = PairOptions::default();
        let e = evaluate_pair(&[1.0], PredKind::Disparity, &[0.1, 0.2], None, &o).unwrap_err();
        assert!(e.to_string().contains("size"), "{e}");
        let e = evaluate_pair(&[f64::NAN, f64::NAN], PredKind::Disparity, &[0.1, 0.2], None, &o).unwrap_err();
        assert!(e.to_string().contains("prediction"), "{e}");
        let e = evaluate_pair(&[1.0, 2.0], PredKind::Disparity, &[0.0, f64::NAN], None, &o).unwrap_err();
        assert!(e.to_string().contains("ground truth"), "{e}");
        let e = evaluate_pair(&[1.0, 2.0], PredKind::Disparity, &[0.1, 0.2], Some(&[false, false]), &o).unwrap_err();
        assert!(e.to_string().contains("mask"), "{e}");
        let e =
            evaluate_pair(&[1.0, 2.0], PredKind::Disparity, &[0.1, f64::NAN], Some(&[false, true]), &o).unwrap_err();
        assert!(e.to_string().contains("mask"), "{e}");
    }

    #[test]
    fn selection_equals_a_plain_filter() {
        // NaN/negative predictions, GT holes and a mask, on a full-size image.
        let (mut pred, mut gt) = synthetic_pair(700, 300, 3);
        for i in (0..pred.len()).step_by(37) {
            pred[i] = if i % 2 == 0 { f64::NAN } else { -1.0 };
        }
        gt[5] = f64::INFINITY;
        let mask: Vec<bool> = (0..gt.len()).map(|i| (i / 700) % 5 != 0).collect();
        for kind in [PredKind::Disparity, PredKind::Depth] {
            for policy in [InvalidPredPolicy::Far, InvalidPredPolicy::Exclude] {
                let v = select_valid(&pred, kind, &gt, Some(&mask), policy).unwrap();
                let (mut idx, mut bad) = (Vec::new(), 0);
                for i in 0..gt.len() {
                    let z = gt[i];
                    if !(z.is_finite() && z > 0.0 && mask[i]) {
                        continue;
                    }
                    let d = if kind == PredKind::Depth { 1.0 / pred[i] } else { pred[i] };
                    let invalid = !pred[i].is_finite() || (kind == PredKind::Depth && pred[i] <= 0.0);
                    bad += invalid as usize;
                    if !(invalid && policy == InvalidPredPolicy::Exclude) {
                        idx.push(i as u32);
                        let k = idx.len() - 1;
                        assert_eq!(v.d[k].to_bits(), if invalid { 0.0f64 } else { d }.to_bits(), "pixel {i}");
                        assert_eq!(v.z_gt[k], z);
                        assert_eq!(v.d_gt[k], 1.0 / z);
                    }
                }
                assert_eq!(v.index, idx, "{kind:?} {policy:?}");
                assert_eq!(v.n_invalid_pred, bad);
                let n_gt_valid = gt.iter().filter(|z| z.is_finite() && **z > 0.0).count();
                let n_in = idx.len() + if policy == InvalidPredPolicy::Exclude { bad } else { 0 };
                assert_eq!(v.n_masked_out, n_gt_valid - n_in);
            }
        }
    }

    #[test]
    fn chunked_parallel_metrics_are_thread_count_independent() {
        // 640×480: several chunks, so the parallel path runs; the reference loop is sequential.
        let (pred, gt) = synthetic_pair(640, 480, 11);
        let opts = PairOptions::default();
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| evaluate_pair(&pred, PredKind::Disparity, &gt, None, &opts).unwrap())
        };
        let (one, two) = (run(1), run(2));
        assert_eq!(one, two, "results depend on the thread count");
        let v = select_valid(&pred, PredKind::Disparity, &gt, None, InvalidPredPolicy::Far).unwrap();
        assert!(v.d.len() > 4 * CHUNK);
        let mut scratch = Vec::new();
        for a in [Alignment::None, Alignment::Scale, Alignment::ScaleShift] {
            let p = fit(a, &v.d, &v.d_gt, &mut scratch);
            let b = metrics_reference(&v.z_gt, &v.d_gt, &v.d, p, DepthRange::default()).values();
            let got = one.get(a).unwrap().values();
            for k in 0..12 {
                assert!((got[k] - b[k]).abs() <= 1e-12 * b[k].abs().max(1e-9), "{a:?} {k}: {} vs {}", got[k], b[k]);
            }
        }
    }

    #[test]
    fn fast_metrics_equal_the_reference_loop() {
        let (pred, gt) = synthetic_pair(37, 23, 5);
        let v = select_valid(&pred, PredKind::Disparity, &gt, None, InvalidPredPolicy::Far).unwrap();
        for p in
            [AlignParams::IDENTITY, AlignParams { scale: 3.0, shift: 1.5 }, AlignParams { scale: -2.0, shift: 9.0 }]
        {
            let a = metrics(&v.z_gt, &v.d_gt, &v.d, p, DepthRange::default()).values();
            let b = metrics_reference(&v.z_gt, &v.d_gt, &v.d, p, DepthRange::default()).values();
            for k in 0..12 {
                assert!((a[k] - b[k]).abs() <= 1e-12 * b[k].abs().max(1e-9), "{k}: {} vs {}", a[k], b[k]);
            }
        }
        // A subnormal GT depth makes the ratio overflow: the reference path is taken.
        let z = [1e-310, 0.1, 0.2, 0.3, 0.1];
        let g: Vec<f64> = z.iter().map(|v| 1.0 / v).collect();
        let d = [1.0; 5];
        let a = metrics(&z, &g, &d, AlignParams::IDENTITY, DepthRange::default());
        let b = metrics_reference(&z, &g, &d, AlignParams::IDENTITY, DepthRange::default());
        assert_eq!(a.values().map(f64::to_bits), b.values().map(f64::to_bits));
    }

    #[test]
    fn mask_restricts_valid_set() {
        let gt = [0.1, 0.2, 0.3];
        let r =
            evaluate_pair(&[0.1, 0.4, 0.3], PredKind::Depth, &gt, Some(&[true, false, true]), &only(Alignment::None))
                .unwrap();
        assert_eq!(r.n_valid, 2);
        assert_eq!(r.none.unwrap().abs_rel, 0.0);
        let (z, p) = aligned_depth_map(
            &[0.1, 0.4, 0.3],
            PredKind::Depth,
            &gt,
            Some(&[true, false, true]),
            Alignment::None,
            &Default::default(),
        )
        .unwrap();
        assert!(z[1].is_nan() && z[0] == 0.1 && p == AlignParams::IDENTITY);
    }
}
