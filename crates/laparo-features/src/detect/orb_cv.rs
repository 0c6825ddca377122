//! ORB as OpenCV's `cv::ORB` computes it (Rublee et al. 2011; `modules/features2d/src/orb.cpp`):
//! a pyramid (bilinear, factor 1.2), FAST-9 with 3×3 non-maximum suppression on every level,
//! the level's keypoint budget kept by FAST score (2×) then Harris score (eq. of Harris &
//! Stephens, 7×7 Sobel window, k = 0.04), the intensity-centroid orientation (radius 15) and
//! the steered BRIEF test on the level blurred by a 7×7 Gaussian (σ = 2).
use laparo_core::image::Image;
use rayon::prelude::*;

use super::lowe::blur::{accumulate, separable_blur_rows, Plane};
use super::orb::OrbParams;
use super::orb_pattern::BIT_PATTERN_31;
use crate::keypoint::{Descriptors, Features, Keypoint};

/// Keypoints closer than this to a level's border are dropped (OpenCV `edgeThreshold`).
const EDGE: usize = 31;
/// Half of the BRIEF / orientation patch (OpenCV `patchSize` 31).
const HALF_PATCH: i32 = 15;
/// The 16-pixel Bresenham circle of radius 3 (dx, dy), contiguous.
const CIRCLE: [(i32, i32); 16] = [
    (0, 3),
    (1, 3),
    (2, 2),
    (3, 1),
    (3, 0),
    (3, -1),
    (2, -2),
    (1, -3),
    (0, -3),
    (-1, -3),
    (-2, -2),
    (-3, -1),
    (-3, 0),
    (-3, 1),
    (-2, 2),
    (-1, 3),
];

/// Keypoint budget per level: geometric series with ratio 1/scale (OpenCV).
fn per_level(n: usize, levels: usize, scale: f64) -> Vec<usize> {
    let f = 1.0 / scale;
    let mut desired = n as f64 * (1.0 - f) / (1.0 - f.powi(levels as i32));
    let mut out = vec![0; levels];
    let mut sum = 0;
    for o in out.iter_mut().take(levels - 1) {
        *o = desired.round() as usize;
        sum += *o;
        desired *= f;
    }
    out[levels - 1] = n.saturating_sub(sum);
    out
}

/// Bilinear downscale of a pyramid level with OpenCV's `INTER_LINEAR_EXACT` arithmetic, as
/// `cv::ORB` builds its pyramid (`laparo_core::remap::resize_exact_u8`).
fn resize(img: &Image<u8>, w: usize, h: usize) -> Image<u8> {
    laparo_core::remap::resize_exact_u8(img, w, h).expect("pyramid levels are non-empty grey images")
}

/// Offsets of the 16 circle pixels in a row-major image of width `w`.
fn circle_offsets(w: usize) -> [isize; 16] {
    CIRCLE.map(|(dx, dy)| dy as isize * w as isize + dx as isize)
}

/// FAST-9 score of pixel (x, y): the largest t for which 9 contiguous circle pixels are all
/// brighter than p + t or all darker than p − t (0 when not a corner at `thr`).
#[cfg(test)]
fn fast_score(d: &[u8], w: usize, x: usize, y: usize, thr: i32) -> i32 {
    fast_score_at(d, &circle_offsets(w), y * w + x, thr)
}

/// FAST-9 score at linear index `c` (circle offsets `off`): the largest t such that 9
/// contiguous circle pixels all exceed p + t or all fall below p − t; 0 unless above `thr`.
#[inline]
fn fast_score_at(d: &[u8], off: &[isize; 16], c: usize, thr: i32) -> i32 {
    let p = d[c] as i32;
    let mut v = [0i16; 25];
    let (mut bm, mut dm) = (0u32, 0u32);
    for k in 0..16 {
        let e = d[(c as isize + off[k]) as usize] as i32 - p;
        v[k] = e as i16;
        bm |= ((e > thr) as u32) << k;
        dm |= ((e < -thr) as u32) << k;
    }
    // 9 contiguous set bits on the 16-ring (doubled so arcs may wrap).
    let has9 = |m: u32| {
        let mut r = m | (m << 16);
        r &= r >> 1;
        r &= r >> 2;
        r &= r >> 4;
        r &= r >> 1;
        r & 0xFFFF != 0
    };
    if !has9(bm) && !has9(dm) {
        return 0;
    }
    for k in 16..25 {
        v[k] = v[k - 16];
    }
    let s = arc_score(&v);
    if s > thr {
        s
    } else {
        0
    }
}

