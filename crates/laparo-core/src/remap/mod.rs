//! The one image sampler of laparo: inverse mapping (each output pixel pulls its value from a
//! source position) by a coordinate map, a homography or per-row coordinates computed by the
//! caller; bilinear or nearest; 1, 3, 4 (or any number of) channels; `u8`, `u16`, `f32`, `f64`.
//! Every warp of the workspace (CATS augmentation, rectification, the CPC texture warp, point
//! queries via [`Image::sample_bilinear`]), every resize ([`resize`]: depth predictions, SIFT's
//! upsampled octave) and every edge-aware depth/disparity lookup ([`sample_smooth`]: the CATS exact
//! rule, ground-truth transfer, raw-frame disparities) goes through it.
//!
//! # Arithmetic contract
//! - Pixel centres are at integer coordinates; source coordinates are `f32` (as OpenCV's
//!   `CV_32FC2` maps), point queries `f64`.
//! - **Bilinear**: valid when `0 <= x <= w − 1` and `0 <= y <= h − 1` (NaN is outside).
//!   x0 = min(⌊x⌋, w − 2), y0 likewise, ax = x − x0, ay = y − y0, and
//!   `v = lerp(lerp(p00, p10, ax), lerp(p01, p11, ax), ay)` with `lerp(a, b, t) = a + t (b − a)`,
//!   evaluated in `f32` for `u8`/`u16`/`f32` texels and in `f64` for `f64` texels and point
//!   queries, without FMA contraction. For float texels a weight of exactly 0 or 1 takes the
//!   neighbour as is (so integer positions reproduce the source bit for bit even next to NaN or
//!   inf). Integer texels are rounded half up: `(v + 0.5)` truncated, saturating.
//! - **Bicubic** (Keys' cubic convolution, a = −½): same valid domain as bilinear;
//!   x1 = ⌊x⌋ (x1 = w − 1 at the right edge), t = x − x1, weights
//!   `w(−1) = ((−½t + 1)t − ½)t`, `w(0) = (1½t − 2½)t² + 1`, `w(1) = ((−1½t + 2)t + ½)t`,
//!   `w(2) = (½t − ½)t²` of the source columns x1 − 1 … x1 + 2 clamped to [0, w − 1] (edge
//!   replicated), likewise in y; weights in `f64` rounded to the interpolation type, then
//!   `v = Σ_j wy_j Σ_i wx_i p_ij` (x first), zero weights skipped (integer positions reproduce the
//!   source bit for bit). Integer texels are rounded half up and saturate at 0 and the maximum
//!   (the kernel overshoots at edges); exact for polynomials of degree ≤ 2 away from the borders.
//! - **Nearest**: the source pixel (⌊x + ½⌋, ⌊y + ½⌋) (round half up); valid when
//!   `−½ <= x < w − ½` and `−½ <= y < h − ½`.
//! - Float texels: an output whose value is not finite is invalid.
//! - Invalid output pixels hold `fill` in every channel and `false` in the returned mask.
//! - **OpenCV `INTER_LINEAR_EXACT`** ([`resize_exact_u8`] only, grey `u8`): 8-bit fixed-point
//!   weights, one rounding; within one grey level of the float contract, bit-equal to OpenCV
//!   (ORB's pyramid).
//! - Homography rows: x_s = (a0 x + c0) / (a2 x + c2) in `f32` with the coefficients of H⁻¹ for
//!   that row rounded to `f32`; NaN (invalid) where the denominator is <= 1e-12.
//!
//! # Speed
//! Rows run in parallel (rayon); results do not depend on the thread count. On x86-64, RGB(A)
//! `u8` bilinear pixels use SSE2 (baseline), and homography warps of RGB `u8` (bilinear), grey
//! `u8` (bicubic) and 1-channel `f32` (nearest) use fused AVX2 row kernels chosen at run time. Every SIMD path is
//! bitwise equal to the scalar path (tests compare them); nothing needs AVX-512.
//!
//! ```
//! use laparo_core::remap::{warp_homography, Interp};
//! use laparo_core::Image;
//! let img = Image::from_vec(4, 1, 1, vec![0u8, 10, 20, 30]).unwrap();
//! // H⁻¹ = shift by +0.5 px: output x samples source x + 0.5.
//! let h_inv = [[1.0, 0.0, 0.5], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
//! let (out, valid) = warp_homography(&img, &h_inv, 4, 1, Interp::Bilinear, 0).unwrap();
//! assert_eq!(out.data, vec![5, 15, 25, 0]); // 5 = 0 + 0.5·10, rounded half up
//! assert_eq!(valid.data, vec![true, true, true, false]);
//! ```
mod kernel;
mod resize;

