//! Prediction-to-ground-truth alignment in disparity space (thesis §2.3.3, §3.2.7).
//!
//! Predictions are depth or disparity in any scale. They are turned into disparity `d`
//! (`d = 1/z` for a depth prediction), aligned to the ground-truth disparity `d* = 1/z*`
//! on the valid pixels, turned back into depth `ẑ = 1/d̂` and clamped to a depth range
//! (default [1 cm, 50 cm], thesis §3.2.7):
//!
//! * **none**: `d̂ = d` (metric methods);
//! * **scale** (s-alignment): `s̃ = med(d*) / med(d)`, `d̂ = s̃ d` (median of an even count is
//!   the mean of the two middle values, as numpy);
//! * **scale-and-shift** (s&t-alignment): `(s̃, t̃) = argmin Σ (s dᵢ + t − d*ᵢ)²`, closed form
//!   `s̃ = Σ(dᵢ−d̄)(d*ᵢ−d̄*) / Σ(dᵢ−d̄)²`, `t̃ = d̄* − s̃ d̄`; a constant prediction gives
//!   `s̃ = 0, t̃ = d̄*` (best constant fit).
//!
//! An aligned disparity `d̂ ≤ 0` (or NaN, e.g. from a zero median) means "too far": its
//! depth is `+∞`, clamped to the far end of the range.
use crate::error::{DepthError, Result};
use laparo_core::stats::fast_median;
use serde::{Deserialize, Serialize};

/// Depth range (metres) to which aligned predicted depth is clamped.
pub const DEPTH_MIN_M: f64 = 0.01;
/// Far end of the default clamp range (metres).
pub const DEPTH_MAX_M: f64 = 0.5;

/// One of the three alignment strategies of §2.3.3.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Alignment {
    /// No alignment (metric predictions).
    None,
    /// s-alignment: ratio of medians.
    Scale,
    /// s&t-alignment: least squares in disparity space.
    ScaleShift,
}

impl Alignment {
    /// All three, in the thesis' order (Tables 3.3, 3.4, 3.5).
    pub const ALL: [Alignment; 3] = [Alignment::None, Alignment::Scale, Alignment::ScaleShift];

    /// Key used in JSON output (`none`, `scale`, `scale_shift`, as depth_eval_ref.py).
    pub fn key(self) -> &'static str {
        match self {
            Alignment::None => "none",
            Alignment::Scale => "scale",
            Alignment::ScaleShift => "scale_shift",
        }
    }

    /// Short name used on the command line (`none`, `s`, `st`).
    pub fn short(self) -> &'static str {
        match self {
            Alignment::None => "none",
            Alignment::Scale => "s",
            Alignment::ScaleShift => "st",
        }
    }

    /// Title as in the thesis tables.
    pub fn title(self) -> &'static str {
        match self {
            Alignment::None => "no-alignment",
            Alignment::Scale => "s-alignment",
            Alignment::ScaleShift => "s&t-alignment",
        }
    }

    /// Index in [`Alignment::ALL`].
    pub fn index(self) -> usize {
        self as usize
    }

    /// Parse `none|s|st|all` (also `scale`, `scale_shift`, `s&t`) into a list of alignments.
    pub fn parse_list(s: &str) -> Result<Vec<Alignment>> {
        let mut out = Vec::new();
        for part in s.split(',').map(str::trim).filter(|p| !p.is_empty()) {
            if part.eq_ignore_ascii_case("all") {
                out.extend(Alignment::ALL);
            } else {
                out.push(part.parse()?);
            }
        }
        if out.is_empty() {
            return Err(DepthError::invalid("alignment", format!("'{s}' (expected none, s, st or all)")));
        }
        out.sort();
        out.dedup();
        Ok(out)
    }
}

impl std::str::FromStr for Alignment {
    type Err = DepthError;
    fn from_str(s: &str) -> Result<Self> {
        match s.to_ascii_lowercase().as_str() {
            "none" | "no" => Ok(Alignment::None),
            "s" | "scale" => Ok(Alignment::Scale),
            "st" | "s&t" | "scale_shift" | "scale-shift" | "ss" => Ok(Alignment::ScaleShift),
            _ => Err(DepthError::invalid("alignment", format!("'{s}' (expected none, s, st or all)"))),
        }
    }
}

impl std::fmt::Display for Alignment {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.key())
    }
}