/// max over the 16 arcs of 9 of max(min e, min −e), e = I − p on the ring (`v` = e doubled to 25
/// entries). SSE2 (x86-64 baseline) as OpenCV's `cornerScore<16>`; integer, so exact.
#[inline(never)]
fn arc_score(v: &[i16; 25]) -> i32 {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: SSE2 is part of the x86-64 baseline; every load reads 8 i16 within `v` (k + 9 + 8 ≤ 25).
    unsafe {
        use std::arch::x86_64::*;
        let ld = |i: usize| _mm_loadu_si128(v.as_ptr().add(i) as *const __m128i);
        let (mut q0, mut q1) = (_mm_set1_epi16(i16::MIN), _mm_set1_epi16(i16::MAX));
        for k in [0usize, 8] {
            // a, b = min, max of e[k+j+1 … k+j+8] in lane j.
            let (mut a, mut b) = (ld(k + 1), ld(k + 1));
            for t in 2..=8 {
                let x = ld(k + t);
                a = _mm_min_epi16(a, x);
                b = _mm_max_epi16(b, x);
            }
            for t in [k, k + 9] {
                let x = ld(t);
                q0 = _mm_max_epi16(q0, _mm_min_epi16(a, x));
                q1 = _mm_min_epi16(q1, _mm_max_epi16(b, x));
            }
        }
        // Bright: max min e = q0; dark: max min(−e) = −min max e = −q1; then the lane maximum.
        let mut q = _mm_max_epi16(q0, _mm_sub_epi16(_mm_setzero_si128(), q1));
        q = _mm_max_epi16(q, _mm_unpackhi_epi64(q, q));
        q = _mm_max_epi16(q, _mm_srli_si128(q, 4));
        q = _mm_max_epi16(q, _mm_srli_si128(q, 2));
        _mm_cvtsi128_si32(q) as i16 as i32
    }
    #[cfg(not(target_arch = "x86_64"))]
    arc_score_scalar(v)
}

/// Portable `arc_score`.
#[cfg_attr(target_arch = "x86_64", allow(dead_code))]
fn arc_score_scalar(v: &[i16; 25]) -> i32 {
    let (mut best_b, mut best_d) = (i32::MIN, i32::MIN);
    for s in 0..16 {
        let w = &v[s..s + 9];
        best_b = best_b.max(w.iter().copied().min().unwrap_or(0) as i32);
        best_d = best_d.max(-(w.iter().copied().max().unwrap_or(0) as i32));
    }
    best_b.max(best_d)
}

