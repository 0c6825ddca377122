//! The scalar row kernels of the sampler: the arithmetic contract of [`super`], written once.
//! The SIMD paths of `avx2.rs` / `sse2` reproduce these operations lane by lane.
use super::Texel;
use std::ops::{Add, Mul, Sub};

/// The arithmetic of interpolation: `f32` for 8/16-bit and `f32` texels, `f64` for `f64` ones.
pub trait Real: Copy + PartialEq + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> {
    /// 0.
    const ZERO: Self;
    /// 1.
    const ONE: Self;
    /// From an f64 weight (exact for f64, rounded to nearest for f32).
    fn from_f64(v: f64) -> Self;
}

impl Real for f32 {
    const ZERO: f32 = 0.0;
    const ONE: f32 = 1.0;
    #[inline(always)]
    fn from_f64(v: f64) -> f32 {
        v as f32
    }
}

impl Real for f64 {
    const ZERO: f64 = 0.0;
    const ONE: f64 = 1.0;
    #[inline(always)]
    fn from_f64(v: f64) -> f64 {
        v
    }
}

/// `a + t (b − a)`; with `exact_ends` (float texels) a weight of exactly 0 or 1 returns `a` or `b`
/// untouched, so that a non-finite neighbour with zero weight does not contaminate the result.
/// For finite small integers (u8, u16) the two forms are bitwise equal. `exact_ends` is a
/// constant at every call site, so the test compiles away.
#[inline(always)]
pub fn lerp<R: Real>(a: R, b: R, t: R, exact_ends: bool) -> R {
    if exact_ends {
        if t == R::ZERO {
            return a;
        }
        if t == R::ONE {
            return b;
        }
    }
    a + t * (b - a)
}

/// The bilinear kernel: `lerp(lerp(p00, p10, ax), lerp(p01, p11, ax), ay)` (x first, then y).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn bilerp<R: Real>(p00: R, p10: R, p01: R, p11: R, ax: R, ay: R, exact_ends: bool) -> R {
    let e = exact_ends;
    lerp(lerp(p00, p10, ax, e), lerp(p01, p11, ax, e), ay, e)
}