#[cfg(target_arch = "x86_64")]
mod avx2;

/// Lane-wise forms of the kernel for fused SIMD row kernels outside this module (the CATS exact
/// rule samples disparities with it), bitwise equal to [`bilerp`] lane by lane (x86-64, AVX).
#[cfg(target_arch = "x86_64")]
pub mod simd {
    pub use super::avx2::bilerp_pd;
}

#[cfg(test)]
mod tests;

pub use kernel::{bilerp, homography_row, lerp, Real};
pub use resize::{resize, resize_exact_u8, resize_position, sample_smooth};

use crate::camera::{Distortion, Intrinsics};
use crate::error::{CoreError, Result};
use crate::image::{Image, Mask};
use rayon::prelude::*;
use std::mem::MaybeUninit;

/// Interpolation of [`remap`], [`warp_homography`] and [`remap_rows`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Interp {
    /// Nearest neighbour, round half up (disparities, labels, masks).
    Nearest,
    /// Bilinear (images).
    Bilinear,
    /// Bicubic convolution (Keys, a = −½; 4×4 neighbours, edge pixels replicated): keeps the
    /// fine texture that bilinear averaging blurs at sub-pixel offsets (keypoint detectors on
    /// resampled images, the CPC warp, the self-rectified matcher). Grey `u8` homography warps
    /// have a fused AVX2 path.
    Bicubic,
}

mod private {
    pub trait Sealed {}
    impl Sealed for u8 {}
    impl Sealed for u16 {}
    impl Sealed for f32 {}
    impl Sealed for f64 {}
}

/// A value type the sampler reads and writes: `u8`, `u16`, `f32`, `f64`.
pub trait Texel: Copy + Send + Sync + PartialEq + std::fmt::Debug + 'static + private::Sealed {
    /// Interpolation arithmetic (`f32`, or `f64` for `f64` texels).
    type Acc: Real;
    /// Float texels: exact-ends lerp, non-finite outputs invalid.
    const FLOAT: bool;
    /// To the interpolation arithmetic.
    fn to_acc(self) -> Self::Acc;
    /// From the interpolation arithmetic (integers: `(v + 0.5)` truncated, saturating).
    fn from_acc(v: Self::Acc) -> Self;
    /// As f64 (point queries).
    fn to_f64(self) -> f64;
    /// False for NaN and ±inf (always true for integers).
    fn is_finite(self) -> bool;
    /// SIMD bilinear pixel (RGB(A) u8 only); false when not handled. Same arithmetic.
    #[doc(hidden)]
    #[inline(always)]
    fn bilerp_px_simd(
        _data: &[Self],
        _i00: usize,
        _dx: usize,
        _dy: usize,
        _ax: f32,
        _ay: f32,
        _o: &mut [Self],
    ) -> bool {
        false
    }
    /// Fused homography row (AVX2); false (nothing written) when not handled.
    #[doc(hidden)]
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn homography_row_simd(
        _a: [f32; 3],
        _c: [f32; 3],
        _src: &Image<Self>,
        _interp: Interp,
        _fill: Self,
        _orow: &mut [MaybeUninit<Self>],
        _mrow: &mut [MaybeUninit<bool>],
    ) -> bool {
        false
    }
}