/// Arc pre-test of one row, written to vectorise over u8 lanes: `out[k] = 1` where, for pixel
/// x = k + 3, 4 cyclically consecutive of the 8 even circle pixels (0, 2, …, 14) are all brighter
/// than p + t, or all darker than p − t. An arc of 9 contiguous circle pixels always contains 4
/// consecutive even ones, so no FAST-9 corner is rejected. `rows` = rows y − 3 … y + 3.
#[inline(always)]
fn compass_row_impl(rows: [&[u8]; 7], t: u8, out: &mut [u8]) {
    let n = out.len();
    // Even circle pixels k = 0, 2, …, 14: (dx, dy) = (0,3) (2,2) (3,0) (2,−2) (0,−3) (−2,−2) (−3,0) (−2,2).
    let e: [&[u8]; 8] = [
        &rows[6][3..n + 3],
        &rows[5][5..n + 5],
        &rows[3][6..n + 6],
        &rows[1][5..n + 5],
        &rows[0][3..n + 3],
        &rows[1][1..n + 1],
        &rows[3][..n],
        &rows[5][1..n + 1],
    ];
    let mid = &rows[3][3..n + 3];
    let run4 = |b: [u8; 8]| {
        (b[0] & b[1] & b[2] & b[3])
            | (b[1] & b[2] & b[3] & b[4])
            | (b[2] & b[3] & b[4] & b[5])
            | (b[3] & b[4] & b[5] & b[6])
            | (b[4] & b[5] & b[6] & b[7])
            | (b[5] & b[6] & b[7] & b[0])
            | (b[6] & b[7] & b[0] & b[1])
            | (b[7] & b[0] & b[1] & b[2])
    };
    for k in 0..n {
        let p = mid[k];
        let (hi, lo) = (p.saturating_add(t), p.saturating_sub(t));
        let br: [u8; 8] = std::array::from_fn(|j| (e[j][k] > hi) as u8);
        let dk: [u8; 8] = std::array::from_fn(|j| (e[j][k] < lo) as u8);
        out[k] = run4(br) | run4(dk);
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn compass_row_avx2(rows: [&[u8]; 7], t: u8, out: &mut [u8]) {
    compass_row_impl(rows, t, out)
}

/// Runtime-dispatched arc pre-test (integer comparisons: both paths agree exactly).
fn compass_row(rows: [&[u8]; 7], t: u8, out: &mut [u8]) {
    #[cfg(target_arch = "x86_64")]
    if is_x86_feature_detected!("avx2") {
        // SAFETY: AVX2 is present (checked just above).
        unsafe { compass_row_avx2(rows, t, out) };
        return;
    }
    compass_row_impl(rows, t, out)
}

/// FAST-9 corners with 3×3 non-maximum suppression, at least `border` (≥ 4) px from the edges:
/// (x, y, score).
fn fast9(img: &Image<u8>, thr: i32, border: usize) -> Vec<(usize, usize, i32)> {
    let (w, h) = (img.width, img.height);
    let border = border.max(4);
    if w < 2 * border + 1 || h < 2 * border + 1 {
        return vec![];
    }
    let d = &img.data;
    let t = thr.clamp(0, 255) as u8;
    let off = circle_offsets(w);
    // Scores are ≤ 255: one byte each.
    let mut score = vec![0u8; w * h];
    score.par_chunks_mut(w).enumerate().skip(border - 1).take(h - 2 * border + 2).for_each_init(
        || vec![0u8; w - 6],
        |mask, (y, row)| {
            compass_row(std::array::from_fn(|j| &d[(y + j - 3) * w..(y + j - 2) * w]), t, mask);
            for_each_nonzero(mask, |k| row[k + 3] = fast_score_at(d, &off, y * w + k + 3, thr) as u8);
        },
    );
    let mut out = vec![];
    for y in border..h - border {
        let (up, row, dn) = (&score[(y - 1) * w..y * w], &score[y * w..(y + 1) * w], &score[(y + 1) * w..(y + 2) * w]);
        for_each_nonzero(&row[border..w - border], |k| {
            let x = k + border;
            let s = row[x];
            if s > row[x - 1]
                && s > row[x + 1]
                && s > up[x - 1]
                && s > up[x]
                && s > up[x + 1]
                && s > dn[x - 1]
                && s > dn[x]
                && s > dn[x + 1]
            {
                out.push((x, y, s as i32));
            }
        });
    }
    out
}

/// Call `f(i)` for every i with `bytes[i] != 0`, in increasing order, skipping zero 8-byte words.
#[inline]
fn for_each_nonzero(bytes: &[u8], mut f: impl FnMut(usize)) {
    let mut chunks = bytes.chunks_exact(8);
    let mut base = 0;
    for c in &mut chunks {
        let mut word = u64::from_le_bytes(c.try_into().expect("8 bytes"));
        while word != 0 {
            let b = (word.trailing_zeros() / 8) as usize;
            f(base + b);
            word &= !(0xFFu64 << (8 * b));
        }
        base += 8;
    }
    for (i, &v) in chunks.remainder().iter().enumerate() {
        if v != 0 {
            f(base + i);
        }
    }
}

/// Keep the `n` best by score (and every tie with the n-th, as OpenCV's `retainBest`), in a
/// deterministic order (score descending, then row, then column).
fn retain_best<T: Copy>(mut v: Vec<(usize, usize, T)>, n: usize, key: impl Fn(&T) -> f64) -> Vec<(usize, usize, T)> {
    if n > 0 && v.len() > n {
        // Drop everything below the n-th largest key first (linear), then sort the rest.
        let mut keys: Vec<f64> = v.iter().map(|e| key(&e.2)).collect();
        let (_, edge, _) = keys.select_nth_unstable_by(n - 1, |a, b| b.total_cmp(a));
        let edge = *edge;
        v.retain(|e| key(&e.2) >= edge);
    }
    v.sort_by(|a, b| key(&b.2).total_cmp(&key(&a.2)).then(a.1.cmp(&b.1)).then(a.0.cmp(&b.0)));
    if v.len() > n {
        if n == 0 {
            return vec![];
        }
        let edge = key(&v[n - 1].2);
        let mut k = n;
        while k < v.len() && key(&v[k].2) >= edge {
            k += 1;
        }
        v.truncate(k);
    }
    v
}

/// Harris response over a 7×7 window of 3×3 Sobel gradients (OpenCV `HarrisResponses`).
fn harris(img: &Image<u8>, x: usize, y: usize) -> f64 {
    let (w, d) = (img.width, &img.data);
    let px = |x: usize, y: usize| d[y * w + x] as i32;
    let (mut a, mut b, mut c) = (0i64, 0i64, 0i64);
    for yy in y - 3..=y + 3 {
        for xx in x - 3..=x + 3 {
            let ix = (px(xx + 1, yy) - px(xx - 1, yy)) * 2
                + (px(xx + 1, yy - 1) - px(xx - 1, yy - 1))
                + (px(xx + 1, yy + 1) - px(xx - 1, yy + 1));
            let iy = (px(xx, yy + 1) - px(xx, yy - 1)) * 2
                + (px(xx - 1, yy + 1) - px(xx - 1, yy - 1))
                + (px(xx + 1, yy + 1) - px(xx + 1, yy - 1));
            a += (ix * ix) as i64;
            b += (iy * iy) as i64;
            c += (ix * iy) as i64;
        }
    }
    let scale: f64 = 1.0 / (4.0 * 7.0 * 255.0);
    let (a, b, c) = (a as f64, b as f64, c as f64);
    (a * b - c * c - 0.04 * (a + b) * (a + b)) * scale.powi(4)
}

/// Row half-widths of the circular patch of radius 15 (OpenCV `umax`).
fn umax() -> [i32; 16] {
    let hp = HALF_PATCH;
    let mut u = [0i32; 16];
    let vmax = (hp as f64 * 2f64.sqrt() / 2.0 + 1.0).floor() as i32;
    let vmin = (hp as f64 * 2f64.sqrt() / 2.0).ceil() as i32;
    for v in 0..=vmax {
        u[v as usize] = ((hp * hp - v * v) as f64).sqrt().round() as i32;
    }
    let mut v0 = 0usize;
    let mut v = hp;
    while v >= vmin {
        while u[v0] == u[v0 + 1] {
            v0 += 1;
        }
        u[v as usize] = v0 as i32;
        v0 += 1;
        v -= 1;
    }
    u
}

/// Intensity-centroid orientation (rad, from +x towards +y): atan2(m01, m10) over the disc;
/// row pairs ±v summed over slices (i32, vectorises).
fn ic_angle(img: &Image<u8>, x: usize, y: usize, um: &[i32; 16]) -> f64 {
    let (w, d) = (img.width, &img.data);
    let hp = HALF_PATCH as usize;
    let c = y * w + x;
    let (mut m01, mut m10) = (0i32, 0i32);
    let mid = &d[c - hp..=c + hp];
    for (i, &p) in mid.iter().enumerate() {
        m10 += (i as i32 - HALF_PATCH) * p as i32;
    }
    for v in 1..=hp {
        let r = um[v] as usize;
        let n = 2 * r + 1;
        let (lo, hi) = (&d[c + v * w - r..c + v * w - r + n], &d[c - v * w - r..c - v * w - r + n]);
        let (mut vs, mut mu) = (0i32, 0i32);
        for i in 0..n {
            let (p, m) = (lo[i] as i32, hi[i] as i32);
            vs += p - m;
            mu += (i as i32 - r as i32) * (p + m);
        }
        m10 += mu;
        m01 += v as i32 * vs;
    }
    let a = (m01 as f64).atan2(m10 as f64);
    if a < 0.0 {
        a + std::f64::consts::TAU
    } else {
        a
    }
}

/// 7×7 Gaussian blur, σ = 2, border reflect-101 (OpenCV's pre-BRIEF smoothing), through the
/// separable f32 blur of `lowe::blur` (AVX2 by runtime dispatch), rounded half up to u8.
fn blur7(img: &Image<u8>, rows: &[bool]) -> Image<u8> {
    let k: [f32; 4] = {
        let g: [f64; 7] = std::array::from_fn(|i| (-((i as f64 - 3.0).powi(2)) / 8.0).exp());
        let s: f64 = g.iter().sum();
        std::array::from_fn(|i| (g[i + 3] / s) as f32)
    };
    let src = Plane { w: img.width, h: img.height, data: img.data.iter().map(|&v| v as f32).collect() };
    let b = separable_blur_rows(&src, &k, accumulate, Some(rows));
    // 0 ≤ v ≤ 255 (normalised kernel on 8-bit input): adding 1.5·2²³ leaves round-half-even(v)
    // in the low mantissa bits (vectorises, unlike a saturating float → int cast).
    const MAGIC: f32 = 12_582_912.0;
    let data = b.data.iter().map(|&v| (v + MAGIC).to_bits() as u8).collect();
    Image { width: img.width, height: img.height, channels: 1, data }
}

/// Rows within reach of a steered BRIEF test (|rotated offset| ≤ 15·√2 < 22) of a keypoint.
fn brief_rows(h: usize, kps: &[(usize, usize, f64)]) -> Vec<bool> {
    let mut need = vec![false; h];
    for &(_, y, _) in kps {
        for r in need.iter_mut().take((y + 23).min(h)).skip(y.saturating_sub(22)) {
            *r = true;
        }
    }
    need
}

/// `bit_pattern_31` as f32 columns: x₁, y₁, x₂, y₂ of the 256 tests, each point as one row of
/// 512 (first points then second points), so the rotation loop vectorises.
fn pattern_columns() -> ([f32; 512], [f32; 512]) {
    let mut px = [0f32; 512];
    let mut py = [0f32; 512];
    for (i, p) in BIT_PATTERN_31.iter().enumerate() {
        (px[i], py[i], px[i + 256], py[i + 256]) = (p[0] as f32, p[1] as f32, p[2] as f32, p[3] as f32);
    }
    (px, py)
}

/// Steered BRIEF: 256 tests `I(R p1) < I(R p2)` on the blurred level, R = rotation by `angle`
/// (AVX2 by runtime dispatch; same IEEE operations, so the same bits as the portable path).
fn brief(img: &Image<u8>, x: usize, y: usize, angle: f64, pat: &([f32; 512], [f32; 512])) -> [u8; 32] {
    #[cfg(target_arch = "x86_64")]
    if is_x86_feature_detected!("avx2") {
        // SAFETY: AVX2 is present (checked just above).
        return unsafe { brief_avx2(img, x, y, angle, pat) };
    }
    brief_impl(img, x, y, angle, pat)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn brief_avx2(img: &Image<u8>, x: usize, y: usize, angle: f64, pat: &([f32; 512], [f32; 512])) -> [u8; 32] {
    brief_impl(img, x, y, angle, pat)
}

/// The steered BRIEF body.
#[inline(always)]
fn brief_impl(img: &Image<u8>, x: usize, y: usize, angle: f64, pat: &([f32; 512], [f32; 512])) -> [u8; 32] {
    let (a, b) = ((angle as f32).cos(), (angle as f32).sin());
    let w = img.width as i32;
    // cvRound (half to even) by the 1.5·2²³ trick: exact for |v| < 2²², no libm call (SSE2
    // has no round instruction; `round_ties_even` became a call to rintf).
    const MAGIC: f32 = 12_582_912.0;
    // (v + 1.5·2²³) holds 0x4B40_0000 + round(v) in its bits for |v| < 2²²: integer only, so
    // the loop vectorises (a float → int cast needs NaN / range checks).
    let rnd = |v: f32| (v + MAGIC).to_bits() as i32 - 0x4B40_0000;
    let mut off = [0i32; 512];
    for ((o, &px), &py) in off.iter_mut().zip(&pat.0).zip(&pat.1) {
        *o = rnd(px * b + py * a) * w + rnd(px * a - py * b);
    }
    let c = (y * img.width + x) as isize;
    let d = &img.data;
    let mut out = [0u8; 32];
    for (i, byte) in out.iter_mut().enumerate() {
        for k in 0..8 {
            let t = i * 8 + k;
            let (p, q) = (d[(c + off[t] as isize) as usize], d[(c + off[t + 256] as isize) as usize]);
            *byte |= ((p < q) as u8) << k;
        }
    }
    out
}

/// One level: keypoints (level px) with their Harris response, angle and descriptor.
fn level_features(img: &Image<u8>, budget: usize, thr: i32, um: &[i32; 16]) -> Vec<(usize, usize, f64, f64, [u8; 32])> {
    if budget == 0 || img.width <= 2 * EDGE || img.height <= 2 * EDGE {
        return vec![];
    }
    let (w, h) = (img.width, img.height);
    let corners: Vec<_> = fast9(img, thr, EDGE)
        .into_iter()
        .filter(|&(x, y, _)| x >= EDGE && x < w - EDGE && y >= EDGE && y < h - EDGE)
        .collect();
    let corners = retain_best(corners, 2 * budget, |&s| s as f64);
    let scored: Vec<(usize, usize, f64)> = corners.iter().map(|&(x, y, _)| (x, y, harris(img, x, y))).collect();
    let mut best = retain_best(scored, budget, |&r| r);
    best.truncate(budget);
    let blurred = blur7(img, &brief_rows(img.height, &best));
    let pat = pattern_columns();
    best.iter()
        .map(|&(x, y, r)| {
            let a = ic_angle(img, x, y, um);
            (x, y, r, a, brief(&blurred, x, y, a, &pat))
        })
        .collect()
}

/// OpenCV-style ORB on a grey u8 image (parameters checked by the caller).
pub fn detect_and_describe(gray: &Image<u8>, p: &OrbParams) -> Features {
    let scale = p.scale_factor as f64;
    let budgets = per_level(p.n_features, p.n_levels, scale);
    let mut levels = vec![gray.clone()];
    for k in 1..p.n_levels {
        let s = scale.powi(k as i32);
        let (lw, lh) = ((gray.width as f64 / s).round() as usize, (gray.height as f64 / s).round() as usize);
        if lw <= 2 * EDGE || lh <= 2 * EDGE {
            break;
        }
        let next = resize(&levels[k - 1], lw, lh);
        levels.push(next);
    }
    let um = umax();
    let thr = p.fast_threshold.round() as i32;
    let per: Vec<_> = levels.par_iter().enumerate().map(|(k, img)| level_features(img, budgets[k], thr, &um)).collect();
    let mut keypoints = vec![];
    let mut data = vec![];
    for (k, feats) in per.into_iter().enumerate() {
        let s = scale.powi(k as i32);
        for (x, y, r, a, d) in feats {
            keypoints.push(Keypoint {
                x: x as f64 * s,
                y: y as f64 * s,
                size_px: 31.0 * s,
                angle_rad: a,
                response: r,
                octave: k as i32,
            });
            data.extend_from_slice(&d);
        }
    }
    Features { keypoints, descriptors: Descriptors::Binary { bytes: 32, data } }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn level_budgets_sum_to_n() {
        let b = per_level(2000, 8, 1.2);
        assert_eq!(b.iter().sum::<usize>(), 2000);
        assert_eq!(b[0], 434); // 2000 · (1 − 1/1.2) / (1 − 1.2⁻⁸) = 434.35
    }

    #[test]
    fn umax_is_a_disc_of_radius_15() {
        // OpenCV's table for patchSize 31.
        assert_eq!(umax(), [15, 15, 15, 15, 14, 14, 14, 13, 13, 12, 11, 10, 9, 8, 6, 3]);
    }

    #[test]
    fn fast_finds_a_bright_corner_and_not_an_edge() {
        // A bright square on black: its corner at (10, 10) is a FAST corner (arc of ≥ 9 dark
        // circle pixels), a point in the middle of an edge is not.
        let mut img = Image::filled(30, 30, 1, 0u8);
        for y in 10..25 {
            for x in 10..25 {
                img.set(x, y, 0, 200);
            }
        }
        assert!(fast_score(&img.data, 30, 10, 10, 20) > 20);
        assert_eq!(fast_score(&img.data, 30, 17, 10, 20), 0);
        assert_eq!(fast_score(&img.data, 30, 17, 17, 20), 0);
        // Score = the largest threshold still passing: 200 − 0 − 1 would fail at 200.
        assert_eq!(fast_score(&img.data, 30, 10, 10, 20), 200);
    }

    #[test]
    fn sse2_and_scalar_arc_scores_agree() {
        let mut s = 5u32;
        for _ in 0..2000 {
            let mut v = [0i16; 25];
            for e in v.iter_mut().take(16) {
                s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                *e = ((s >> 24) as i16) - 128;
            }
            for k in 16..25 {
                v[k] = v[k - 16];
            }
            assert_eq!(arc_score(&v), arc_score_scalar(&v));
        }
    }

    #[test]
    fn nonzero_scan_visits_exactly_the_nonzero_bytes() {
        let v: Vec<u8> = (0..37).map(|i| if i % 5 == 0 || i == 36 { 1 + i as u8 } else { 0 }).collect();
        let mut seen = vec![];
        for_each_nonzero(&v, |i| seen.push(i));
        assert_eq!(seen, vec![0, 5, 10, 15, 20, 25, 30, 35, 36]);
    }

    #[test]
    fn resize_ramp() {
        // 6 → 5: positions (i + ½)·1.2 − ½ = 0.1, 1.3, 2.5, 3.7, 4.9; a ramp 10·x keeps 10·position
        // (rounded half up).
        let img = Image::from_vec(6, 2, 1, (0..12).map(|i| (i % 6 * 10) as u8).collect()).unwrap();
        let r = resize(&img, 5, 2);
        assert_eq!(&r.data[..5], &[1, 13, 25, 37, 49]);
    }

    #[test]
    fn compass_pretest_never_rejects_a_corner() {
        let mut s = 99u32;
        let data: Vec<u8> = (0..64 * 40)
            .map(|_| {
                s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                (s >> 24) as u8
            })
            .collect();
        let img = Image::from_vec(64, 40, 1, data).unwrap();
        let mut m = vec![0u8; 58];
        let mut m2 = vec![0u8; 58];
        let mut corners = 0;
        for y in 3..37 {
            let d = &img.data;
            let rows: [&[u8]; 7] = std::array::from_fn(|j| &d[(y + j - 3) * 64..(y + j - 2) * 64]);
            compass_row(rows, 20, &mut m);
            compass_row_impl(rows, 20, &mut m2);
            assert_eq!(m, m2);
            for x in 3..61 {
                if fast_score(d, 64, x, y, 20) > 0 {
                    corners += 1;
                    assert_eq!(m[x - 3], 1, "({x}, {y})");
                }
            }
        }
        assert!(corners > 10);
    }

    #[test]
    fn ic_angle_points_to_the_bright_side() {
        // Brightness increasing with x → angle 0; with y → π/2.
        let gx = Image::from_vec(40, 40, 1, (0..1600).map(|i| (i % 40 * 5) as u8).collect()).unwrap();
        let gy = Image::from_vec(40, 40, 1, (0..1600).map(|i| (i / 40 * 5) as u8).collect()).unwrap();
        let um = umax();
        assert!(ic_angle(&gx, 20, 20, &um).min(std::f64::consts::TAU - ic_angle(&gx, 20, 20, &um)) < 1e-9);
        assert!((ic_angle(&gy, 20, 20, &um) - std::f64::consts::FRAC_PI_2).abs() < 1e-9);
    }
}