/// Source coordinates of one output row of a homography warp: x_s = (a0 x + c0) / (a2 x + c2),
/// y_s = (a1 x + c1) / (a2 x + c2), in f32, NaN where the denominator is <= 1e-12 (behind the
/// camera). Compiled for AVX2 when the CPU has it (same operations, no FMA contraction).
pub fn homography_row(a: [f32; 3], c: [f32; 3], sx: &mut [f32], sy: &mut [f32]) {
    #[cfg(target_arch = "x86_64")]
    {
        if super::avx2::available() {
            // SAFETY: the CPU supports AVX2 (checked above).
            unsafe { homography_row_avx2(a, c, sx, sy) };
            return;
        }
    }
    homography_row_body(a, c, sx, sy)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn homography_row_avx2(a: [f32; 3], c: [f32; 3], sx: &mut [f32], sy: &mut [f32]) {
    homography_row_body(a, c, sx, sy)
}

/// One pixel of [`homography_row`] (the AVX2 paths do the same operations).
#[inline(always)]
pub fn homography_px(a: [f32; 3], c: [f32; 3], xf: f32) -> (f32, f32) {
    let w = a[2] * xf + c[2];
    let iw = if w > 1e-12 { 1.0 / w } else { f32::NAN };
    ((a[0] * xf + c[0]) * iw, (a[1] * xf + c[1]) * iw)
}

#[inline(always)]
fn homography_row_body(a: [f32; 3], c: [f32; 3], sx: &mut [f32], sy: &mut [f32]) {
    let n = sx.len().min(sy.len());
    let (sx, sy) = (&mut sx[..n], &mut sy[..n]);
    for i in 0..n {
        // Through i32: usize → f32 has no single instruction before AVX-512.
        let (x, y) = homography_px(a, c, (i as i32) as f32);
        sx[i] = x;
        sy[i] = y;
    }
}

/// Bilinear sampling of one output row with `C` channels (`C` = 0: the run-time channel count
/// `src_c`). Writes every output pixel: the sample and `true`, or `fill` and `false` when the
/// source lies outside [0, w−1]×[0, h−1], is NaN, or (float texels) the sample is not finite.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub fn bilinear_row<T: Texel, const C: usize>(
    data: &[T],
    w: usize,
    h: usize,
    src_c: usize,
    fill: T,
    sx: &[f32],
    sy: &[f32],
    orow: &mut [T],
    mrow: &mut [bool],
) {
    let c = if C == 0 { src_c } else { C };
    let n = mrow.len();
    assert!(
        c > 0 && sx.len() >= n && sy.len() >= n && orow.len() == n * c && data.len() == w * h * c && w > 0 && h > 0
    );
    let (xmax, ymax) = ((w - 1) as f32, (h - 1) as f32);
    let stride = w * c;
    let dx = if w > 1 { c } else { 0 };
    let dy = if h > 1 { stride } else { 0 };
    let (wm2, hm2) = (w.saturating_sub(2), h.saturating_sub(2));
    for x in 0..n {
        let (fx, fy) = (sx[x], sy[x]);
        let o = &mut orow[x * c..x * c + c];
        if !(fx >= 0.0 && fy >= 0.0 && fx <= xmax && fy <= ymax) {
            o.fill(fill);
            mrow[x] = false;
            continue;
        }
        // fx >= 0, so truncation is floor; clamp so that x0 + 1 stays inside.
        let x0 = (fx as i32 as usize).min(wm2);
        let y0 = (fy as i32 as usize).min(hm2);
        let (ax, ay) = (fx - x0 as i32 as f32, fy - y0 as i32 as f32);
        let i00 = y0 * stride + x0 * c;
        if T::bilerp_px_simd(data, i00, dx, dy, ax, ay, o) {
            mrow[x] = true;
            continue;
        }
        let (ax, ay) = (T::Acc::from_f64(ax as f64), T::Acc::from_f64(ay as f64));
        let mut ok = true;
        for ch in 0..c {
            let v = bilerp(
                data[i00 + ch].to_acc(),
                data[i00 + dx + ch].to_acc(),
                data[i00 + dy + ch].to_acc(),
                data[i00 + dy + dx + ch].to_acc(),
                ax,
                ay,
                T::FLOAT,
            );
            let t = T::from_acc(v);
            ok &= t.is_finite();
            o[ch] = t;
        }
        if !ok {
            o.fill(fill);
        }
        mrow[x] = ok;
    }
}

/// Keys' cubic convolution weights (a = −½) of the taps at offsets −1, 0, 1, 2 for the fraction
/// t ∈ [0, 1] (they sum to 1; t = 0 gives (0, 1, 0, 0) exactly).
#[inline(always)]
pub fn cubic_weights(t: f64) -> [f64; 4] {
    [
        ((-0.5 * t + 1.0) * t - 0.5) * t,
        (1.5 * t - 2.5) * t * t + 1.0,
        ((-1.5 * t + 2.0) * t + 0.5) * t,
        (0.5 * t - 0.5) * t * t,
    ]
}

/// Bicubic sampling of one output row (`C` = 0: run-time `src_c` channels), the contract of
/// [`super`]: valid domain [0, w−1]×[0, h−1], edge pixels replicated, zero weights skipped.
/// Integer texels whose 4×4 neighbourhood lies inside the image take an unclamped path that adds
/// every tap in the same order (a zero weight adds ±0 to a finite sum: the same value); float
/// texels and border pixels take [`bicubic_px_generic`].
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub fn bicubic_row<T: Texel, const C: usize>(
    data: &[T],
    w: usize,
    h: usize,
    src_c: usize,
    fill: T,
    sx: &[f32],
    sy: &[f32],
    orow: &mut [T],
    mrow: &mut [bool],
) {
    let c = if C == 0 { src_c } else { C };
    let n = mrow.len();
    assert!(
        c > 0 && sx.len() >= n && sy.len() >= n && orow.len() == n * c && data.len() == w * h * c && w > 0 && h > 0
    );
    let (xmax, ymax) = ((w - 1) as f32, (h - 1) as f32);
    for x in 0..n {
        let (fx, fy) = (sx[x], sy[x]);
        let o = &mut orow[x * c..x * c + c];
        if !(fx >= 0.0 && fy >= 0.0 && fx <= xmax && fy <= ymax) {
            o.fill(fill);
            mrow[x] = false;
            continue;
        }
        // f >= 0: truncation is floor.
        let (i1, j1) = (fx as usize, fy as usize);
        if !T::FLOAT && i1 >= 1 && i1 + 2 < w && j1 >= 1 && j1 + 2 < h {
            let wx = cubic_weights(fx as f64 - i1 as f64).map(T::Acc::from_f64);
            let wy = cubic_weights(fy as f64 - j1 as f64).map(T::Acc::from_f64);
            for (ch, out) in o.iter_mut().enumerate() {
                let mut v = T::Acc::ZERO;
                for (j, &wyj) in wy.iter().enumerate() {
                    let b = ((j1 + j - 1) * w + i1 - 1) * c + ch;
                    let p = &data[b..=b + 3 * c];
                    let r = T::Acc::ZERO
                        + wx[0] * p[0].to_acc()
                        + wx[1] * p[c].to_acc()
                        + wx[2] * p[2 * c].to_acc()
                        + wx[3] * p[3 * c].to_acc();
                    v = v + wyj * r;
                }
                *out = T::from_acc(v);
            }
            mrow[x] = true;
            continue;
        }
        mrow[x] = bicubic_px_generic(data, w, h, c, fill, fx, fy, o);
    }
}