/// What a prediction file holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PredKind {
    /// Depth in any (possibly unknown) scale; turned into disparity `1/z` before alignment.
    Depth,
    /// Disparity / inverse depth in any scale (and shift).
    Disparity,
}

impl std::str::FromStr for PredKind {
    type Err = DepthError;
    fn from_str(s: &str) -> Result<Self> {
        match s.to_ascii_lowercase().as_str() {
            "depth" => Ok(PredKind::Depth),
            "disparity" | "disp" | "inverse_depth" | "inverse-depth" => Ok(PredKind::Disparity),
            _ => Err(DepthError::invalid("prediction kind", format!("'{s}' (expected depth or disparity)"))),
        }
    }
}

impl std::fmt::Display for PredKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            PredKind::Depth => "depth",
            PredKind::Disparity => "disparity",
        })
    }
}

/// Clamp range of aligned predicted depth, in metres.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct DepthRange {
    /// Near clamp (m).
    pub min_m: f64,
    /// Far clamp (m).
    pub max_m: f64,
}

impl Default for DepthRange {
    fn default() -> Self {
        DepthRange { min_m: DEPTH_MIN_M, max_m: DEPTH_MAX_M }
    }
}

impl DepthRange {
    /// A checked range: finite, `0 < min_m < max_m`.
    pub fn new(min_m: f64, max_m: f64) -> Result<Self> {
        let r = DepthRange { min_m, max_m };
        r.validate()?;
        Ok(r)
    }

    /// Check `0 < min_m < max_m`, both finite.
    pub fn validate(&self) -> Result<()> {
        if !(self.min_m.is_finite() && self.max_m.is_finite() && self.min_m > 0.0 && self.min_m < self.max_m) {
            return Err(DepthError::invalid(
                "depth range",
                format!("[{}, {}] m (need 0 < min < max, finite)", self.min_m, self.max_m),
            ));
        }
        Ok(())
    }
}

/// Scale and shift applied in disparity space: `d̂ = scale · d + shift`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct AlignParams {
    /// Scale s of the aligned disparity s d + t.
    pub scale: f64,
    /// Shift t of the aligned disparity s d + t.
    pub shift: f64,
}

impl AlignParams {
    /// The identity (no alignment).
    pub const IDENTITY: AlignParams = AlignParams { scale: 1.0, shift: 0.0 };

    /// Aligned, clamped depth (metres) of predicted disparity `d`: `ẑ = clamp(1/(s d + t))`,
    /// `+∞` (so the far limit) where `s d + t ≤ 0` or is NaN.
    #[inline(always)]
    pub fn depth(&self, d: f64, range: DepthRange) -> f64 {
        let dh = self.scale * d + self.shift;
        let z = if dh > 0.0 { 1.0 / dh } else { f64::INFINITY };
        z.clamp(range.min_m, range.max_m)
    }
}

thread_local! {
    static GT_SCRATCH: std::cell::Cell<Vec<f64>> = const { std::cell::Cell::new(Vec::new()) };
}

/// s-alignment: `s̃ = med(d*) / med(d)` (NaN when `med(d) = 0`, as the reference).
/// `scratch` is reused to avoid allocation.
pub fn fit_scale(d: &[f64], d_gt: &[f64], scratch: &mut Vec<f64>) -> AlignParams {
    // The two medians are independent: one per core for large inputs.
    let (md, mg) = if d.len() >= 1 << 16 {
        rayon::join(
            || fast_median(d, scratch),
            || {
                let mut own = GT_SCRATCH.with(|c| c.take());
                let m = fast_median(d_gt, &mut own);
                GT_SCRATCH.with(|c| c.replace(own));
                m
            },
        )
    } else {
        (fast_median(d, scratch), fast_median(d_gt, scratch))
    };
    let scale = if md != 0.0 { mg / md } else { f64::NAN };
    AlignParams { scale, shift: 0.0 }
}