/// The conversions of a texel type: interpolation type, float flag, rounding back.
macro_rules! texel_basics {
    ($t:ty, $acc:ty, $float:literal, |$v:ident| $from:expr) => {
        type Acc = $acc;
        const FLOAT: bool = $float;
        #[inline(always)]
        #[allow(clippy::unnecessary_cast)]
        fn to_acc(self) -> $acc {
            self as $acc
        }
        #[inline(always)]
        fn from_acc($v: $acc) -> $t {
            $from
        }
        #[inline(always)]
        #[allow(clippy::unnecessary_cast)]
        fn to_f64(self) -> f64 {
            self as f64
        }
        #[inline(always)]
        fn is_finite(self) -> bool {
            #[allow(clippy::unnecessary_cast)]
            (self as f64).is_finite()
        }
    };
}

impl Texel for u8 {
    texel_basics!(u8, f32, false, |v| (v + 0.5) as u8);
    #[inline(always)]
    fn bilerp_px_simd(data: &[u8], i00: usize, dx: usize, dy: usize, ax: f32, ay: f32, o: &mut [u8]) -> bool {
        #[cfg(target_arch = "x86_64")]
        {
            if (o.len() == 3 || o.len() == 4) && i00 + dy + dx + 4 <= data.len() {
                // SAFETY: all four 4-byte loads end at most at i00 + dy + dx + 4 <= data.len().
                unsafe { avx2::bilerp4(data.as_ptr(), i00, dx, dy, ax, ay, o) };
                return true;
            }
        }
        let _ = (data, i00, dx, dy, ax, ay, o);
        false
    }
    #[inline(always)]
    fn homography_row_simd(
        a: [f32; 3],
        c: [f32; 3],
        src: &Image<u8>,
        interp: Interp,
        fill: u8,
        orow: &mut [MaybeUninit<u8>],
        mrow: &mut [MaybeUninit<bool>],
    ) -> bool {
        #[cfg(target_arch = "x86_64")]
        {
            if interp == Interp::Bilinear
                && src.channels == 3
                && src.width >= 2
                && src.height >= 2
                && src.data.len() < i32::MAX as usize
                && orow.len() == 3 * mrow.len()
                && avx2::available()
            {
                // SAFETY: AVX2 checked; sizes checked; gathers are masked to in-bounds lanes.
                unsafe { avx2::homography_bilinear_rgb(a, c, &src.data, src.width, src.height, fill, orow, mrow) };
                return true;
            }
            if interp == Interp::Bicubic
                && src.channels == 1
                && src.data.len() < i32::MAX as usize
                && orow.len() == mrow.len()
                && avx2::available()
            {
                // SAFETY: AVX2 checked; sizes checked; gathers only for lanes whose 4×4 taps are inside.
                unsafe { avx2::homography_bicubic_gray(a, c, &src.data, src.width, src.height, fill, orow, mrow) };
                return true;
            }
        }
        let _ = (a, c, src, interp, fill, orow, mrow);
        false
    }
}

impl Texel for u16 {
    texel_basics!(u16, f32, false, |v| (v + 0.5) as u16);
}

impl Texel for f32 {
    texel_basics!(f32, f32, true, |v| v);
    #[inline(always)]
    fn homography_row_simd(
        a: [f32; 3],
        c: [f32; 3],
        src: &Image<f32>,
        interp: Interp,
        fill: f32,
        orow: &mut [MaybeUninit<f32>],
        mrow: &mut [MaybeUninit<bool>],
    ) -> bool {
        #[cfg(target_arch = "x86_64")]
        {
            if interp == Interp::Nearest
                && src.channels == 1
                && src.data.len() < i32::MAX as usize
                && orow.len() == mrow.len()
                && avx2::available()
            {
                // SAFETY: AVX2 checked; sizes checked; gathers are masked to in-bounds lanes, and
                // the safe span only holds pixels whose source is inside.
                unsafe { avx2::homography_nearest_f32(a, c, &src.data, src.width, src.height, fill, orow, mrow) };
                return true;
            }
        }
        let _ = (a, c, src, interp, fill, orow, mrow);
        false
    }
}

