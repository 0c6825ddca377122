//! Semi-global matching (Hirschmüller, CVPR 2005 / PAMI 2008) for raw and rectified stereo
//! laparoscope pairs (thesis §3.3: signed disparities `d = x_L − x_R`, small vertical offsets).
//!
//! Stages, one per file: [`cost`] (9×7 census, Hamming, vertical tolerance), [`aggregate`]
//! (4 or 8 paths, eq. 13–14), [`select`] (winner-takes-all, uniqueness, parabola sub-pixel),
//! [`lr_check`], [`speckle`], [`fill`]; [`masked`] for warped pairs with canvas outside the images. Any integer range `[d_min, d_max)` of either sign; cells
//! whose right pixel is outside the image get a neutral cost, so there are no invalid border
//! strips. Invalid pixels are +∞. The AVX2 kernels (run-time detected) and the portable
//! kernels give identical bits, and the work split never depends on the thread count, so the
//! output is the same for any number of threads.
use crate::error::StereoError;
use laparo_core::image::Image;
use rayon::prelude::*;
use select::Selection;
use serde::{Deserialize, Serialize};

mod aggregate;
mod cost;
mod fill;
mod lr_check;
mod masked;
mod select;
mod speckle;
mod workspace;

pub use fill::fill_background;
pub use masked::{extend_rows, match_masked, match_masked_with};
pub use workspace::SgmWorkspace;

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
    /// Fill invalid pixels with the row background (see [`fill_background`]).
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
        c => {
            // Rows in parallel (a 1280×1024 RGBA pair is 10 MB to read).
            let mut out = vec![0u8; img.data.len() / c];
            let row = img.width.max(1);
            out.par_chunks_mut(row).zip(img.data.par_chunks(row * c)).for_each(|(o, px)| match c {
                3 => luma_row::<3>(px, o),
                4 => luma_row::<4>(px, o),
                _ => {
                    for (o, p) in o.iter_mut().zip(px.chunks_exact(c)) {
                        *o = luma(p);
                    }
                }
            });
            out
        }
    }
}

/// BT.601 integer luminance of one pixel (R, G, B first).
#[inline(always)]
fn luma(p: &[u8]) -> u8 {
    ((77 * p[0] as u32 + 150 * p[1] as u32 + 29 * p[2] as u32 + 128) >> 8) as u8
}

/// [`luma`] of a row of `C`-channel pixels (a constant stride, so that it vectorises).
#[inline(always)]
fn luma_row<const C: usize>(px: &[u8], out: &mut [u8]) {
    let (px, _) = px.as_chunks::<C>();
    for (o, p) in out.iter_mut().zip(px) {
        *o = ((77 * p[0] as u32 + 150 * p[1] as u32 + 29 * p[2] as u32 + 128) >> 8) as u8;
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
/// module documentation. Errors name the parameter (empty range, size mismatch, ...). Uses a
/// fresh [`SgmWorkspace`]; to match pair after pair, keep one and call [`match_pair_with`].
pub fn match_pair(left: &Image<u8>, right: &Image<u8>, p: &SgmParams) -> Result<SgmOutput, StereoError> {
    match_pair_with(&mut SgmWorkspace::new(), left, right, p)
}

/// [`match_pair`] with the caller's buffers (reused from one pair to the next; the output is the
/// same as with a fresh workspace).
pub fn match_pair_with(
    ws: &mut SgmWorkspace,
    left: &Image<u8>,
    right: &Image<u8>,
    p: &SgmParams,
) -> Result<SgmOutput, StereoError> {
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
    let (gl, gr) = rayon::join(|| to_gray_u8(left), || to_gray_u8(right));
    match_gray_with(ws, &gl, &gr, w, h, p)
}

/// [`match_pair_with`] on grey images given as row-major `w × h` bytes.
pub fn match_gray_with(
    ws: &mut SgmWorkspace,
    gl: &[u8],
    gr: &[u8],
    w: usize,
    h: usize,
    p: &SgmParams,
) -> Result<SgmOutput, StereoError> {
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
    let [census_l, census_r] = &mut ws.census;
    let (mut cl, mut cr) = (workspace::take(census_l, w * h), workspace::take(census_r, w * h));
    rayon::join(|| cost::census_into(gl, w, h, avx2, &mut cl), || cost::census_into(gr, w, h, avx2, &mut cr));
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
        narrow: aggregate::narrow_partial_sums(p.paths == Paths::Eight, p.p2),
    };
    let counts: Vec<(usize, usize)>;
    // Per row, as the second sweep finishes it: sub-pixel disparity, uniqueness, confidence,
    // left–right check. Zeroed allocations (fresh pages, no serial fill); every element is
    // written.
    let mut disp = vec![0f32; w * h];
    let mut conf = vec![0f32; w * h];
    {
        type RowOut<'a> = std::sync::Mutex<(&'a mut [f32], &'a mut [f32], usize, usize)>;
        let rows: Vec<RowOut> =
            disp.chunks_mut(w).zip(conf.chunks_mut(w)).map(|(d, c)| std::sync::Mutex::new((d, c, 0, 0))).collect();
        let finish = |y: usize, srow: &[Selection]| {
            let mut g = rows[y].lock().unwrap_or_else(|e| e.into_inner());
            let (drow, crow, n_nu, n_lr) = &mut *g;
            for x in 0..w {
                let s = &srow[x];
                if s.unique(p.uniqueness_pct) {
                    drow[x] = (p.d_min + s.best as i32) as f32 + s.subpixel_offset();
                    crow[x] = s.confidence();
                } else {
                    drow[x] = f32::INFINITY;
                    *n_nu += 1;
                }
            }
            if let Some(md) = p.lr_max_diff {
                let best: Vec<i32> = srow.iter().map(|s| p.d_min + s.best as i32).collect();
                let smin: Vec<u16> = srow.iter().map(|s| s.smin).collect();
                *n_lr = lr_check::lr_check_row(&best, &smin, drow, md);
            }
        };
        aggregate::aggregate_select(&inp, p.paths == Paths::Eight, &finish, &mut ws.volumes);
        counts =
            rows.into_iter().map(|r| r.into_inner().unwrap_or_else(|e| e.into_inner())).map(|r| (r.2, r.3)).collect();
    }
    let n_not_unique = counts.iter().map(|c| c.0).sum();
    let n_lr_rejected = counts.iter().map(|c| c.1).sum();
    let n_speckle_removed = speckle::filter_speckles(&mut disp, w, h, p.speckle_window, p.speckle_range);
    let n_filled = if p.fill_holes { fill::fill_background(&mut disp, w, h) } else { 0 };
    let n_valid: usize = conf
        .par_chunks_mut(w)
        .zip(disp.par_chunks(w))
        .map(|(cr, dr)| {
            let mut n = 0;
            for (c, d) in cr.iter_mut().zip(dr) {
                if d.is_finite() {
                    n += 1;
                } else {
                    *c = 0.0;
                }
            }
            n
        })
        .sum();
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
    workspace::put_back(&mut ws.census[0], cl);
    workspace::put_back(&mut ws.census[1], cr);
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
