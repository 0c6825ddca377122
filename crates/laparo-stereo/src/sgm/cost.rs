//! Matching cost of SGM (Hirschmüller 2008, §3.1 with the census cost of Zabih & Woodfill):
//! a 9×7 census transform (62 bits, centre excluded) and the Hamming distance
//! `C(x, y, d) = min_{|δ| ≤ k} H(c_L(x, y), c_R(x − d, y + δ))` (the vertical tolerance `k` of
//! `--vertical-tol`; `k = 0` is the classical cost). Cells whose right pixel `x − d` lies outside
//! the image get the neutral cost [`NEUTRAL_COST`] (no invalid border strips).
//!
//! Everything is integer arithmetic: the AVX2 build of these loops (compiled with
//! `#[target_feature]`, popcnt) and the portable build give identical bits.

/// Census window width (px).
pub const CENSUS_W: usize = 9;
/// Census window height (px).
pub const CENSUS_H: usize = 7;
/// Number of census bits (window minus centre): the largest Hamming cost.
pub const CENSUS_BITS: u32 = (CENSUS_W * CENSUS_H - 1) as u32;
/// Cost of a cell whose right pixel is outside the image: the expected Hamming distance of two
/// unrelated census strings (half the bits).
pub const NEUTRAL_COST: u8 = (CENSUS_BITS / 2) as u8;

/// 9×7 census transform of a grey image (row-major, `w × h`): bit set when the neighbour is darker
/// than the centre; neighbours outside the image are clamped to the border.
#[cfg(test)]
pub fn census(gray: &[u8], w: usize, h: usize, avx2: bool) -> Vec<u64> {
    let mut out = Vec::new();
    census_into(gray, w, h, avx2, &mut out);
    out
}

/// [`census`] into a reused buffer (resized to `w × h`).
pub fn census_into(gray: &[u8], w: usize, h: usize, avx2: bool, out: &mut Vec<u64>) {
    out.resize(w * h, 0);
    if w == 0 || h == 0 {
        return;
    }
    // Border-replicated copy with margins rx, ry.
    let (rx, ry) = (CENSUS_W / 2, CENSUS_H / 2);
    let pw = w + 2 * rx;
    let mut pad = vec![0u8; pw * (h + 2 * ry)];
    for py in 0..h + 2 * ry {
        let sy = py.saturating_sub(ry).min(h - 1);
        let src = &gray[sy * w..(sy + 1) * w];
        let dst = &mut pad[py * pw..(py + 1) * pw];
        dst[rx..rx + w].copy_from_slice(src);
        for x in 0..rx {
            dst[x] = src[0];
            dst[rx + w + x] = src[w - 1];
        }
    }
    use rayon::prelude::*;
    out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        row.fill(0); // the bits are shifted in
        #[cfg(target_arch = "x86_64")]
        if avx2 {
            // SAFETY: the caller checked AVX2 and popcnt support at run time.
            unsafe { census_row_avx2(&pad, pw, y, w, row) };
            return;
        }
        let _ = avx2;
        census_row(&pad, pw, y, 0, w, row);
    });
}

/// Census of pixels `x0..w` of row `y` into `row[x0..]` (portable).
#[inline(always)]
fn census_row(pad: &[u8], pw: usize, y: usize, x0: usize, w: usize, row: &mut [u64]) {
    let (rx, ry) = (CENSUS_W / 2, CENSUS_H / 2);
    let centre = &pad[(y + ry) * pw + rx + x0..(y + ry) * pw + rx + w];
    for dy in 0..CENSUS_H {
        let nrow = &pad[(y + dy) * pw..(y + dy + 1) * pw];
        for dx in 0..CENSUS_W {
            if dx == rx && dy == ry {
                continue;
            }
            let nb = &nrow[x0 + dx..dx + w];
            for ((o, &c), &n) in row[x0..w].iter_mut().zip(centre).zip(nb) {
                *o = (*o << 1) | u64::from(n < c);
            }
        }
    }
}

