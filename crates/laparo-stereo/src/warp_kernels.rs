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

/// Fused homography + nearest f32 row (AVX2 gathers); writes every pixel. Returns false without AVX2.
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
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") && data.len() < i32::MAX as usize {
            assert!(data.len() == w * h && orow.len() == mrow.len());
            // SAFETY: AVX2 checked; sizes asserted; gathers are masked to in-bounds lanes.
            unsafe { avx2::nearest_f32(a, c, data, w, h, fill, orow, mrow) };
            return true;
        }
    }
    let _ = (a, c, data, w, h, fill, orow, mrow);
    false
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use std::arch::x86_64::*;

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

    #[target_feature(enable = "avx2")]
    #[allow(clippy::too_many_arguments)]
    pub unsafe fn nearest_f32(
        a: [f32; 3],
        c: [f32; 3],
        data: &[f32],
        w: usize,
        h: usize,
        fill: f32,
        orow: &mut [f32],
        mrow: &mut [bool],
    ) {
        let n = orow.len();
        let (wf, hf) = (_mm256_set1_ps(w as f32 - 0.5), _mm256_set1_ps(h as f32 - 0.5));
        let (wm1, hm1, wi) =
            (_mm256_set1_epi32(w as i32 - 1), _mm256_set1_epi32(h as i32 - 1), _mm256_set1_epi32(w as i32));
        let half = _mm256_set1_ps(0.5);
        let mhalf = _mm256_set1_ps(-0.5);
        let vfill = _mm256_set1_ps(fill);
        let mut x = 0;
        while x + 8 <= n {
            let (sx, sy, ok_w) = coords(a, c, x);
            let inb = _mm256_and_ps(
                _mm256_and_ps(_mm256_cmp_ps::<_CMP_GE_OQ>(sx, mhalf), _mm256_cmp_ps::<_CMP_GE_OQ>(sy, mhalf)),
                _mm256_and_ps(_mm256_cmp_ps::<_CMP_LT_OQ>(sx, wf), _mm256_cmp_ps::<_CMP_LT_OQ>(sy, hf)),
            );
            let inb = _mm256_and_ps(inb, ok_w);
            let ix = _mm256_min_epi32(_mm256_cvttps_epi32(_mm256_add_ps(sx, half)), wm1);
            let iy = _mm256_min_epi32(_mm256_cvttps_epi32(_mm256_add_ps(sy, half)), hm1);
            let idx = _mm256_add_epi32(_mm256_mullo_epi32(iy, wi), ix);
            let idx = _mm256_and_si256(idx, _mm256_castps_si256(inb));
            let fill = vfill;
            let v = _mm256_mask_i32gather_ps::<4>(fill, data.as_ptr(), idx, inb);
            let abs = _mm256_and_si256(_mm256_castps_si256(v), _mm256_set1_epi32(0x7fff_ffff));
            let finite = _mm256_cmpgt_epi32(_mm256_set1_epi32(0x7f80_0000), abs);
            let ok = _mm256_and_ps(inb, _mm256_castsi256_ps(finite));
            _mm256_storeu_ps(orow.as_mut_ptr().add(x), _mm256_blendv_ps(fill, v, ok));
            store_mask(ok, &mut mrow[x..x + 8]);
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
            super::nearest_row_f32(data, w, h, fill, &sx[..m], &sy[..m], &mut orow[x..], &mut mrow[x..]);
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