impl Texel for f64 {
    texel_basics!(f64, f64, true, |v| v);
}

/// An inverse coordinate map (OpenCV's `map1` as `CV_32FC2`): for each output pixel, row-major,
/// its source position `[x, y]` in px (NaN = none).
#[derive(Clone, Debug, PartialEq)]
pub struct CoordMap {
    /// Output width (px).
    pub width: usize,
    /// Output height (px).
    pub height: usize,
    /// Source positions, `width * height` of them.
    pub xy: Vec<[f32; 2]>,
}

impl CoordMap {
    /// The identity map of a `width`×`height` image.
    pub fn identity(width: usize, height: usize) -> CoordMap {
        let xy = (0..width * height).map(|i| [(i % width) as f32, (i / width) as f32]).collect();
        CoordMap { width, height, xy }
    }

    /// The undistortion map of camera `k` with lens `distortion` (OpenCV `initUndistortRectifyMap`
    /// with R = I and P = K): output pixel (u, v) of the ideal pinhole image with the same `k`
    /// samples the distorted image at `distortion.distort_pixel(k, u, v)` (px).
    pub fn undistort(k: &Intrinsics, distortion: &Distortion, width: usize, height: usize) -> CoordMap {
        let xy = (0..width * height)
            .into_par_iter()
            .map(|i| {
                let (u, v) = distortion.distort_pixel(k, (i % width) as f64, (i / width) as f64);
                [u as f32, v as f32]
            })
            .collect();
        CoordMap { width, height, xy }
    }
}

/// Sample one output row from precomputed source coordinates (the dispatch on channel count).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn sample_row<T: Texel>(
    src: &Image<T>,
    interp: Interp,
    fill: T,
    sx: &[f32],
    sy: &[f32],
    orow: &mut [T],
    mrow: &mut [bool],
) {
    let (d, w, h, c) = (&src.data[..], src.width, src.height, src.channels);
    match (interp, c) {
        (Interp::Bilinear, 1) => kernel::bilinear_row::<T, 1>(d, w, h, c, fill, sx, sy, orow, mrow),
        (Interp::Bilinear, 3) => kernel::bilinear_row::<T, 3>(d, w, h, c, fill, sx, sy, orow, mrow),
        (Interp::Bilinear, 4) => kernel::bilinear_row::<T, 4>(d, w, h, c, fill, sx, sy, orow, mrow),
        (Interp::Bilinear, _) => kernel::bilinear_row::<T, 0>(d, w, h, c, fill, sx, sy, orow, mrow),
        (Interp::Bicubic, 1) => kernel::bicubic_row::<T, 1>(d, w, h, c, fill, sx, sy, orow, mrow),
        (Interp::Bicubic, 3) => kernel::bicubic_row::<T, 3>(d, w, h, c, fill, sx, sy, orow, mrow),
        (Interp::Bicubic, _) => kernel::bicubic_row::<T, 0>(d, w, h, c, fill, sx, sy, orow, mrow),
        (Interp::Nearest, 1) => kernel::nearest_row::<T, 1>(d, w, h, c, fill, sx, sy, orow, mrow),
        (Interp::Nearest, 3) => kernel::nearest_row::<T, 3>(d, w, h, c, fill, sx, sy, orow, mrow),
        (Interp::Nearest, _) => kernel::nearest_row::<T, 0>(d, w, h, c, fill, sx, sy, orow, mrow),
    }
}

/// Initialise a row with `fill` / `false` and view it as initialised.
#[inline(always)]
fn init_row<'a, T: Copy>(
    orow: &'a mut [MaybeUninit<T>],
    mrow: &'a mut [MaybeUninit<bool>],
    fill: T,
) -> (&'a mut [T], &'a mut [bool]) {
    for o in orow.iter_mut() {
        o.write(fill);
    }
    for m in mrow.iter_mut() {
        m.write(false);
    }
    // SAFETY: every element was just initialised; MaybeUninit<T> has T's layout.
    unsafe {
        (&mut *(orow as *mut [MaybeUninit<T>] as *mut [T]), &mut *(mrow as *mut [MaybeUninit<bool>] as *mut [bool]))
    }
}