/// AVX2 census of row `y`: 32 pixels at a time, one byte plane per 8 census bits (signed
/// compares on sign-flipped bytes, `acc = 2 acc + bit` in the scalar bit order), then an 8×8
/// byte transpose into u64; the remaining pixels go through [`census_row`].
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,popcnt")]
unsafe fn census_row_avx2(pad: &[u8], pw: usize, y: usize, w: usize, row: &mut [u64]) {
    use std::arch::x86_64::*;
    let (rx, ry) = (CENSUS_W / 2, CENSUS_H / 2);
    let flip = _mm256_set1_epi8(-128);
    let mut x0 = 0;
    while x0 + 32 <= w {
        let cp = pad.as_ptr().add((y + ry) * pw + rx + x0);
        let c = _mm256_xor_si256(_mm256_loadu_si256(cp as *const __m256i), flip);
        // planes[b] holds bits 8b..8b+7 of the 62-bit string (neighbour i ↦ bit 61 − i).
        let mut planes = [_mm256_setzero_si256(); 8];
        let mut i = 0usize;
        for dy in 0..CENSUS_H {
            let np = pad.as_ptr().add((y + dy) * pw + x0);
            for dx in 0..CENSUS_W {
                if dx == rx && dy == ry {
                    continue;
                }
                let n = _mm256_xor_si256(_mm256_loadu_si256(np.add(dx) as *const __m256i), flip);
                let bit = _mm256_cmpgt_epi8(c, n); // n < c → 0xFF
                let b = (CENSUS_BITS as usize - 1 - i) / 8;
                let acc = planes[b];
                planes[b] = _mm256_sub_epi8(_mm256_add_epi8(acc, acc), bit);
                i += 1;
            }
        }
        for half in 0..2 {
            let p: [__m128i; 8] = std::array::from_fn(|b| {
                if half == 0 {
                    _mm256_castsi256_si128(planes[b])
                } else {
                    _mm256_extracti128_si256(planes[b], 1)
                }
            });
            let a01 = [_mm_unpacklo_epi8(p[0], p[1]), _mm_unpackhi_epi8(p[0], p[1])];
            let a23 = [_mm_unpacklo_epi8(p[2], p[3]), _mm_unpackhi_epi8(p[2], p[3])];
            let a45 = [_mm_unpacklo_epi8(p[4], p[5]), _mm_unpackhi_epi8(p[4], p[5])];
            let a67 = [_mm_unpacklo_epi8(p[6], p[7]), _mm_unpackhi_epi8(p[6], p[7])];
            let out = row.as_mut_ptr().add(x0 + 16 * half) as *mut __m128i;
            for k in 0..4 {
                let (lo03, lo47) = if k % 2 == 0 {
                    (_mm_unpacklo_epi16(a01[k / 2], a23[k / 2]), _mm_unpacklo_epi16(a45[k / 2], a67[k / 2]))
                } else {
                    (_mm_unpackhi_epi16(a01[k / 2], a23[k / 2]), _mm_unpackhi_epi16(a45[k / 2], a67[k / 2]))
                };
                _mm_storeu_si128(out.add(2 * k), _mm_unpacklo_epi32(lo03, lo47));
                _mm_storeu_si128(out.add(2 * k + 1), _mm_unpackhi_epi32(lo03, lo47));
            }
        }
        x0 += 32;
    }
    census_row(pad, pw, y, x0, w, row)
}

/// Geometry of one cost computation: image width, signed range start, number of disparities
/// `nd`, padded count `ndp` (multiple of 16) and the vertical tolerance rows.
#[derive(Clone, Copy, Debug)]
pub struct CostGeom {
    /// Image width (px).
    pub w: usize,
    /// First disparity (px), any sign.
    pub d_min: i32,
    /// Number of disparities.
    pub nd: usize,
    /// `nd` rounded up to a multiple of 16 (the AVX2 lane count of u16).
    pub ndp: usize,
}

