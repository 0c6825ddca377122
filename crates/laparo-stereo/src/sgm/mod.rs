//! Semi-global matching (Hirschmüller, CVPR 2005 / PAMI 2008) for raw and rectified stereo
//! laparoscope pairs (thesis §3.3: signed disparities `d = x_L − x_R`, small vertical offsets).
//!
//! Stages, one per file: [`cost`] (9×7 census, Hamming, vertical tolerance), [`aggregate`]
//! (4 or 8 paths, eq. 13–14), [`select`] (winner-takes-all, uniqueness, parabola sub-pixel),
//! [`lr_check`], [`speckle`], [`fill`]. Any integer range `[d_min, d_max)` of either sign; cells
//! whose right pixel is outside the image get a neutral cost, so there are no invalid border
//! strips. Invalid pixels are +∞. The AVX2 kernels (run-time detected) and the portable
//! kernels give identical bits, and the work split never depends on the thread count, so the
//! output is the same for any number of threads.
use crate::error::StereoError;
use laparo_core::image::Image;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

pub mod aggregate;
pub mod cost;
pub mod fill;
pub mod lr_check;
pub mod select;
pub mod speckle;

/// Largest accepted number of disparities.
pub const MAX_DISPARITIES: usize = 1024;
/// Largest accepted vertical tolerance (rows).
pub const MAX_VERTICAL_TOL: usize = 8;

/// Number of aggregation paths.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Paths {
    /// Horizontal and vertical (one pass each way).
    Four,
    /// Plus the four diagonals.
    Eight,
}

/// Which kernels to run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Kernel {
    /// AVX2 when the CPU has it, else portable.
    Auto,
    /// Portable kernels only (same bits as AVX2).
    Scalar,
}

/// Parameters of [`match_pair`]. Costs are in census bits (0..=62).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SgmParams {
    /// First disparity searched (px), any sign.
    pub d_min: i32,
    /// One past the last disparity searched (px).
    pub d_max: i32,
    /// 4 or 8 paths.
    pub paths: Paths,
    /// Penalty P1 of eq. 13 (small disparity steps).
    pub p1: u16,
    /// Penalty P2 of eq. 13 (large steps) before the intensity adaptation.
    pub p2: u16,
    /// P2 adaptation γ (grey levels): `P2 · γ / (γ + |ΔI|)`, at least P1; 0 = constant.
    pub p2_gamma: u16,
    /// Uniqueness margin (percent, as OpenCV's uniquenessRatio); 0 = off.
    pub uniqueness_pct: u8,
    /// Left–right check tolerance (px); `None` = no check.
    pub lr_max_diff: Option<i32>,
    /// Speckle filter: regions smaller than this (pixels) are removed; 0 = off.
    pub speckle_window: usize,
    /// Speckle filter: largest disparity step (px) inside a region.
    pub speckle_range: f32,
    /// Fill invalid pixels with the row background (see [`fill`]).
    pub fill_holes: bool,
    /// Vertical tolerance k (rows): the cost is the minimum over `y + δ`, `|δ| ≤ k`.
    pub vertical_tol: usize,
    /// Kernel choice (tests compare both).
    pub kernel: Kernel,
}

impl SgmParams {
    /// The default mode: 4 paths, adaptive P2, uniqueness 10 %, LR check 1 px, speckle 100 / 2 px
    /// (OpenCV's suggested post-processing), no hole filling.
    pub fn new(d_min: i32, d_max: i32) -> Self {
        SgmParams {
            d_min,
            d_max,
            paths: Paths::Four,
            p1: 5,
            p2: 60,
            p2_gamma: 16,
            uniqueness_pct: 10,
            lr_max_diff: Some(1),
            speckle_window: 100,
            speckle_range: 2.0,
            fill_holes: false,
            vertical_tol: 0,
            kernel: Kernel::Auto,
        }
    }

    /// The accurate mode: 8 paths, P1 = 7, P2 = 100, otherwise as [`new`](Self::new).
    pub fn accurate(d_min: i32, d_max: i32) -> Self {
        SgmParams { paths: Paths::Eight, p1: 7, p2: 100, ..Self::new(d_min, d_max) }
    }