/// Largest output accepted (values), a guard against absurd sizes before allocating.
const MAX_OUTPUT_VALUES: usize = 1 << 32;

fn check_source<T>(src: &Image<T>, width: usize, height: usize) -> Result<()> {
    if src.width == 0 || src.height == 0 || src.channels == 0 {
        return Err(CoreError::invalid(
            "source image",
            format!("is empty ({}x{}x{})", src.width, src.height, src.channels),
        ));
    }
    if src.data.len() != src.width * src.height * src.channels {
        return Err(CoreError::SizeMismatch(format!(
            "source image has {} values, {}x{}x{} needs {}",
            src.data.len(),
            src.width,
            src.height,
            src.channels,
            src.width * src.height * src.channels
        )));
    }
    if width.checked_mul(height).and_then(|n| n.checked_mul(src.channels)).is_none_or(|n| n > MAX_OUTPUT_VALUES) {
        return Err(CoreError::invalid("output size", format!("{width}x{height} is too large")));
    }
    Ok(())
}

/// The parallel row driver: `row(y, out_row, mask_row, scratch_x, scratch_y)` must write every
/// element of both rows.
fn drive<T: Texel>(
    width: usize,
    height: usize,
    channels: usize,
    row: impl Fn(usize, &mut [MaybeUninit<T>], &mut [MaybeUninit<bool>], &mut [f32], &mut [f32]) + Sync,
) -> (Image<T>, Mask) {
    let n = width * height;
    let mut data: Vec<T> = Vec::with_capacity(n * channels);
    let mut valid: Vec<bool> = Vec::with_capacity(n);
    if n > 0 {
        let orows = &mut data.spare_capacity_mut()[..n * channels];
        let mrows = &mut valid.spare_capacity_mut()[..n];
        orows.par_chunks_mut(width * channels).zip(mrows.par_chunks_mut(width)).enumerate().for_each_init(
            || (vec![0f32; width], vec![0f32; width]),
            |(sx, sy), (y, (orow, mrow))| row(y, orow, mrow, sx, sy),
        );
    }
    // SAFETY: every row of the first n (n * channels) elements was written by `row`, whose
    // contract is to write every element; capacity >= those lengths.
    unsafe {
        data.set_len(n * channels);
        valid.set_len(n);
    }
    (Image { width, height, channels, data }, Image { width, height, channels: 1, data: valid })
}

/// Sample `src` at the positions of `map` (OpenCV `remap` with `CV_32FC2` maps, border
/// "constant" = `fill`). Returns the output image and its validity mask.
pub fn remap<T: Texel>(src: &Image<T>, map: &CoordMap, interp: Interp, fill: T) -> Result<(Image<T>, Mask)> {
    check_source(src, map.width, map.height)?;
    if map.xy.len() != map.width * map.height {
        return Err(CoreError::SizeMismatch(format!(
            "coordinate map has {} positions, {}x{} needs {}",
            map.xy.len(),
            map.width,
            map.height,
            map.width * map.height
        )));
    }
    let w = map.width;
    Ok(drive(map.width, map.height, src.channels, |y, orow, mrow, sx, sy| {
        for ((a, b), p) in sx.iter_mut().zip(sy.iter_mut()).zip(&map.xy[y * w..(y + 1) * w]) {
            (*a, *b) = (p[0], p[1]);
        }
        let (orow, mrow) = init_row(orow, mrow, fill);
        sample_row(src, interp, fill, sx, sy, orow, mrow);
    }))
}