/// s&t-alignment: least-squares `(s̃, t̃) = argmin Σ (s dᵢ + t − d*ᵢ)²` in closed form
/// (centred normal equations); a constant `d` gives `s̃ = 0`, `t̃ = mean(d*)`.
pub fn fit_scale_shift(d: &[f64], d_gt: &[f64]) -> AlignParams {
    let n = d.len();
    if n == 0 {
        return AlignParams { scale: f64::NAN, shift: f64::NAN };
    }
    let nf = n as f64;
    let (sd, sg) = d.iter().zip(d_gt).fold((0.0, 0.0), |(a, b), (&x, &y)| (a + x, b + y));
    let (md, mg) = (sd / nf, sg / nf);
    let mut sxx = 0.0;
    let mut sxy = 0.0;
    let mut sq = 0.0;
    for (&x, &y) in d.iter().zip(d_gt) {
        let dx = x - md;
        sxx += dx * dx;
        sxy += dx * (y - mg);
        sq += x * x;
    }
    // Relative variance below 1e-20 is rounding noise of a constant prediction.
    if sxx <= 1e-20 * sq || sxx == 0.0 {
        return AlignParams { scale: 0.0, shift: mg };
    }
    let scale = sxy / sxx;
    AlignParams { scale, shift: mg - scale * md }
}

/// Fit `alignment` on predicted disparity `d` against ground-truth disparity `d_gt`.
pub fn fit(alignment: Alignment, d: &[f64], d_gt: &[f64], scratch: &mut Vec<f64>) -> AlignParams {
    match alignment {
        Alignment::None => AlignParams::IDENTITY,
        Alignment::Scale => fit_scale(d, d_gt, scratch),
        Alignment::ScaleShift => fit_scale_shift(d, d_gt),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scale_is_ratio_of_medians() {
        // med(d) = 2, med(d*) = 10 -> s = 5.
        let d = [1.0, 2.0, 3.0];
        let g = [10.0, 30.0, 5.0];
        let p = fit_scale(&d, &g, &mut Vec::new());
        assert_eq!(p, AlignParams { scale: 5.0, shift: 0.0 });
        // zero median -> NaN scale, depth goes to the far limit.
        let p = fit_scale(&[0.0, 0.0, 1.0], &g, &mut Vec::new());
        assert!(p.scale.is_nan());
        assert_eq!(p.depth(1.0, DepthRange::default()), DEPTH_MAX_M);
    }

    #[test]
    fn scale_shift_closed_form_by_hand() {
        // d = (0, 1, 2), d* = (1, 2, 4): d̄ = 1, d̄* = 7/3, Sxx = 2,
        // Sxy = (-1)(1 - 7/3) + 0 + (1)(4 - 7/3) = 4/3 + 5/3 = 3 -> s = 3/2, t = 7/3 - 3/2 = 5/6.
        let p = fit_scale_shift(&[0.0, 1.0, 2.0], &[1.0, 2.0, 4.0]);
        assert!((p.scale - 1.5).abs() < 1e-15);
        assert!((p.shift - 5.0 / 6.0).abs() < 1e-15);
        // Exact affine data is recovered.
        let d = [0.3, -1.0, 2.5, 7.0];
        let g: Vec<f64> = d.iter().map(|x| 0.25 * x + 3.0).collect();
        let p = fit_scale_shift(&d, &g);
        assert!((p.scale - 0.25).abs() < 1e-14 && (p.shift - 3.0).abs() < 1e-14);
        // Constant prediction: best constant fit.
        let p = fit_scale_shift(&[2.0, 2.0, 2.0], &[1.0, 2.0, 6.0]);
        assert_eq!(p, AlignParams { scale: 0.0, shift: 3.0 });
    }

    #[test]
    fn depth_from_aligned_disparity_is_clamped() {
        let r = DepthRange::default();
        let p = AlignParams { scale: 2.0, shift: -1.0 };
        assert!((p.depth(5.0, r) - 1.0 / 9.0).abs() < 1e-15); // 1/(10 - 1)
        assert_eq!(p.depth(0.5, r), DEPTH_MAX_M); // d̂ = 0 -> +inf -> 0.5
        assert_eq!(p.depth(0.1, r), DEPTH_MAX_M); // d̂ < 0 -> too far
        assert_eq!(p.depth(1000.0, r), DEPTH_MIN_M); // 1/1999 < 1 cm
        assert_eq!(p.depth(1.2, r), DEPTH_MAX_M); // 1/1.4 > 0.5 m -> 0.5 m
    }

    #[test]
    fn parse_alignments() {
        assert_eq!(Alignment::parse_list("all").unwrap(), Alignment::ALL.to_vec());
        assert_eq!(Alignment::parse_list("st,s").unwrap(), vec![Alignment::Scale, Alignment::ScaleShift]);
        assert!(Alignment::parse_list("x").is_err());
        assert!(DepthRange::new(0.5, 0.01).is_err());
    }
}