    /// Number of disparities `d_max − d_min`.
    pub fn n_disparities(&self) -> usize {
        (self.d_max as i64 - self.d_min as i64).max(0) as usize
    }

    fn validate(&self) -> Result<(), StereoError> {
        let bad = |what: &str, msg: String| Err(StereoError::Invalid { what: what.into(), msg });
        if self.d_max <= self.d_min {
            return bad("disparity range", format!("[{}, {}) is empty (need d_max > d_min)", self.d_min, self.d_max));
        }
        if self.n_disparities() > MAX_DISPARITIES {
            return bad("disparity range", format!("{} disparities, at most {MAX_DISPARITIES}", self.n_disparities()));
        }
        if self.p1 == 0 || self.p2 < self.p1 {
            return bad("P1/P2", format!("need 0 < P1 ≤ P2, got P1 = {}, P2 = {}", self.p1, self.p2));
        }
        if self.p2 > 1000 {
            return bad("P2", format!("{} is too large (≤ 1000)", self.p2));
        }
        if self.uniqueness_pct >= 100 {
            return bad("uniqueness", format!("{} % (must be < 100)", self.uniqueness_pct));
        }
        if self.vertical_tol > MAX_VERTICAL_TOL {
            return bad(
                "vertical tolerance",
                format!("{} rows, at most {MAX_VERTICAL_TOL} (rectify larger offsets)", self.vertical_tol),
            );
        }
        if self.speckle_range.is_nan() || self.speckle_range < 0.0 {
            return bad("speckle range", format!("{}", self.speckle_range));
        }
        Ok(())
    }
}

/// Counts of one run.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SgmStats {
    /// Image size (px).
    pub width: usize,
    /// Image height (px).
    pub height: usize,
    /// Valid pixels at the end.
    pub n_valid: usize,
    /// Rejected by the uniqueness test.
    pub n_not_unique: usize,
    /// Rejected by the left–right check.
    pub n_lr_rejected: usize,
    /// Removed by the speckle filter.
    pub n_speckle_removed: usize,
    /// Filled by hole filling.
    pub n_filled: usize,
    /// Whether the AVX2 kernels ran.
    pub avx2: bool,
}

/// Output of [`match_pair`].
#[derive(Clone, Debug, PartialEq)]
pub struct SgmOutput {
    /// Left disparity `d = x_L − x_R` (px), +∞ where invalid.
    pub disparity: Image<f32>,
    /// Confidence in [0, 1] (`(S₂ − S₁) / S₂`, second best not adjacent), 0 where invalid.
    pub confidence: Image<f32>,
    /// Vertical offset δ (px) of the chosen match (`vertical_tol > 0`), NaN where invalid.
    pub dy: Option<Image<f32>>,
    /// Counts.
    pub stats: SgmStats,
}

/// Integer luminance (BT.601, `(77 R + 150 G + 29 B + 128) >> 8`) of an 8-bit grey, RGB or RGBA
/// image.
pub fn to_gray_u8(img: &Image<u8>) -> Vec<u8> {
    match img.channels {
        1 => img.data.clone(),
        2 => img.data.chunks_exact(2).map(|p| p[0]).collect(),
        c => img
            .data
            .chunks_exact(c)
            .map(|p| ((77 * p[0] as u32 + 150 * p[1] as u32 + 29 * p[2] as u32 + 128) >> 8) as u8)
            .collect(),
    }
}

/// Whether the AVX2 kernels can run here.
pub fn avx2_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
            && std::arch::is_x86_feature_detected!("popcnt")
            && std::arch::is_x86_feature_detected!("bmi1")
    }
    #[cfg(not(target_arch = "x86_64"))]
    false
}

/// Match a stereo pair (8-bit grey/RGB/RGBA, same size): SGM with the stages listed in the
/// module documentation. Errors name the parameter (empty range, size mismatch, ...).
pub fn match_pair(left: &Image<u8>, right: &Image<u8>, p: &SgmParams) -> Result<SgmOutput, StereoError> {
    p.validate()?;
    if left.size() != right.size() {
        return Err(StereoError::SizeMismatch(format!(
            "left image is {}x{}, right image is {}x{}",
            left.width, left.height, right.width, right.height
        )));
    }
    let (w, h) = left.size();
    if w == 0 || h == 0 {
        return Err(StereoError::Invalid { what: "image".into(), msg: format!("empty image ({w}x{h})") });
    }
    let gl = to_gray_u8(left);
    let gr = to_gray_u8(right);
    match_gray(&gl, &gr, w, h, p)
}

