//! x86-64 SIMD paths of the sampler, each bitwise equal to the scalar kernels of `kernel.rs`
//! (same f32 operations in the same order, no FMA contraction):
//! - `bilerp4`: one RGB(A) u8 pixel at once (SSE2, part of the x86-64 baseline);
//! - `homography_bilinear_rgb`: fused homography + bilinear RGB u8 rows, 8 pixels per step
//!   (AVX2 gathers, chosen at run time);
//! - `homography_nearest_f32`: fused homography + nearest 1-channel f32 rows (AVX2);
//! - `homography_bicubic_gray`: fused homography + bicubic grey u8 rows (AVX2: one 32-bit gather
//!   holds a source row's 4 taps).
//!
//! Nothing here needs AVX-512.
use std::arch::x86_64::*;
use std::mem::MaybeUninit;

/// Whether the CPU has AVX2 (the detection macro caches its answer).
#[inline]
pub fn available() -> bool {
    std::arch::is_x86_feature_detected!("avx2")
}

/// Bilinear interpolation of 4 consecutive bytes at once (SSE2); writes `o.len()` (3 or 4)
/// bytes. Same f32 operations as the scalar path: lerp(lerp(p00, p10, ax), lerp(p01, p11, ax), ay),
/// then v + 0.5 truncated.
///
/// # Safety
/// The four 4-byte reads at `i00`, `i00 + dx`, `i00 + dy`, `i00 + dy + dx` must be in bounds.
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

/// Coordinates of the 8 pixels `xi` (i32 lanes): the operations of `kernel::homography_px`;
/// returns (x_s, y_s, denominator).
#[inline(always)]
unsafe fn coords_xi(a: [f32; 3], c: [f32; 3], xi: __m256i) -> (__m256, __m256, __m256) {
    let xf = _mm256_cvtepi32_ps(xi);
    let w = _mm256_add_ps(_mm256_mul_ps(_mm256_set1_ps(a[2]), xf), _mm256_set1_ps(c[2]));
    let iw = _mm256_div_ps(_mm256_set1_ps(1.0), w);
    let sx = _mm256_mul_ps(_mm256_add_ps(_mm256_mul_ps(_mm256_set1_ps(a[0]), xf), _mm256_set1_ps(c[0])), iw);
    let sy = _mm256_mul_ps(_mm256_add_ps(_mm256_mul_ps(_mm256_set1_ps(a[1]), xf), _mm256_set1_ps(c[1])), iw);
    (sx, sy, w)
}

/// [`coords_xi`] for the 8 consecutive pixels from `x0`.
#[inline(always)]
unsafe fn coords(a: [f32; 3], c: [f32; 3], x0: usize) -> (__m256, __m256, __m256) {
    coords_xi(a, c, _mm256_add_epi32(_mm256_set1_epi32(x0 as i32), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7)))
}

/// Nearest 1-channel f32 row of a homography warp; pixels in `span` (see
/// `kernel::safe_span`) skip the bounds tests. Writes every element of `orow` and `mrow`.
///
/// # Safety
/// AVX2 must be available; `data.len() == w * h < i32::MAX`; `orow.len() == mrow.len()`.
#[target_feature(enable = "avx2")]
#[allow(clippy::too_many_arguments)]
pub unsafe fn homography_nearest_f32(
    a: [f32; 3],
    c: [f32; 3],
    data: &[f32],
    w: usize,
    h: usize,
    fill: f32,
    orow: &mut [MaybeUninit<f32>],
    mrow: &mut [MaybeUninit<bool>],
) {
    let n = orow.len().min(mrow.len());
    let span = super::kernel::safe_span(a, c, w, h, n);
    let (wf, hf) = (_mm256_set1_ps(w as f32 - 0.5), _mm256_set1_ps(h as f32 - 0.5));
    let (wm1, hm1, wi) =
        (_mm256_set1_epi32(w as i32 - 1), _mm256_set1_epi32(h as i32 - 1), _mm256_set1_epi32(w as i32));
    let half = _mm256_set1_ps(0.5);
    let mhalf = _mm256_set1_ps(-0.5);
    let vfill = _mm256_set1_ps(fill);
    let iota = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    let eps = _mm256_set1_ps(1e-12);
    let (absm, inf) = (_mm256_set1_epi32(0x7fff_ffff), _mm256_set1_epi32(0x7f80_0000));
    let (optr, mptr, dptr) = (orow.as_mut_ptr() as *mut f32, mrow.as_mut_ptr() as *mut u8, data.as_ptr());
    let (xs, xe) = (span.0, span.1.min(n));
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
        let (sx, sy, ww) = coords(a, c, x);
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
        let (sx, sy, _) = coords_xi(a, c, xi);
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
        for k in 0..m {
            (sx[k], sy[k]) = super::kernel::homography_px(a, c, (x + k) as i32 as f32);
        }
        let (mut o, mut mk) = ([0f32; 8], [false; 8]);
        super::kernel::nearest_row::<f32, 1>(data, w, h, 1, fill, &sx[..m], &sy[..m], &mut o[..m], &mut mk[..m]);
        for k in 0..m {
            orow[x + k].write(o[k]);
            mrow[x + k].write(mk[k]);
        }
    }
}