/// Sample `src` at source positions computed per output row by `coords(y, xs, ys)` (which fills
/// `xs[x], ys[x]` for every x of row y; NaN = none). For warps that are neither a homography nor
/// a stored map (piecewise-affine CPC warps, lens distortion).
pub fn remap_rows<T: Texel>(
    src: &Image<T>,
    width: usize,
    height: usize,
    interp: Interp,
    fill: T,
    coords: impl Fn(usize, &mut [f32], &mut [f32]) + Sync,
) -> Result<(Image<T>, Mask)> {
    check_source(src, width, height)?;
    Ok(drive(width, height, src.channels, |y, orow, mrow, sx, sy| {
        coords(y, sx, sy);
        let (orow, mrow) = init_row(orow, mrow, fill);
        sample_row(src, interp, fill, sx, sy, orow, mrow);
    }))
}

/// f32 coefficients of output row `y` of H⁻¹ (row-major): x_s = (a0 x + c0) / (a2 x + c2),
/// y_s = (a1 x + c1) / (a2 x + c2).
#[inline]
pub fn homography_row_coeffs(h_inv: &[[f64; 3]; 3], y: usize) -> ([f32; 3], [f32; 3]) {
    let (h, yf) = (h_inv, y as f64);
    (
        [h[0][0] as f32, h[1][0] as f32, h[2][0] as f32],
        [(h[0][1] * yf + h[0][2]) as f32, (h[1][1] * yf + h[1][2]) as f32, (h[2][1] * yf + h[2][2]) as f32],
    )
}

/// Warp `src` by a homography given as its inverse `h_inv` (output pixel → source pixel,
/// row-major) into a `width`×`height` image (OpenCV `warpPerspective` with `WARP_INVERSE_MAP`).
pub fn warp_homography<T: Texel>(
    src: &Image<T>,
    h_inv: &[[f64; 3]; 3],
    width: usize,
    height: usize,
    interp: Interp,
    fill: T,
) -> Result<(Image<T>, Mask)> {
    check_source(src, width, height)?;
    if h_inv.iter().flatten().any(|v| !v.is_finite()) {
        return Err(CoreError::invalid("homography", format!("non-finite entry in {h_inv:?}")));
    }
    Ok(drive(width, height, src.channels, |y, orow, mrow, sx, sy| {
        let (a, c) = homography_row_coeffs(h_inv, y);
        if T::homography_row_simd(a, c, src, interp, fill, orow, mrow) {
            return;
        }
        homography_row(a, c, sx, sy);
        let (orow, mrow) = init_row(orow, mrow, fill);
        sample_row(src, interp, fill, sx, sy, orow, mrow);
    }))
}

/// Bilinear sample of channel `c` of `img` at the real position (x, y) (f64 arithmetic, the
/// contract above); `None` outside [0, w−1]×[0, h−1]. Float images may give a non-finite value.
#[inline]
pub fn sample_bilinear<T: Texel>(img: &Image<T>, x: f64, y: f64, c: usize) -> Option<f64> {
    let (w, h) = (img.width, img.height);
    if w == 0 || h == 0 || !(x >= 0.0 && y >= 0.0 && x <= (w - 1) as f64 && y <= (h - 1) as f64) {
        return None;
    }
    // x, y >= 0: truncation is floor.
    let x0 = (x as usize).min(w.saturating_sub(2));
    let y0 = (y as usize).min(h.saturating_sub(2));
    let x1 = (x0 + 1).min(w - 1);
    let y1 = (y0 + 1).min(h - 1);
    let g = |xx: usize, yy: usize| img.get(xx, yy, c).to_f64();
    Some(bilerp(g(x0, y0), g(x1, y0), g(x0, y1), g(x1, y1), x - x0 as f64, y - y0 as f64, true))
}

/// Nearest-neighbour sample of channel `c` at (x, y) (round half up); `None` outside
/// [−½, w − ½)×[−½, h − ½).
#[inline]
pub fn sample_nearest<T: Copy>(img: &Image<T>, x: f64, y: f64, c: usize) -> Option<T> {
    let (w, h) = (img.width as f64, img.height as f64);
    if !(x >= -0.5 && y >= -0.5 && x < w - 0.5 && y < h - 0.5) {
        return None;
    }
    let ix = ((x + 0.5) as usize).min(img.width - 1);
    let iy = ((y + 0.5) as usize).min(img.height - 1);
    Some(img.get(ix, iy, c))
}