/// One bicubic output pixel at (fx, fy) ∈ [0, w−1]×[0, h−1] with clamped taps and zero weights
/// skipped (every texel type, every position); writes `fill` and returns false when a channel is
/// not finite.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub fn bicubic_px_generic<T: Texel>(
    data: &[T],
    w: usize,
    h: usize,
    c: usize,
    fill: T,
    fx: f32,
    fy: f32,
    o: &mut [T],
) -> bool {
    let taps = |f: f32, size: usize| -> ([usize; 4], [T::Acc; 4]) {
        // f >= 0: truncation is floor.
        let i1 = (f as i32 as usize).min(size - 1);
        let wt = cubic_weights(f as f64 - i1 as f64).map(T::Acc::from_f64);
        let idx = [i1.saturating_sub(1), i1, (i1 + 1).min(size - 1), (i1 + 2).min(size - 1)];
        (idx, wt)
    };
    let (ix, wx) = taps(fx, w);
    let (iy, wy) = taps(fy, h);
    let mut ok = true;
    for ch in 0..c {
        let mut v = T::Acc::ZERO;
        for j in 0..4 {
            if wy[j] == T::Acc::ZERO {
                continue;
            }
            let row = iy[j] * w;
            let mut r = T::Acc::ZERO;
            for i in 0..4 {
                if wx[i] != T::Acc::ZERO {
                    r = r + wx[i] * data[(row + ix[i]) * c + ch].to_acc();
                }
            }
            v = v + wy[j] * r;
        }
        let t = T::from_acc(v);
        ok &= t.is_finite();
        o[ch] = t;
    }
    if !ok {
        o.fill(fill);
    }
    ok
}

/// Nearest-neighbour sampling of one output row (`C` = 0: run-time `src_c` channels): the source
/// pixel is (⌊x + ½⌋, ⌊y + ½⌋) (round half up); valid when x, y ∈ [−½, w − ½) × [−½, h − ½) and
/// (float texels) every channel is finite. Writes every output pixel (`fill`, `false` if invalid).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub fn nearest_row<T: Texel, const C: usize>(
    data: &[T],
    w: usize,
    h: usize,
    src_c: usize,
    fill: T,
    sx: &[f32],
    sy: &[f32],
    orow: &mut [T],
    mrow: &mut [bool],
) {
    let c = if C == 0 { src_c } else { C };
    let n = mrow.len();
    assert!(c > 0 && sx.len() >= n && sy.len() >= n && orow.len() == n * c && data.len() == w * h * c);
    let (wf, hf) = (w as f32 - 0.5, h as f32 - 0.5);
    for x in 0..n {
        let (fx, fy) = (sx[x], sy[x]);
        let o = &mut orow[x * c..x * c + c];
        if fx >= -0.5 && fy >= -0.5 && fx < wf && fy < hf {
            // fx + 0.5 is in [0, w): truncation is floor and the index is in bounds.
            let ix = ((fx + 0.5) as i32 as usize).min(w - 1);
            let iy = ((fy + 0.5) as i32 as usize).min(h - 1);
            let i = (iy * w + ix) * c;
            let src = &data[i..i + c];
            if !T::FLOAT || src.iter().all(|v| v.is_finite()) {
                o.copy_from_slice(src);
                mrow[x] = true;
                continue;
            }
        }
        o.fill(fill);
        mrow[x] = false;
    }
}