/// Fused homography + bilinear RGB u8 row, 8 pixels per step (AVX2 gathers). Invalid pixels get
/// `fill` in every channel. Writes every element of `orow` (3 per pixel) and `mrow`.
///
/// # Safety
/// AVX2 must be available; `data.len() == w * h * 3 < i32::MAX`, `w, h >= 2`,
/// `orow.len() == 3 * mrow.len()`.
#[target_feature(enable = "avx2")]
#[allow(clippy::too_many_arguments)]
pub unsafe fn homography_bilinear_rgb(
    a: [f32; 3],
    c: [f32; 3],
    data: &[u8],
    w: usize,
    h: usize,
    fill: u8,
    orow: &mut [MaybeUninit<u8>],
    mrow: &mut [MaybeUninit<bool>],
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
    let fillword = _mm256_set1_epi32(fill as i32 * 0x01_01_01);
    // Shuffle packing each 128-bit lane's four RGBx pixels into 12 bytes.
    let pack = _mm256_setr_epi8(
        0, 1, 2, 4, 5, 6, 8, 9, 10, 12, 13, 14, -1, -1, -1, -1, 0, 1, 2, 4, 5, 6, 8, 9, 10, 12, 13, 14, -1, -1, -1, -1,
    );
    let (optr, mptr) = (orow.as_mut_ptr() as *mut u8, mrow.as_mut_ptr() as *mut u8);
    let mut x = 0;
    while x + 8 <= n {
        let (sx, sy, ww) = coords(a, c, x);
        let ok_w = _mm256_cmp_ps::<_CMP_GT_OQ>(ww, _mm256_set1_ps(1e-12));
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
            scalar_px(a, c, data, w, h, fill, x, 8, optr, mptr);
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
        let packed = _mm256_or_si256(_mm256_and_si256(packed, m), _mm256_andnot_si256(m, fillword));
        let bytes = _mm256_shuffle_epi8(packed, pack);
        let mut tmp = [0u8; 32];
        _mm256_storeu_si256(tmp.as_mut_ptr() as *mut __m256i, bytes);
        // SAFETY: x + 8 <= n, so bytes 3x .. 3x + 24 of `orow` and 8 of `mrow` are in bounds.
        std::ptr::copy_nonoverlapping(tmp.as_ptr(), optr.add(x * 3), 12);
        std::ptr::copy_nonoverlapping(tmp.as_ptr().add(16), optr.add(x * 3 + 12), 12);
        let bits = _mm256_movemask_ps(inb) as usize & 0xff;
        std::ptr::write_unaligned(mptr.add(x) as *mut u64, SPREAD[bits]);
        x += 8;
    }
    if x < n {
        scalar_px(a, c, data, w, h, fill, x, n - x, optr, mptr);
    }
}

/// Scalar path for `count` (<= 8) pixels from `x`: the kernels of `kernel.rs`.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
unsafe fn scalar_px(
    a: [f32; 3],
    c: [f32; 3],
    data: &[u8],
    w: usize,
    h: usize,
    fill: u8,
    x: usize,
    count: usize,
    optr: *mut u8,
    mptr: *mut u8,
) {
    let (mut sx, mut sy) = ([0f32; 8], [0f32; 8]);
    for k in 0..count {
        (sx[k], sy[k]) = super::kernel::homography_px(a, c, (x + k) as i32 as f32);
    }
    let (mut o, mut m) = ([0u8; 24], [false; 8]);
    super::kernel::bilinear_row::<u8, 3>(
        data,
        w,
        h,
        3,
        fill,
        &sx[..count],
        &sy[..count],
        &mut o[..count * 3],
        &mut m[..count],
    );
    // SAFETY: the caller guarantees x + count <= n (3 bytes per pixel of `orow`).
    std::ptr::copy_nonoverlapping(o.as_ptr(), optr.add(x * 3), count * 3);
    std::ptr::copy_nonoverlapping(m.as_ptr() as *const u8, mptr.add(x), count);
}

