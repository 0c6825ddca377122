//! Inner loops of the inverse-mapping warps (hand-written for speed: the image crates in the
//! workspace have no perspective warp, and a generic per-pixel closure is ~3× slower).
//!
//! Per output row: (1) source coordinates in f32 structure-of-arrays buffers (a loop the
//! compiler vectorises; compiled for AVX2 when the CPU has it, chosen at run time), then
//! (2) sampling. Bilinear sampling works on all channels of a pixel at once (SSE2 on x86-64).
//! All paths use the same f32 operations in the same order (no FMA contraction), so results
//! do not depend on the CPU path taken: bilinear value = lerp(lerp(p00, p10, ax), lerp(p01, p11, ax), ay)
//! with lerp(a, b, t) = a + t (b − a), rounded half up. At integer source positions the weights
//! are exactly 0, so identity and integer shifts reproduce the input bit for bit.

use std::mem::MaybeUninit;

/// Source coordinates of one row of a homography warp: x_s = (a0 x + c0) / (a2 x + c2),
/// y_s = (a1 x + c1) / (a2 x + c2); NaN where the denominator is <= 1e-12 (behind the camera).
pub fn homography_row(a: [f32; 3], c: [f32; 3], sx: &mut [f32], sy: &mut [f32]) {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") {
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

#[inline(always)]
fn homography_row_body(a: [f32; 3], c: [f32; 3], sx: &mut [f32], sy: &mut [f32]) {
    let n = sx.len().min(sy.len());
    let (sx, sy) = (&mut sx[..n], &mut sy[..n]);
    for i in 0..n {
        // Through i32: usize → f32 has no single instruction before AVX-512.
        let xf = (i as i32) as f32;
        let w = a[2] * xf + c[2];
        let iw = if w > 1e-12 { 1.0 / w } else { f32::NAN };
        sx[i] = (a[0] * xf + c[0]) * iw;
        sy[i] = (a[1] * xf + c[1]) * iw;
    }
}

#[inline(always)]
fn lerp(a: f32, b: f32, t: f32) -> f32 {
    a + t * (b - a)
}

/// Bilinear sampling of one output row of an interleaved u8 image with `C` channels.
/// Pixels whose source lies outside [0, w−1]×[0, h−1] (or is NaN) are left untouched
/// (the caller pre-fills 0) and marked invalid.
pub fn bilinear_row<const C: usize>(
    data: &[u8],
    w: usize,
    h: usize,
    sx: &[f32],
    sy: &[f32],
    orow: &mut [u8],
    mrow: &mut [bool],
) {
    let n = orow.len() / C;
    assert!(sx.len() >= n && sy.len() >= n && mrow.len() >= n && data.len() == w * h * C && w > 0 && h > 0);
    let (xmax, ymax) = ((w - 1) as f32, (h - 1) as f32);
    let stride = w * C;
    let dx = if w > 1 { C } else { 0 };
    let dy = if h > 1 { stride } else { 0 };
    let (wm2, hm2) = (w.saturating_sub(2), h.saturating_sub(2));
    for x in 0..n {
        let (fx, fy) = (sx[x], sy[x]);
        if !(fx >= 0.0 && fy >= 0.0 && fx <= xmax && fy <= ymax) {
            continue;
        }
        // fx >= 0, so truncation is floor; clamp so that x0 + 1 stays inside.
        let x0 = (fx as i32 as usize).min(wm2);
        let y0 = (fy as i32 as usize).min(hm2);
        let ax = fx - x0 as f32;
        let ay = fy - y0 as f32;
        let i00 = y0 * stride + x0 * C;
        let o = &mut orow[x * C..x * C + C];
        #[cfg(target_arch = "x86_64")]
        {
            if (C == 3 || C == 4) && i00 + dy + dx + 4 <= data.len() {
                // SAFETY: all four 4-byte loads end at most at i00 + dy + dx + 4 <= data.len().
                unsafe { simd::bilerp4(data.as_ptr(), i00, dx, dy, ax, ay, o) };
                mrow[x] = true;
                continue;
            }
        }
        for ch in 0..C {
            let p00 = data[i00 + ch] as f32;
            let p10 = data[i00 + dx + ch] as f32;
            let p01 = data[i00 + dy + ch] as f32;
            let p11 = data[i00 + dy + dx + ch] as f32;
            let v = lerp(lerp(p00, p10, ax), lerp(p01, p11, ax), ay);
            o[ch] = (v + 0.5) as u8;
        }
        mrow[x] = true;
    }
}

#[cfg(target_arch = "x86_64")]
mod simd {
    use std::arch::x86_64::*;

    /// Bilinear interpolation of 4 consecutive bytes at once (SSE2, part of x86-64); writes
    /// `o.len()` (3 or 4) bytes. Same f32 operations as the scalar path.
    #[inline(always)]
    pub unsafe fn bilerp4(p: *const u8, i00: usize, dx: usize, dy: usize, ax: f32, ay: f32, o: &mut [u8]) {
        let z = _mm_setzero_si128();
        let ld = |i: usize| {
            let v = _mm_cvtsi32_si128(std::ptr::read_unaligned(p.add(i) as *const i32));
            _mm_cvtepi32_ps(_mm_unpacklo_epi16(_mm_unpacklo_epi8(v, z), z))
        };
        let (p00, p10, p01, p11) = (ld(i00), ld(i00 + dx), ld(i00 + dy), ld(i00 + dy + dx));
        let vax = _mm_set1_ps(ax);
        let vay = _mm_set1_ps(ay);
        let top = _mm_add_ps(p00, _mm_mul_ps(vax, _mm_sub_ps(p10, p00)));
        let bot = _mm_add_ps(p01, _mm_mul_ps(vax, _mm_sub_ps(p11, p01)));
        let v = _mm_add_ps(_mm_add_ps(top, _mm_mul_ps(vay, _mm_sub_ps(bot, top))), _mm_set1_ps(0.5));
        let i = _mm_cvttps_epi32(v);
        let b = _mm_packus_epi16(_mm_packs_epi32(i, z), z);
        let word = (_mm_cvtsi128_si32(b) as u32).to_le_bytes();
        let n = o.len();
        o.copy_from_slice(&word[..n]);
    }
}

/// Nearest-neighbour sampling of one output row of a one-channel f32 map; a pixel is valid
/// when its rounded source (half up) is inside and the value is finite. Writes every output
/// pixel (`fill` and `false` where invalid).
#[allow(clippy::too_many_arguments)]
pub fn nearest_row_f32(
    data: &[f32],
    w: usize,
    h: usize,
    fill: f32,
    sx: &[f32],
    sy: &[f32],
    orow: &mut [f32],
    mrow: &mut [bool],
) {
    let n = orow.len();
    assert!(sx.len() >= n && sy.len() >= n && mrow.len() >= n && data.len() == w * h);
    let (wf, hf) = (w as f32 - 0.5, h as f32 - 0.5);
    for x in 0..n {
        let (fx, fy) = (sx[x], sy[x]);
        if fx >= -0.5 && fy >= -0.5 && fx < wf && fy < hf {
            // fx + 0.5 is in [0, w): truncation is floor and the index is in bounds.
            let ix = ((fx + 0.5) as i32 as usize).min(w - 1);
            let iy = ((fy + 0.5) as i32 as usize).min(h - 1);
            // SAFETY: ix < w and iy < h, and data.len() == w * h (asserted above).
            let v = unsafe { *data.get_unchecked(iy * w + ix) };
            if v.is_finite() {
                orow[x] = v;
                mrow[x] = true;
                continue;
            }
        }
        orow[x] = fill;
        mrow[x] = false;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn simd_and_scalar_paths_agree() {
        // 3-channel 5x4 image; sample at many sub-pixel positions including the last pixel
        // (which takes the scalar path) and compare with a scalar reference.
        let (w, h) = (5usize, 4usize);
        let data: Vec<u8> = (0..w * h * 3).map(|i| ((i * 37 + 11) % 256) as u8).collect();
        let pts: Vec<(f32, f32)> = (0..200)
            .map(|i| ((i as f32 * 0.0213) % 4.0, (i as f32 * 0.0157) % 3.0))
            .chain([(4.0, 3.0), (3.5, 2.999)])
            .collect();
        let sx: Vec<f32> = pts.iter().map(|p| p.0).collect();
        let sy: Vec<f32> = pts.iter().map(|p| p.1).collect();
        let mut o = vec![0u8; pts.len() * 3];
        let mut m = vec![false; pts.len()];
        bilinear_row::<3>(&data, w, h, &sx, &sy, &mut o, &mut m);
        for (k, &(fx, fy)) in pts.iter().enumerate() {
            let x0 = (fx as usize).min(w - 2);
            let y0 = (fy as usize).min(h - 2);
            let (ax, ay) = (fx - x0 as f32, fy - y0 as f32);
            for c in 0..3 {
                let g = |x: usize, y: usize| data[(y * w + x) * 3 + c] as f32;
                let v = lerp(lerp(g(x0, y0), g(x0 + 1, y0), ax), lerp(g(x0, y0 + 1), g(x0 + 1, y0 + 1), ax), ay);
                assert_eq!(o[k * 3 + c], (v + 0.5) as u8, "point {k} channel {c}");
            }
            assert!(m[k]);
        }
    }

    #[test]
    fn fused_rows_equal_two_pass_rows() {
        // A CATS-like inverse homography on a 61x37 RGB image and a float map with inf holes.
        let (w, h) = (61usize, 37usize);
        let img: Vec<u8> = (0..w * h * 3).map(|i| ((i * 131 + 7) % 251) as u8).collect();
        let fmap: Vec<f32> = (0..w * h).map(|i| if i % 13 == 0 { f32::INFINITY } else { i as f32 * 0.37 }).collect();
        for y in 0..h {
            let yf = y as f32;
            let a = [0.9983f32, 0.0041, -4.04e-4];
            let c = [-0.005 * yf + 5.3, 1.0001 * yf - 2.3, 4.0e-5 * yf + 1.0018];
            let (mut sx, mut sy) = (vec![0f32; w], vec![0f32; w]);
            homography_row(a, c, &mut sx, &mut sy);
            let (mut o1, mut m1) = (vec![0u8; w * 3], vec![false; w]);
            bilinear_row::<3>(&img, w, h, &sx, &sy, &mut o1, &mut m1);
            let (mut o2, mut m2) = (vec![0u8; w * 3], vec![false; w]);
            if homography_bilinear_rgb_row(a, c, &img, w, h, &mut o2, &mut m2) {
                assert_eq!((&o1, &m1), (&o2, &m2), "row {y}");
            }
            let (mut f1, mut n1) = (vec![0f32; w], vec![false; w]);
            nearest_row_f32(&fmap, w, h, -1.0, &sx, &sy, &mut f1, &mut n1);
            let (mut f2, mut n2) = (vec![0f32; w], vec![false; w]);
            if homography_nearest_f32_row(a, c, &fmap, w, h, -1.0, &mut f2, &mut n2) {
                assert_eq!(
                    f1.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                    f2.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
                );
                assert_eq!(n1, n2);
            }
        }
    }

    /// Plain per-pixel reference of the nearest f32 row: the coordinate arithmetic of
    /// `homography_row_body`, the rounding and validity rule of `nearest_row_f32`.
    fn nearest_reference(
        a: [f32; 3],
        c: [f32; 3],
        data: &[f32],
        w: usize,
        h: usize,
        fill: f32,
        n: usize,
    ) -> (Vec<u32>, Vec<bool>) {
        let (mut o, mut m) = (vec![fill.to_bits(); n], vec![false; n]);
        for x in 0..n {
            let xf = x as i32 as f32;
            let ww = a[2] * xf + c[2];
            let iw = if ww > 1e-12 { 1.0 / ww } else { f32::NAN };
            let (fx, fy) = ((a[0] * xf + c[0]) * iw, (a[1] * xf + c[1]) * iw);
            if fx >= -0.5 && fy >= -0.5 && fx < w as f32 - 0.5 && fy < h as f32 - 0.5 {
                let ix = ((fx + 0.5).floor() as usize).min(w - 1);
                let iy = ((fy + 0.5).floor() as usize).min(h - 1);
                let v = data[iy * w + ix];
                if v.is_finite() {
                    o[x] = v.to_bits();
                    m[x] = true;
                }
            }
        }
        (o, m)
    }

    #[test]
    fn nearest_fast_paths_equal_per_pixel_reference() {
        // Random homographies (CATS-like small rotations where runs dominate, large rotations,
        // scalings and perspective where runs break and denominators change sign), random sizes
        // incl. 1-pixel rows/columns, maps with inf/NaN holes, sources crossing every border.
        let mut st = 0x9E37_79B9_7F4A_7C15u64;
        let mut rnd = move || {
            st ^= st << 13;
            st ^= st >> 7;
            st ^= st << 17;
            (st >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut fast_rows = 0;
        for t in 0..400 {
            let (w, h) =
                if t % 5 == 0 { (640, 360) } else { (1 + (rnd() * 90.0) as usize, 1 + (rnd() * 60.0) as usize) };
            let n = if t % 7 == 0 { 1 + (rnd() * 100.0) as usize } else { w };
            let data: Vec<f32> = (0..w * h)
                .map(|i| match (rnd() * 40.0) as u32 {
                    0 => f32::INFINITY,
                    1 => f32::NAN,
                    2 => f32::NEG_INFINITY,
                    _ => i as f32 * 0.37 - 11.0,
                })
                .collect();
            let deg = [0.3, 5.0, 45.0, 170.0][t % 4] * (2.0 * rnd() - 1.0);
            let (sn, cs) = deg.to_radians().sin_cos();
            let s = 1.0 + [0.0, 0.001, 0.2, -0.5][(t / 4) % 4] * rnd();
            let p = [0.0, 1e-5, 1e-3, 2e-2][(t / 16) % 4] * (2.0 * rnd() - 1.0);
            let (tx, ty) = ((2.0 * rnd() - 1.0) * w as f64 * 0.3, (2.0 * rnd() - 1.0) * h as f64 * 0.3);
            // H⁻¹ rows: x_s = (s cos x − s sin y + tx) / (p x + q y + 1) etc.
            let q = p * (2.0 * rnd() - 1.0);
            for y in 0..h {
                let yf = y as f64;
                let a = [(s * cs) as f32, (s * sn) as f32, p as f32];
                let c = [(-s * sn * yf + tx) as f32, (s * cs * yf + ty) as f32, (q * yf + 1.0) as f32];
                let fill = -7.0;
                let (ro, rm) = nearest_reference(a, c, &data, w, h, fill, n);
                let (mut o, mut m) = (vec![1.5f32; n], vec![true; n]);
                if homography_nearest_f32_row(a, c, &data, w, h, fill, &mut o, &mut m) {
                    let o: Vec<u32> = o.iter().map(|v| v.to_bits()).collect();
                    assert_eq!((&o, &m), (&ro, &rm), "case {t} row {y} ({w}x{h}, n {n}, {deg} deg)");
                }
                // The two-pass portable path.
                let (mut sx, mut sy) = (vec![0f32; n], vec![0f32; n]);
                homography_row(a, c, &mut sx, &mut sy);
                let (mut o, mut m) = (vec![1.5f32; n], vec![true; n]);
                nearest_row_f32(&data, w, h, fill, &sx, &sy, &mut o, &mut m);
                let o: Vec<u32> = o.iter().map(|v| v.to_bits()).collect();
                assert_eq!((&o, &m), (&ro, &rm), "portable: case {t} row {y}");
                let (xs, xe) = safe_span(a, c, w, h, n);
                assert!(xs <= xe && xe <= n);
                if xe > xs + 8 {
                    fast_rows += 1;
                }
                // Every pixel of the safe span is strictly inside with a positive denominator.
                for x in xs..xe {
                    let (fx, fy) = (sx[x], sy[x]);
                    assert!(fx > -0.5 && fy > -0.5 && fx < w as f32 - 0.5 && fy < h as f32 - 0.5, "span {t} {y} {x}");
                    assert!(((fx + 0.5) as usize) < w && ((fy + 0.5) as usize) < h);
                }
            }
        }
        assert!(fast_rows > 1000, "the safe span was exercised ({fast_rows} rows)");
    }

    #[test]
    fn safe_span_rejects_degenerate_rows() {
        let nan = f32::NAN;
        assert_eq!(safe_span([1.0, 0.0, 0.0], [0.0, 0.0, 1.0], 0, 10, 10), (0, 0));
        assert_eq!(safe_span([1.0, 0.0, 0.0], [0.0, 0.0, 1.0], 10, 10, 0), (0, 0));
        assert_eq!(safe_span([nan, 0.0, 0.0], [0.0, 0.0, 1.0], 10, 10, 10), (0, 0));
        assert_eq!(safe_span([1.0, 0.0, f32::INFINITY], [0.0, 0.0, 1.0], 10, 10, 10), (0, 0));
        // Denominator crossing zero on the row, or negative: nothing is declared safe.
        assert_eq!(safe_span([1.0, 0.0, -0.01], [0.0, 5.0, 0.05], 100, 10, 100), (0, 0));
        assert_eq!(safe_span([1.0, 0.0, 0.0], [0.0, 5.0, -1.0], 100, 10, 100), (0, 0));
        // Identity row 5 of a 100x10 image: all but the end pixels (one-pixel shrink).
        assert_eq!(safe_span([1.0, 0.0, 0.0], [0.0, 5.0, 1.0], 100, 10, 100), (1, 99));
        // Row outside the image.
        assert_eq!(safe_span([1.0, 0.0, 0.0], [0.0, 10.0, 1.0], 100, 10, 100), (0, 0));
    }

    #[test]
    fn homography_row_identity_is_exact() {
        let mut sx = vec![0.0; 1000];
        let mut sy = vec![0.0; 1000];
        homography_row([1.0, 0.0, 0.0], [-7.0, 3.0, 1.0], &mut sx, &mut sy);
        for (i, (&a, &b)) in sx.iter().zip(&sy).enumerate() {
            assert_eq!((a, b), (i as f32 - 7.0, 3.0));
        }
    }
}

/// Fused homography + bilinear RGB row (AVX2 gathers, 8 pixels per step). Returns false when
/// the CPU lacks AVX2 (the caller then uses [`homography_row`] + [`bilinear_row`], which give
/// identical bytes: same f32 operations in the same order).
pub fn homography_bilinear_rgb_row(
    a: [f32; 3],
    c: [f32; 3],
    data: &[u8],
    w: usize,
    h: usize,
    orow: &mut [u8],
    mrow: &mut [bool],
) -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") && data.len() < i32::MAX as usize && w >= 2 && h >= 2 {
            assert!(data.len() == w * h * 3 && orow.len() == mrow.len() * 3);
            // SAFETY: AVX2 checked; sizes asserted; gathers are masked to in-bounds lanes.
            unsafe { avx2::bilinear_rgb(a, c, data, w, h, orow, mrow) };
            return true;
        }
    }
    let _ = (a, c, data, w, h, orow, mrow);
    false
}

/// Fused homography + nearest f32 row (AVX2); writes every pixel. Returns false without AVX2.
/// (Initialised-slice form of [`homography_nearest_f32_row_uninit`], for the tests.)
#[cfg(test)]
#[allow(clippy::too_many_arguments)]
pub fn homography_nearest_f32_row(
    a: [f32; 3],
    c: [f32; 3],
    data: &[f32],
    w: usize,
    h: usize,
    fill: f32,
    orow: &mut [f32],
    mrow: &mut [bool],
) -> bool {
    // SAFETY: `MaybeUninit<T>` has the layout of `T`, and the kernel only ever writes
    // initialised values (floats; bools as bytes 0 or 1) into these slices.
    let (orow, mrow) = unsafe {
        (&mut *(orow as *mut [f32] as *mut [MaybeUninit<f32>]), &mut *(mrow as *mut [bool] as *mut [MaybeUninit<bool>]))
    };
    homography_nearest_f32_row_uninit(a, c, data, w, h, fill, orow, mrow)
}

/// [`homography_nearest_f32_row`] into uninitialised rows: when it returns true, every element
/// of `orow` and `mrow` has been written. Returns false (writing nothing) without AVX2.
#[allow(clippy::too_many_arguments)]
pub fn homography_nearest_f32_row_uninit(
    a: [f32; 3],
    c: [f32; 3],
    data: &[f32],
    w: usize,
    h: usize,
    fill: f32,
    orow: &mut [MaybeUninit<f32>],
    mrow: &mut [MaybeUninit<bool>],
) -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") && data.len() < i32::MAX as usize {
            assert!(data.len() == w * h && orow.len() == mrow.len());
            let span = safe_span(a, c, w, h, orow.len());
            // SAFETY: AVX2 checked; sizes asserted; gathers are masked to in-bounds lanes, and
            // `span` only holds pixels whose source is inside (see `safe_span`).
            unsafe { avx2::nearest_f32(a, c, data, w, h, fill, span, orow, mrow) };
            return true;
        }
    }
    let _ = (a, c, data, w, h, fill, orow, mrow);
    false
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

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use std::arch::x86_64::*;
    use std::mem::MaybeUninit;

    /// Coordinates of 8 consecutive pixels starting at `x0`: same operations as `homography_row_body`.
    #[inline(always)]
    unsafe fn coords(a: [f32; 3], c: [f32; 3], x0: usize) -> (__m256, __m256, __m256) {
        let xf = _mm256_cvtepi32_ps(_mm256_add_epi32(
            _mm256_set1_epi32(x0 as i32),
            _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7),
        ));
        let w = _mm256_add_ps(_mm256_mul_ps(_mm256_set1_ps(a[2]), xf), _mm256_set1_ps(c[2]));
        let ok_w = _mm256_cmp_ps::<_CMP_GT_OQ>(w, _mm256_set1_ps(1e-12));
        let iw = _mm256_div_ps(_mm256_set1_ps(1.0), w);
        let sx = _mm256_mul_ps(_mm256_add_ps(_mm256_mul_ps(_mm256_set1_ps(a[0]), xf), _mm256_set1_ps(c[0])), iw);
        let sy = _mm256_mul_ps(_mm256_add_ps(_mm256_mul_ps(_mm256_set1_ps(a[1]), xf), _mm256_set1_ps(c[1])), iw);
        (sx, sy, ok_w)
    }

    /// Spread the 8 bits of a movemask into 8 bytes of 0/1 (a `bool` is one byte, 0 or 1).
    const fn spread_table() -> [u64; 256] {
        let mut t = [0u64; 256];
        let mut i = 0;
        while i < 256 {
            let mut k = 0;
            while k < 8 {
                if (i >> k) & 1 == 1 {
                    t[i] |= 1u64 << (8 * k);
                }
                k += 1;
            }
            i += 1;
        }
        t
    }
    static SPREAD: [u64; 256] = spread_table();

    #[inline(always)]
    unsafe fn store_mask(ok: __m256, m: &mut [bool]) {
        let bits = _mm256_movemask_ps(ok) as usize & 0xff;
        let bytes = SPREAD[bits].to_le_bytes();
        assert!(m.len() >= 8);
        // SAFETY: each byte is 0 or 1, valid bool representations; 8 bytes are in bounds.
        std::ptr::copy_nonoverlapping(bytes.as_ptr(), m.as_mut_ptr() as *mut u8, 8);
    }

    /// Nearest f32 row; pixels in `span` skip the bounds tests (see `super::safe_span`).
    /// Writes every element of `orow` and `mrow`.
    #[target_feature(enable = "avx2")]
    #[allow(clippy::too_many_arguments)]
    pub unsafe fn nearest_f32(
        a: [f32; 3],
        c: [f32; 3],
        data: &[f32],
        w: usize,
        h: usize,
        fill: f32,
        span: (usize, usize),
        orow: &mut [MaybeUninit<f32>],
        mrow: &mut [MaybeUninit<bool>],
    ) {
        let n = orow.len().min(mrow.len());
        let (wf, hf) = (_mm256_set1_ps(w as f32 - 0.5), _mm256_set1_ps(h as f32 - 0.5));
        let (wm1, hm1, wi) =
            (_mm256_set1_epi32(w as i32 - 1), _mm256_set1_epi32(h as i32 - 1), _mm256_set1_epi32(w as i32));
        let half = _mm256_set1_ps(0.5);
        let mhalf = _mm256_set1_ps(-0.5);
        let vfill = _mm256_set1_ps(fill);
        let iota = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
        let (va0, va1, va2) = (_mm256_set1_ps(a[0]), _mm256_set1_ps(a[1]), _mm256_set1_ps(a[2]));
        let (vc0, vc1, vc2) = (_mm256_set1_ps(c[0]), _mm256_set1_ps(c[1]), _mm256_set1_ps(c[2]));
        let (eps, one) = (_mm256_set1_ps(1e-12), _mm256_set1_ps(1.0));
        let (absm, inf) = (_mm256_set1_epi32(0x7fff_ffff), _mm256_set1_epi32(0x7f80_0000));
        let (optr, mptr, dptr) = (orow.as_mut_ptr() as *mut f32, mrow.as_mut_ptr() as *mut u8, data.as_ptr());
        let (xs, xe) = (span.0, span.1.min(n));
        // Same operations as `coords` / `homography_row_body`, for the 8 pixels from `x`.
        let coords_xi = |xi: __m256i| {
            let xf = _mm256_cvtepi32_ps(xi);
            let ww = _mm256_add_ps(_mm256_mul_ps(va2, xf), vc2);
            let iw = _mm256_div_ps(one, ww);
            let sx = _mm256_mul_ps(_mm256_add_ps(_mm256_mul_ps(va0, xf), vc0), iw);
            let sy = _mm256_mul_ps(_mm256_add_ps(_mm256_mul_ps(va1, xf), vc1), iw);
            (sx, sy, ww)
        };
        let coords = |x: usize| coords_xi(_mm256_add_epi32(_mm256_set1_epi32(x as i32), iota));
        // Finite test, store of the value (or `fill`) and of the mask bytes.
        let finish = |x: usize, v: __m256, ok: __m256| {
            let finite = _mm256_castsi256_ps(_mm256_cmpgt_epi32(inf, _mm256_and_si256(_mm256_castps_si256(v), absm)));
            let ok = _mm256_and_ps(ok, finite);
            // SAFETY: x + 8 <= n <= orow.len(), mrow.len(); the mask bytes are 0 or 1 (valid bools).
            _mm256_storeu_ps(optr.add(x), _mm256_blendv_ps(vfill, v, ok));
            let bits = _mm256_movemask_ps(ok) as u32 as usize;
            std::ptr::write_unaligned(mptr.add(x) as *mut u64, SPREAD[bits & 0xff]);
        };
        // General block: bounds tests, clamps, masked gather.
        let checked = |x: usize| {
            let (sx, sy, ww) = coords(x);
            let ok_w = _mm256_cmp_ps::<_CMP_GT_OQ>(ww, eps);
            let inb = _mm256_and_ps(
                _mm256_and_ps(_mm256_cmp_ps::<_CMP_GE_OQ>(sx, mhalf), _mm256_cmp_ps::<_CMP_GE_OQ>(sy, mhalf)),
                _mm256_and_ps(_mm256_cmp_ps::<_CMP_LT_OQ>(sx, wf), _mm256_cmp_ps::<_CMP_LT_OQ>(sy, hf)),
            );
            let inb = _mm256_and_ps(inb, ok_w);
            let ix = _mm256_min_epi32(_mm256_cvttps_epi32(_mm256_add_ps(sx, half)), wm1);
            let iy = _mm256_min_epi32(_mm256_cvttps_epi32(_mm256_add_ps(sy, half)), hm1);
            let idx = _mm256_add_epi32(_mm256_mullo_epi32(iy, wi), ix);
            let idx = _mm256_and_si256(idx, _mm256_castps_si256(inb));
            // Run test: when idx[k] == idx[0] + k for every lane, one unaligned load replaces
            // the gather. Lanes outside the image have idx 0 and then cannot pass for k > 0
            // (idx[0] >= 0), so idx[7] = idx[0] + 7 is an in-bounds index; an outside lane 0
            // reads data[0], which the `ok` mask replaces by `fill` as the masked gather would.
            let idx0 = _mm256_broadcastd_epi32(_mm256_castsi256_si128(idx));
            let run = _mm256_cmpeq_epi32(idx, _mm256_add_epi32(idx0, iota));
            let v = if _mm256_movemask_ps(_mm256_castsi256_ps(run)) == 0xff {
                // SAFETY: idx[0] + 7 = idx[7] < w * h = data.len() (see above).
                _mm256_loadu_ps(dptr.add(_mm256_cvtsi256_si32(idx) as u32 as usize))
            } else {
                // SAFETY: lanes outside `inb` are not loaded; the others are < w * h.
                _mm256_mask_i32gather_ps::<4>(vfill, dptr, idx, inb)
            };
            finish(x, v, inb);
        };
        let mut x = 0;
        while x + 8 <= n && x < xs {
            checked(x);
            x += 8;
        }
        // Inside the safe span every lane is in bounds with ix <= w − 1, iy <= h − 1 and a
        // positive denominator: the tests of `checked` would all pass and its clamps are no-ops.
        let mut xi = _mm256_add_epi32(_mm256_set1_epi32(x as i32), iota);
        let eight = _mm256_set1_epi32(8);
        while x + 8 <= xe {
            let (sx, sy, _) = coords_xi(xi);
            xi = _mm256_add_epi32(xi, eight);
            let ix = _mm256_cvttps_epi32(_mm256_add_ps(sx, half));
            let iy = _mm256_cvttps_epi32(_mm256_add_ps(sy, half));
            let idx = _mm256_add_epi32(_mm256_mullo_epi32(iy, wi), ix);
            let idx0 = _mm256_broadcastd_epi32(_mm256_castsi256_si128(idx));
            let run = _mm256_cmpeq_epi32(idx, _mm256_add_epi32(idx0, iota));
            let v = if _mm256_movemask_ps(_mm256_castsi256_ps(run)) == 0xff {
                // SAFETY: idx[0] + 7 = idx[7] < w * h = data.len().
                _mm256_loadu_ps(dptr.add(_mm256_cvtsi256_si32(idx) as u32 as usize))
            } else {
                // SAFETY: every lane's index is < w * h.
                _mm256_i32gather_ps::<4>(dptr, idx)
            };
            let finite = _mm256_castsi256_ps(_mm256_cmpgt_epi32(inf, _mm256_and_si256(_mm256_castps_si256(v), absm)));
            // SAFETY: as in `finish`.
            _mm256_storeu_ps(optr.add(x), _mm256_blendv_ps(vfill, v, finite));
            let bits = _mm256_movemask_ps(finite) as u32 as usize;
            std::ptr::write_unaligned(mptr.add(x) as *mut u64, SPREAD[bits & 0xff]);
            x += 8;
        }
        while x + 8 <= n {
            checked(x);
            x += 8;
        }
        if x < n {
            let m = n - x;
            let (mut sx, mut sy) = ([0f32; 8], [0f32; 8]);
            // Exactly the vector path's arithmetic (xf = x + k).
            for k in 0..m {
                let xf = (x + k) as i32 as f32;
                let ww = a[2] * xf + c[2];
                let iw = if ww > 1e-12 { 1.0 / ww } else { f32::NAN };
                sx[k] = (a[0] * xf + c[0]) * iw;
                sy[k] = (a[1] * xf + c[1]) * iw;
            }
            let (mut o, mut mk) = ([0f32; 8], [false; 8]);
            super::nearest_row_f32(data, w, h, fill, &sx[..m], &sy[..m], &mut o[..m], &mut mk[..m]);
            for k in 0..m {
                orow[x + k].write(o[k]);
                mrow[x + k].write(mk[k]);
            }
        }
    }

    #[target_feature(enable = "avx2")]
    pub unsafe fn bilinear_rgb(
        a: [f32; 3],
        c: [f32; 3],
        data: &[u8],
        w: usize,
        h: usize,
        orow: &mut [u8],
        mrow: &mut [bool],
    ) {
        let n = mrow.len();
        let (xmax, ymax) = (_mm256_set1_ps((w - 1) as f32), _mm256_set1_ps((h - 1) as f32));
        let (wm2, hm2) = (_mm256_set1_epi32(w as i32 - 2), _mm256_set1_epi32(h as i32 - 2));
        let stride = (w * 3) as i32;
        let vstride = _mm256_set1_epi32(stride);
        let three = _mm256_set1_epi32(3);
        let zero = _mm256_setzero_ps();
        let last_ok = _mm256_set1_epi32(data.len() as i32 - 4 - stride - 3);
        let ff = _mm256_set1_epi32(0xff);
        let half = _mm256_set1_ps(0.5);
        // Shuffle packing each 128-bit lane's four RGBx pixels into 12 bytes.
        let pack = _mm256_setr_epi8(
            0, 1, 2, 4, 5, 6, 8, 9, 10, 12, 13, 14, -1, -1, -1, -1, 0, 1, 2, 4, 5, 6, 8, 9, 10, 12, 13, 14, -1, -1, -1,
            -1,
        );
        let mut x = 0;
        while x + 8 <= n {
            let (sx, sy, ok_w) = coords(a, c, x);
            let inb = _mm256_and_ps(
                _mm256_and_ps(_mm256_cmp_ps::<_CMP_GE_OQ>(sx, zero), _mm256_cmp_ps::<_CMP_GE_OQ>(sy, zero)),
                _mm256_and_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(sx, xmax), _mm256_cmp_ps::<_CMP_LE_OQ>(sy, ymax)),
            );
            let inb = _mm256_and_ps(inb, ok_w);
            let x0 = _mm256_min_epi32(_mm256_cvttps_epi32(sx), wm2);
            let y0 = _mm256_min_epi32(_mm256_cvttps_epi32(sy), hm2);
            let ax = _mm256_sub_ps(sx, _mm256_cvtepi32_ps(x0));
            let ay = _mm256_sub_ps(sy, _mm256_cvtepi32_ps(y0));
            let i00 = _mm256_add_epi32(_mm256_mullo_epi32(y0, vstride), _mm256_mullo_epi32(x0, three));
            let i00 = _mm256_and_si256(i00, _mm256_castps_si256(inb));
            // Lanes whose 4-byte loads would pass the end of the buffer go to the scalar path.
            let tail = _mm256_and_si256(_mm256_cmpgt_epi32(i00, last_ok), _mm256_castps_si256(inb));
            if _mm256_testz_si256(tail, tail) == 0 {
                scalar_px(a, c, data, w, h, x, 8, orow, mrow);
                x += 8;
                continue;
            }
            let m = _mm256_castps_si256(inb);
            let z = _mm256_setzero_si256();
            let base = data.as_ptr() as *const i32;
            let p00 = _mm256_mask_i32gather_epi32::<1>(z, base, i00, m);
            let p10 = _mm256_mask_i32gather_epi32::<1>(z, base, _mm256_add_epi32(i00, three), m);
            let i01 = _mm256_add_epi32(i00, vstride);
            let p01 = _mm256_mask_i32gather_epi32::<1>(z, base, i01, m);
            let p11 = _mm256_mask_i32gather_epi32::<1>(z, base, _mm256_add_epi32(i01, three), m);
            let mut packed = z;
            // Channel by channel: same f32 operations as the scalar lerp.
            macro_rules! chan {
                ($sh:literal) => {{
                    let g = |p: __m256i| _mm256_cvtepi32_ps(_mm256_and_si256(_mm256_srli_epi32::<$sh>(p), ff));
                    let (q00, q10, q01, q11) = (g(p00), g(p10), g(p01), g(p11));
                    let top = _mm256_add_ps(q00, _mm256_mul_ps(ax, _mm256_sub_ps(q10, q00)));
                    let bot = _mm256_add_ps(q01, _mm256_mul_ps(ax, _mm256_sub_ps(q11, q01)));
                    let v = _mm256_add_ps(_mm256_add_ps(top, _mm256_mul_ps(ay, _mm256_sub_ps(bot, top))), half);
                    packed = _mm256_or_si256(packed, _mm256_slli_epi32::<$sh>(_mm256_cvttps_epi32(v)));
                }};
            }
            chan!(0);
            chan!(8);
            chan!(16);
            let packed = _mm256_and_si256(packed, m);
            let bytes = _mm256_shuffle_epi8(packed, pack);
            let mut tmp = [0u8; 32];
            _mm256_storeu_si256(tmp.as_mut_ptr() as *mut __m256i, bytes);
            let o = &mut orow[x * 3..x * 3 + 24];
            o[..12].copy_from_slice(&tmp[..12]);
            o[12..].copy_from_slice(&tmp[16..28]);
            store_mask(inb, &mut mrow[x..x + 8]);
            x += 8;
        }
        if x < n {
            scalar_px(a, c, data, w, h, x, n - x, orow, mrow);
        }
    }

    /// Scalar fallback for `count` pixels from `x` (identical arithmetic).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    unsafe fn scalar_px(
        a: [f32; 3],
        c: [f32; 3],
        data: &[u8],
        w: usize,
        h: usize,
        x: usize,
        count: usize,
        orow: &mut [u8],
        mrow: &mut [bool],
    ) {
        let (mut sx, mut sy) = ([0f32; 8], [0f32; 8]);
        for k in 0..count {
            let xf = (x + k) as i32 as f32;
            let ww = a[2] * xf + c[2];
            let iw = if ww > 1e-12 { 1.0 / ww } else { f32::NAN };
            sx[k] = (a[0] * xf + c[0]) * iw;
            sy[k] = (a[1] * xf + c[1]) * iw;
        }
        super::bilinear_row::<3>(
            data,
            w,
            h,
            &sx[..count],
            &sy[..count],
            &mut orow[x * 3..(x + count) * 3],
            &mut mrow[x..x + count],
        );
    }
}
