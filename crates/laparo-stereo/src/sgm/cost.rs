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
pub fn census(gray: &[u8], w: usize, h: usize, avx2: bool) -> Vec<u64> {
    let mut out = vec![0u64; w * h];
    if w == 0 || h == 0 {
        return out;
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
        #[cfg(target_arch = "x86_64")]
        if avx2 {
            // SAFETY: the caller checked AVX2 and popcnt support at run time.
            unsafe { census_row_avx2(&pad, pw, y, w, row) };
            return;
        }
        let _ = avx2;
        census_row(&pad, pw, y, w, row);
    });
    out
}

#[inline(always)]
fn census_row(pad: &[u8], pw: usize, y: usize, w: usize, row: &mut [u64]) {
    let (rx, ry) = (CENSUS_W / 2, CENSUS_H / 2);
    let centre = &pad[(y + ry) * pw + rx..(y + ry) * pw + rx + w];
    for dy in 0..CENSUS_H {
        let nrow = &pad[(y + dy) * pw..(y + dy + 1) * pw];
        for dx in 0..CENSUS_W {
            if dx == rx && dy == ry {
                continue;
            }
            let nb = &nrow[dx..dx + w];
            for ((o, &c), &n) in row.iter_mut().zip(centre).zip(nb) {
                *o = (*o << 1) | u64::from(n < c);
            }
        }
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,popcnt")]
unsafe fn census_row_avx2(pad: &[u8], pw: usize, y: usize, w: usize, row: &mut [u64]) {
    census_row(pad, pw, y, w, row)
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
pub fn pixel_costs(g: &CostGeom, x: usize, cl: u64, right_rows: &[&[u64]], out: &mut [u8]) {
    let out = &mut out[..g.ndp];
    // d = d_min + i, x_R = x − d ∈ [0, w) ⇔ i ∈ (x − d_min − w, x − d_min].
    let hi = x as i64 - g.d_min as i64; // i ≤ hi
    let lo = hi - g.w as i64 + 1; // i ≥ lo
    let i0 = lo.clamp(0, g.nd as i64) as usize;
    let i1 = (hi + 1).clamp(0, g.nd as i64) as usize;
    out[..i0].fill(NEUTRAL_COST);
    out[i1..g.nd].fill(NEUTRAL_COST);
    out[g.nd..].fill(0);
    if i0 >= i1 {
        return;
    }
    // x_R for i is hi − i, decreasing: take the right-row slice [hi − (i1 − 1), hi − i0].
    let xr_lo = (hi - (i1 as i64 - 1)) as usize;
    let n = i1 - i0;
    let dst = &mut out[i0..i1];
    let first = &right_rows[0][xr_lo..xr_lo + n];
    for (o, &r) in dst.iter_mut().zip(first.iter().rev()) {
        *o = (cl ^ r).count_ones() as u8;
    }
    for rr in &right_rows[1..] {
        let s = &rr[xr_lo..xr_lo + n];
        for (o, &r) in dst.iter_mut().zip(s.iter().rev()) {
            *o = (*o).min((cl ^ r).count_ones() as u8);
        }
    }
}

#[inline(always)]
fn row_costs_impl(g: &CostGeom, x0: usize, x1: usize, left_row: &[u64], right_rows: &[&[u64]], out: &mut [u8]) {
    for (i, &cl) in left_row[x0..x1].iter().enumerate() {
        let o = i * g.ndp;
        pixel_costs(g, x0 + i, cl, right_rows, &mut out[o..o + g.ndp]);
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,popcnt")]
unsafe fn row_costs_avx2(g: &CostGeom, x0: usize, x1: usize, left_row: &[u64], right_rows: &[&[u64]], out: &mut [u8]) {
    row_costs_impl(g, x0, x1, left_row, right_rows, out)
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
    let _ = avx2;
    row_costs_impl(g, x0, x1, left_row, right_rows, out)
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
        pixel_costs(&g, 0, l[0], &[&r], &mut out);
        // x = 0: d = −2..2 → x_R = 2, 1, 0, −1, −2.
        let want =
            [(0b1011u64 ^ 2).count_ones() as u8, (0b1011u64 ^ 1).count_ones() as u8, 3, NEUTRAL_COST, NEUTRAL_COST];
        assert_eq!(&out[..5], &want);
        assert!(out[5..].iter().all(|&v| v == 0));
    }
}