/// [`super::lerp`]`::<f64>(a, b, t, true)` on four lanes: `a + t (b − a)`, with a weight of
/// exactly 0 or 1 returning `a` or `b` untouched (float texels' exact ends).
#[inline(always)]
unsafe fn lerp_pd(a: __m256d, b: __m256d, t: __m256d) -> __m256d {
    let r = _mm256_add_pd(a, _mm256_mul_pd(t, _mm256_sub_pd(b, a)));
    let r = _mm256_blendv_pd(r, b, _mm256_cmp_pd::<_CMP_EQ_OQ>(t, _mm256_set1_pd(1.0)));
    _mm256_blendv_pd(r, a, _mm256_cmp_pd::<_CMP_EQ_OQ>(t, _mm256_setzero_pd()))
}

/// [`super::bilerp`]`::<f64>(.., true)` on four lanes, bitwise equal to the scalar kernel
/// lane by lane: `lerp(lerp(p00, p10, ax), lerp(p01, p11, ax), ay)`.
///
/// # Safety
/// The CPU must support AVX (callers inside `#[target_feature(enable = "avx2")]` functions).
#[inline(always)]
pub unsafe fn bilerp_pd(p00: __m256d, p10: __m256d, p01: __m256d, p11: __m256d, ax: __m256d, ay: __m256d) -> __m256d {
    lerp_pd(lerp_pd(p00, p10, ax), lerp_pd(p01, p11, ax), ay)
}

/// Keys' weights (a = −½) of 4 f64 lanes, the operations of `kernel::cubic_weights` in the same
/// order, rounded to f32 (as `f64 as f32`).
#[inline(always)]
unsafe fn cubic_weights_pd(t: __m256d) -> [__m128; 4] {
    let s = _mm256_set1_pd;
    let (m, a) = (_mm256_mul_pd, _mm256_add_pd);
    let sub = _mm256_sub_pd;
    let w0 = m(sub(m(a(m(s(-0.5), t), s(1.0)), t), s(0.5)), t);
    let w1 = a(m(m(sub(m(s(1.5), t), s(2.5)), t), t), s(1.0));
    let w2 = m(a(m(a(m(s(-1.5), t), s(2.0)), t), s(0.5)), t);
    let w3 = m(m(sub(m(s(0.5), t), s(0.5)), t), t);
    [_mm256_cvtpd_ps(w0), _mm256_cvtpd_ps(w1), _mm256_cvtpd_ps(w2), _mm256_cvtpd_ps(w3)]
}

/// The 4 weights of 8 f32 lanes (fraction t = s − ⌊s⌋ in f64, exact).
#[inline(always)]
unsafe fn cubic_weights_8(s: __m256, i: __m256i) -> [__m256; 4] {
    let lo = _mm256_sub_pd(_mm256_cvtps_pd(_mm256_castps256_ps128(s)), _mm256_cvtepi32_pd(_mm256_castsi256_si128(i)));
    let hi = _mm256_sub_pd(
        _mm256_cvtps_pd(_mm256_extractf128_ps::<1>(s)),
        _mm256_cvtepi32_pd(_mm256_extracti128_si256::<1>(i)),
    );
    let (l, h) = (cubic_weights_pd(lo), cubic_weights_pd(hi));
    [0, 1, 2, 3].map(|k| _mm256_set_m128(h[k], l[k]))
}