/// Costs of pixel `x` for every disparity into `out[..ndp]` (lanes ≥ nd are set to 0).
/// `cl` is c_L(x, y); `right_rows` are the census rows y + δ, δ ∈ [−k, k] ∩ image.
#[inline(always)]
pub fn pixel_costs(avx2: bool, g: &CostGeom, x: usize, cl: u64, right_rows: &[&[u64]], out: &mut [u8]) {
    let out = &mut out[..g.ndp];
    // d = d_min + i, x_R = x − d ∈ [0, w) ⇔ i ∈ (x − d_min − w, x − d_min].
    let hi = x as i64 - g.d_min as i64; // i ≤ hi
    let lo = hi - g.w as i64 + 1; // i ≥ lo
    let i0 = lo.clamp(0, g.nd as i64) as usize;
    let i1 = (hi + 1).clamp(0, g.nd as i64) as usize;
    // (Guarded: most pixels have no neutral cells, and an empty `fill` is still a memset call.)
    if i0 > 0 {
        out[..i0].fill(NEUTRAL_COST);
    }
    if i1 < g.nd {
        out[i1..g.nd].fill(NEUTRAL_COST);
    }
    if g.nd < g.ndp {
        out[g.nd..].fill(0);
    }
    if i0 >= i1 {
        return;
    }
    // x_R for i is hi − i, decreasing: take the right-row slice [hi − (i1 − 1), hi − i0].
    let xr_lo = (hi - (i1 as i64 - 1)) as usize;
    let n = i1 - i0;
    let dst = &mut out[i0..i1];
    let first = &right_rows[0][xr_lo..xr_lo + n];
    hamming_rev::<false>(avx2, cl, first, dst);
    for rr in &right_rows[1..] {
        hamming_rev::<true>(avx2, cl, &rr[xr_lo..xr_lo + n], dst);
    }
}

/// `dst[t] = H(cl, r[n − 1 − t])` (or its minimum with `dst[t]`, `MIN`), `n = r.len()`.
#[inline(always)]
fn hamming_rev<const MIN: bool>(avx2: bool, cl: u64, r: &[u64], dst: &mut [u8]) {
    let n = r.len();
    let mut done = 0;
    #[cfg(target_arch = "x86_64")]
    if avx2 {
        // SAFETY: `avx2` is only true when AVX2 was detected at run time.
        done = unsafe { hamming_rev_avx2::<MIN>(cl, r, dst) };
    }
    let _ = avx2;
    for t in done..n {
        let c = (cl ^ r[n - 1 - t]).count_ones() as u8;
        dst[t] = if MIN { dst[t].min(c) } else { c };
    }
}

/// AVX2 block of [`hamming_rev`]: popcounts by nibble lookup (exact, so the same bytes as
/// `count_ones`), 16 costs at a time; returns how many leading outputs were written.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn hamming_rev_avx2<const MIN: bool>(cl: u64, r: &[u64], dst: &mut [u8]) -> usize {
    use std::arch::x86_64::*;
    let n = r.len();
    debug_assert!(dst.len() >= n);
    let lut = _mm256_setr_epi8(
        0, 1, 1, 2, 1, 2, 2, 3, 1, 2, 2, 3, 2, 3, 3, 4, 0, 1, 1, 2, 1, 2, 2, 3, 1, 2, 2, 3, 2, 3, 3, 4,
    );
    let low = _mm256_set1_epi8(0x0F);
    let vcl = _mm256_set1_epi64x(cl as i64);
    let zero = _mm256_setzero_si256();
    // Output byte t of a block comes from m = 15 − t (r index R0 + m): m = 4 b + q sits in
    // 64-bit lane q, byte b of the combined vector (lanes 0, 1 low half; 2, 3 high half).
    // (t = 0: m = 15, q = 3, b = 3 → high byte 11; t = 2: m = 13, q = 1, b = 3 → low byte 11; ...)
    let ml = _mm_setr_epi8(-1, -1, 11, 3, -1, -1, 10, 2, -1, -1, 9, 1, -1, -1, 8, 0);
    let mh = _mm_setr_epi8(11, 3, -1, -1, 10, 2, -1, -1, 9, 1, -1, -1, 8, 0, -1, -1);
    let pc = |v: __m256i| -> __m256i {
        let v = _mm256_xor_si256(v, vcl);
        let lo = _mm256_shuffle_epi8(lut, _mm256_and_si256(v, low));
        let hi = _mm256_shuffle_epi8(lut, _mm256_and_si256(_mm256_srli_epi16(v, 4), low));
        _mm256_sad_epu8(_mm256_add_epi8(lo, hi), zero)
    };
    let mut j = 0;
    while j + 16 <= n {
        let p = r.as_ptr().add(n - 16 - j) as *const __m256i;
        let a = pc(_mm256_loadu_si256(p));
        let b = pc(_mm256_loadu_si256(p.add(1)));
        let c = pc(_mm256_loadu_si256(p.add(2)));
        let d = pc(_mm256_loadu_si256(p.add(3)));
        let x = _mm256_or_si256(
            _mm256_or_si256(a, _mm256_slli_epi64(b, 8)),
            _mm256_or_si256(_mm256_slli_epi64(c, 16), _mm256_slli_epi64(d, 24)),
        );
        let v = _mm_or_si128(
            _mm_shuffle_epi8(_mm256_castsi256_si128(x), ml),
            _mm_shuffle_epi8(_mm256_extracti128_si256(x, 1), mh),
        );
        let o = dst.as_mut_ptr().add(j) as *mut __m128i;
        let v = if MIN { _mm_min_epu8(v, _mm_loadu_si128(o)) } else { v };
        _mm_storeu_si128(o, v);
        j += 16;
    }
    j
}