/// [`match_pair`] on grey images given as row-major `w × h` bytes.
pub fn match_gray(gl: &[u8], gr: &[u8], w: usize, h: usize, p: &SgmParams) -> Result<SgmOutput, StereoError> {
    p.validate()?;
    if gl.len() != w * h || gr.len() != w * h {
        return Err(StereoError::SizeMismatch(format!(
            "grey buffers of {} and {} bytes for {w}x{h}",
            gl.len(),
            gr.len()
        )));
    }
    let avx2 = p.kernel == Kernel::Auto && avx2_available();
    let nd = p.n_disparities();
    let ndp = nd.div_ceil(16) * 16;
    let cl = cost::census(gl, w, h, avx2);
    let cr = cost::census(gr, w, h, avx2);
    let g = cost::CostGeom { w, d_min: p.d_min, nd, ndp };
    let inp = aggregate::Inputs {
        census_l: &cl,
        census_r: &cr,
        gray_l: gl,
        h,
        g,
        vtol: p.vertical_tol,
        pen: aggregate::Penalties { p1: p.p1, p2: p.p2, gamma: p.p2_gamma },
        avx2,
    };
    let sel = aggregate::aggregate_select(&inp, p.paths == Paths::Eight);

    // Per row: sub-pixel disparity, uniqueness, confidence, left–right check.
    let mut disp = vec![f32::INFINITY; w * h];
    let mut conf = vec![0f32; w * h];
    let counts: Vec<(usize, usize)> = disp
        .par_chunks_mut(w)
        .zip(conf.par_chunks_mut(w))
        .enumerate()
        .map(|(y, (drow, crow))| {
            let srow = &sel[y * w..(y + 1) * w];
            let mut n_nu = 0;
            for x in 0..w {
                let s = &srow[x];
                if s.unique(p.uniqueness_pct) {
                    drow[x] = (p.d_min + s.best as i32) as f32 + s.subpixel_offset();
                    crow[x] = s.confidence();
                } else {
                    n_nu += 1;
                }
            }
            let n_lr = match p.lr_max_diff {
                Some(md) => {
                    let best: Vec<i32> = srow.iter().map(|s| p.d_min + s.best as i32).collect();
                    let smin: Vec<u16> = srow.iter().map(|s| s.smin).collect();
                    lr_check::lr_check_row(&best, &smin, drow, md)
                }
                None => 0,
            };
            (n_nu, n_lr)
        })
        .collect();
    let n_not_unique = counts.iter().map(|c| c.0).sum();
    let n_lr_rejected = counts.iter().map(|c| c.1).sum();
    let n_speckle_removed = speckle::filter_speckles(&mut disp, w, h, p.speckle_window, p.speckle_range);
    let n_filled = if p.fill_holes { fill::fill_background(&mut disp, w, h) } else { 0 };
    for (c, d) in conf.iter_mut().zip(&disp) {
        if !d.is_finite() {
            *c = 0.0;
        }
    }
    let dy = (p.vertical_tol > 0).then(|| {
        let mut dy = vec![f32::NAN; w * h];
        dy.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
            for x in 0..w {
                let d = disp[y * w + x];
                if d.is_finite() {
                    let di = d.round() as i32;
                    if let Some(v) = cost::best_dy(&cl, &cr, w, h, x, y, di, p.vertical_tol) {
                        row[x] = v as f32;
                    }
                }
            }
        });
        Image { width: w, height: h, channels: 1, data: dy }
    });
    let n_valid = disp.iter().filter(|d| d.is_finite()).count();
    Ok(SgmOutput {
        disparity: Image { width: w, height: h, channels: 1, data: disp },
        confidence: Image { width: w, height: h, channels: 1, data: conf },
        dy,
        stats: SgmStats {
            width: w,
            height: h,
            n_valid,
            n_not_unique,
            n_lr_rejected,
            n_speckle_removed,
            n_filled,
            avx2,
        },
    })
}