/// Pixels `[xs, xe)` of a row (n pixels, x_s = (a0 x + c0) / (a2 x + c2), y_s likewise) whose
/// f32 source coordinates, computed as in [`homography_row`], are guaranteed to be strictly
/// inside the nearest-neighbour domain: x_s ∈ (−0.5, w − 0.5), y_s ∈ (−0.5, h − 0.5), with the
/// denominator > 1e-12 and x_s + 0.5 (y_s + 0.5) rounding to [0, w) ([0, h)). There the bounds
/// tests and clamps of the general loop are all true / no-ops and may be skipped.
///
/// Error bound (u = 2⁻²⁴, xf exact since n <= 2²⁴): the f32 numerator and denominator are within
/// e_N = 3u (|a0| x_max + |c0|) and e_W = 3u (|a2| x_max + |c2|) of their exact values N, W (two
/// rounded operations each); with W >= W_min > e_W on the whole row (W is linear in x, so its
/// minimum is at an end), |x_s,f32 − N/W| <= (e_N + |N/W| e_W) / (W_min − e_W) (1 + 4u) + 8u S,
/// S = max(w, h) + 1 bounding |N/W| inside. The exact coordinates are then kept at least
/// m = err + 1e-3 + 8u S from the borders; for W > 0, "N/W >= L" is the linear condition
/// (a0 − L a2) x >= L c2 − c0, so the span is an intersection of half-lines, shrunk by one pixel
/// at each end for the f64 rounding of the bounds. Returns an empty span when unsure.
pub fn safe_span(a: [f32; 3], c: [f32; 3], w: usize, h: usize, n: usize) -> (usize, usize) {
    const NONE: (usize, usize) = (0, 0);
    if n == 0 || n > 1 << 24 || w == 0 || h == 0 || w > 1 << 22 || h > 1 << 22 {
        return NONE;
    }
    let u = f64::from(f32::EPSILON) / 2.0;
    let [a0, a1, a2] = a.map(f64::from);
    let [c0, c1, c2] = c.map(f64::from);
    if !a.iter().chain(&c).all(|v| v.is_finite()) {
        return NONE;
    }
    let xm = (n - 1) as f64;
    let w_min = c2.min(a2 * xm + c2);
    let ew = 3.0 * u * (a2.abs() * xm + c2.abs());
    if !(w_min > 2.0 * ew && w_min > 1e-6) {
        return NONE; // also NaN / infinite coefficients
    }
    let en = 3.0 * u * (a0.abs() * xm + c0.abs()).max(a1.abs() * xm + c1.abs());
    let smax = (w.max(h) + 1) as f64;
    let err = (en + smax * ew) / (w_min - ew) * (1.0 + 4.0 * u) + 8.0 * u * smax;
    let m = err + 1e-3 + 8.0 * u * smax;
    if m.is_nan() || m >= 0.25 {
        return NONE;
    }
    let (mut lo, mut hi) = (0.0f64, xm);
    // p x >= q
    let mut half_line = |p: f64, q: f64| {
        if !(p.is_finite() && q.is_finite()) {
            hi = -1.0;
        } else if p > 0.0 {
            lo = lo.max(q / p);
        } else if p < 0.0 {
            hi = hi.min(q / p);
        } else if q > 0.0 {
            hi = -1.0;
        }
    };
    for (ak, ck, size) in [(a0, c0, w as f64), (a1, c1, h as f64)] {
        let (lb, ub) = (-0.5 + m, size - 0.5 - m);
        half_line(ak - lb * a2, lb * c2 - ck); // N/W >= lb
        half_line(ub * a2 - ak, ck - ub * c2); // N/W <= ub
    }
    let (xs, xe) = (lo.ceil() + 1.0, hi.floor() - 1.0);
    if !(xs <= xe && xs >= 0.0 && xe <= xm) {
        return NONE;
    }
    (xs as usize, xe as usize + 1)
}