#[inline(always)]
fn row_costs_impl(
    avx2: bool,
    g: &CostGeom,
    x0: usize,
    x1: usize,
    left_row: &[u64],
    right_rows: &[&[u64]],
    out: &mut [u8],
) {
    for (i, &cl) in left_row[x0..x1].iter().enumerate() {
        let o = i * g.ndp;
        pixel_costs(avx2, g, x0 + i, cl, right_rows, &mut out[o..o + g.ndp]);
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,popcnt")]
unsafe fn row_costs_avx2(g: &CostGeom, x0: usize, x1: usize, left_row: &[u64], right_rows: &[&[u64]], out: &mut [u8]) {
    row_costs_impl(true, g, x0, x1, left_row, right_rows, out)
}

/// Costs of pixels `x0..x1` of one row into `out` (`(x1 − x0) × ndp`); `avx2` selects the
/// build compiled for AVX2 + popcnt (same integer results).
pub fn row_costs(
    avx2: bool,
    g: &CostGeom,
    x0: usize,
    x1: usize,
    left_row: &[u64],
    right_rows: &[&[u64]],
    out: &mut [u8],
) {
    #[cfg(target_arch = "x86_64")]
    if avx2 {
        // SAFETY: `avx2` is only true when AVX2 and popcnt were detected at run time.
        return unsafe { row_costs_avx2(g, x0, x1, left_row, right_rows, out) };
    }
    row_costs_impl(false, g, x0, x1, left_row, right_rows, out)
}

/// The rows y + δ, δ ∈ [−k, k] clipped to the image, centre row first (so that the minimum over
/// δ is taken in a fixed order).
pub fn tolerance_rows(census_r: &[u64], w: usize, h: usize, y: usize, k: usize) -> Vec<&[u64]> {
    let mut rows = vec![&census_r[y * w..(y + 1) * w]];
    for dy in 1..=k {
        if y >= dy {
            rows.push(&census_r[(y - dy) * w..(y - dy + 1) * w]);
        }
        if y + dy < h {
            rows.push(&census_r[(y + dy) * w..(y + dy + 1) * w]);
        }
    }
    rows
}

/// Vertical offset δ (px) that realises the cost of disparity `d` at `(x, y)`: the δ with the
/// smallest Hamming distance, ties to the smallest |δ| then to the negative one; `None` when
/// `x − d` is outside the image.
#[allow(clippy::too_many_arguments)]
pub fn best_dy(
    census_l: &[u64],
    census_r: &[u64],
    w: usize,
    h: usize,
    x: usize,
    y: usize,
    d: i32,
    k: usize,
) -> Option<i32> {
    let xr = x as i64 - d as i64;
    if xr < 0 || xr >= w as i64 {
        return None;
    }
    let cl = census_l[y * w + x];
    let mut best = (u32::MAX, 0i32);
    for dy in std::iter::once(0i32).chain((1..=k as i32).flat_map(|a| [-a, a])) {
        let yy = y as i64 + dy as i64;
        if yy < 0 || yy >= h as i64 {
            continue;
        }
        let c = (cl ^ census_r[yy as usize * w + xr as usize]).count_ones();
        if c < best.0 {
            best = (c, dy);
        }
    }
    Some(best.1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn census_bits_by_hand() {
        // 9×7 image, centre (4, 3) = 100; one darker pixel at (0, 0), one equal at (8, 6).
        let (w, h) = (9, 7);
        let mut g = vec![150u8; w * h];
        g[3 * w + 4] = 100;
        g[0] = 50;
        g[6 * w + 8] = 100;
        let c = census(&g, w, h, false);
        // The first bit shifted in (dx = 0, dy = 0) ends as the highest of the 62 bits.
        assert_eq!(c[3 * w + 4], 1u64 << (CENSUS_BITS - 1));
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("popcnt") {
            assert_eq!(census(&g, w, h, true), c);
        }
    }

    #[test]
    fn costs_neutral_outside_and_hamming_inside() {
        let w = 5;
        let l: Vec<u64> = vec![0b1011; w];
        let r: Vec<u64> = (0..w as u64).collect();
        let g = CostGeom { w, d_min: -2, nd: 5, ndp: 16 };
        let mut out = vec![9u8; 16];
        pixel_costs(false, &g, 0, l[0], &[&r], &mut out);
        // x = 0: d = −2..2 → x_R = 2, 1, 0, −1, −2.
        let want =
            [(0b1011u64 ^ 2).count_ones() as u8, (0b1011u64 ^ 1).count_ones() as u8, 3, NEUTRAL_COST, NEUTRAL_COST];
        assert_eq!(&out[..5], &want);
        assert!(out[5..].iter().all(|&v| v == 0));
    }

    #[test]
    fn avx2_costs_equal_scalar() {
        if !(cfg!(target_arch = "x86_64") && crate::sgm::avx2_available()) {
            eprintln!("SKIP: no AVX2");
            return;
        }
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let w = 150;
        let r0: Vec<u64> = (0..w).map(|_| rng.gen::<u64>() >> 2).collect();
        let r1: Vec<u64> = (0..w).map(|_| rng.gen::<u64>() >> 2).collect();
        for (d_min, nd) in [(-40i32, 5usize), (0, 16), (-20, 33), (3, 64), (-70, 100)] {
            let g = CostGeom { w, d_min, nd, ndp: nd.div_ceil(16) * 16 };
            for x in [0usize, 7, 60, 149] {
                let cl = rng.gen::<u64>() >> 2;
                for rows in [vec![&r0[..]], vec![&r0[..], &r1[..]]] {
                    let (mut a, mut b) = (vec![0u8; g.ndp], vec![0u8; g.ndp]);
                    pixel_costs(true, &g, x, cl, &rows, &mut a);
                    pixel_costs(false, &g, x, cl, &rows, &mut b);
                    assert_eq!(a, b, "d_min {d_min} nd {nd} x {x}");
                }
            }
        }
    }

    #[test]
    fn avx2_census_equals_scalar() {
        if !(cfg!(target_arch = "x86_64") && crate::sgm::avx2_available()) {
            eprintln!("SKIP: no AVX2");
            return;
        }
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        for (w, h) in [(100usize, 9usize), (64, 3), (33, 12)] {
            // Few grey levels so that ties (equal neighbours, bit 0) occur often.
            let g: Vec<u8> = (0..w * h).map(|_| rng.gen_range(0..6u8) * 50).collect();
            assert_eq!(census(&g, w, h, true), census(&g, w, h, false), "{w}x{h}");
        }
    }
}