/// Fused homography + bicubic 1-channel u8 row, 8 pixels per step: blocks whose 8 source
/// positions all have their 4×4 neighbourhood inside the image gather one 32-bit word (the 4 taps)
/// per source row; the others, and the tail, take the scalar kernel. Bitwise equal to
/// `homography_row` + `kernel::bicubic_row::<u8, 1>`. Writes every element of `orow` and `mrow`.
///
/// # Safety
/// AVX2 must be available; `data.len() == w * h < i32::MAX`, `w, h >= 1`, `orow.len() == mrow.len()`.
#[target_feature(enable = "avx2")]
#[allow(clippy::too_many_arguments)]
pub unsafe fn homography_bicubic_gray(
    a: [f32; 3],
    c: [f32; 3],
    data: &[u8],
    w: usize,
    h: usize,
    fill: u8,
    orow: &mut [MaybeUninit<u8>],
    mrow: &mut [MaybeUninit<bool>],
) {
    let n = orow.len().min(mrow.len());
    let (optr, mptr, dptr) = (orow.as_mut_ptr() as *mut u8, mrow.as_mut_ptr() as *mut u8, data.as_ptr() as *const i32);
    let one = _mm256_set1_epi32(1);
    let (wm2, hm2) = (_mm256_set1_ps(w as f32 - 2.0), _mm256_set1_ps(h as f32 - 2.0));
    let (zero, eps, half) = (_mm256_setzero_ps(), _mm256_set1_ps(1e-12), _mm256_set1_ps(0.5));
    let (wi, ff) = (_mm256_set1_epi32(w as i32), _mm256_set1_epi32(0xff));
    // Scalar block of m pixels from x: the coordinates of `homography_row`, the scalar kernel.
    let mut scalar = |x: usize, m: usize| {
        let (mut sx, mut sy) = ([0f32; 8], [0f32; 8]);
        for k in 0..m {
            (sx[k], sy[k]) = super::kernel::homography_px(a, c, (x + k) as i32 as f32);
        }
        let (mut o, mut mk) = ([0u8; 8], [false; 8]);
        super::kernel::bicubic_row::<u8, 1>(data, w, h, 1, fill, &sx[..m], &sy[..m], &mut o[..m], &mut mk[..m]);
        for k in 0..m {
            orow[x + k].write(o[k]);
            mrow[x + k].write(mk[k]);
        }
    };
    let mut x = 0;
    while x + 8 <= n {
        let (sx, sy, den) = coords(a, c, x);
        // interior: 1 <= s < size − 2 (so 1 <= ⌊s⌋ <= size − 3; NaN fails), denominator > 1e-12; the
        // float tests come first, so ⌊s⌋ is only taken of in-range lanes
        let inside = |v: __m256, hi: __m256| {
            _mm256_and_ps(_mm256_cmp_ps::<_CMP_GE_OQ>(v, _mm256_set1_ps(1.0)), _mm256_cmp_ps::<_CMP_LT_OQ>(v, hi))
        };
        let ok = _mm256_and_ps(_mm256_and_ps(inside(sx, wm2), inside(sy, hm2)), _mm256_cmp_ps::<_CMP_GT_OQ>(den, eps));
        let ok = _mm256_castps_si256(ok);
        if _mm256_movemask_ps(_mm256_castsi256_ps(ok)) != 0xff {
            scalar(x, 8);
            x += 8;
            continue;
        }
        let (ix, iy) = (_mm256_cvttps_epi32(sx), _mm256_cvttps_epi32(sy));
        let wx = cubic_weights_8(sx, ix);
        let wy = cubic_weights_8(sy, iy);
        // byte offset of the first tap of source row ⌊y⌋ − 1
        let mut off = _mm256_sub_epi32(_mm256_add_epi32(_mm256_mullo_epi32(_mm256_sub_epi32(iy, one), wi), ix), one);
        let mut v = zero;
        for wyj in wy {
            // SAFETY: off + 3 <= (⌊y⌋ + 2) w + ⌊x⌋ + 2 <= w h − 1 for interior lanes.
            let g = _mm256_i32gather_epi32::<1>(dptr, off);
            let p = |k: i32| _mm256_cvtepi32_ps(_mm256_and_si256(_mm256_srlv_epi32(g, _mm256_set1_epi32(8 * k)), ff));
            let r = _mm256_add_ps(zero, _mm256_mul_ps(wx[0], p(0)));
            let r = _mm256_add_ps(r, _mm256_mul_ps(wx[1], p(1)));
            let r = _mm256_add_ps(r, _mm256_mul_ps(wx[2], p(2)));
            let r = _mm256_add_ps(r, _mm256_mul_ps(wx[3], p(3)));
            v = _mm256_add_ps(v, _mm256_mul_ps(wyj, r));
            off = _mm256_add_epi32(off, wi);
        }
        // (v + 0.5) truncated, saturated to [0, 255] (as `f32 as u8`)
        let i = _mm256_cvttps_epi32(_mm256_add_ps(v, half));
        let p16 = _mm256_packs_epi32(i, i);
        let p8 = _mm256_packus_epi16(p16, p16);
        let lo = _mm256_cvtsi256_si32(p8) as u32;
        let hi = _mm256_extract_epi32::<4>(p8) as u32;
        // SAFETY: x + 8 <= n; the mask bytes are 1 (valid bools).
        std::ptr::write_unaligned(optr.add(x) as *mut u64, (lo as u64) | ((hi as u64) << 32));
        std::ptr::write_unaligned(mptr.add(x) as *mut u64, SPREAD[0xff]);
        x += 8;
    }
    if x < n {
        scalar(x, n - x);
    }
}
