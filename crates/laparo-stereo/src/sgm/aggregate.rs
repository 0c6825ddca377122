//! Path-wise cost aggregation of SGM (Hirschmüller 2008, eq. 13):
//! `L_r(p, d) = C(p, d) + min(L_r(p − r, d), L_r(p − r, d ± 1) + P1, min_k L_r(p − r, k) + P2)
//! − min_k L_r(p − r, k)`, summed over the paths into `S(p, d) = Σ_r L_r(p, d)` (eq. 14).
//! P2 adapts to the intensity step along the path: `P2(p) = max(P1, P2 · γ / (γ + |I(p) − I(p − r)|))`
//! (Hirschmüller's `P2 = P2' / |ΔI|`, bounded), `γ = 0` keeps P2 constant.
//!
//! Layout: S is `h × w × ndp` u16 (ndp = disparities rounded up to 16); a path buffer holds one
//! pixel's `ndp` values between [`SENT`] sentinel lanes of 0xFFFF on each side, so that the
//! `d ± 1` neighbours are plain unaligned loads. Lanes ≥ nd are held at 0xFFFF. The AVX2 kernel
//! and the scalar kernel perform the same u16 operations (saturating adds for `+ P1`, `+ P2` and
//! the sum into S, wrapping `C + t − min` which never wraps): results are identical bit for bit.
use super::cost::{row_costs, tolerance_rows, CostGeom};
use rayon::prelude::*;

/// Sentinel lanes on each side of a path buffer.
pub const SENT: usize = 16;

/// Penalties of eq. 13 (cost units: census bits).
#[derive(Clone, Copy, Debug)]
pub struct Penalties {
    /// Small-step penalty P1.
    pub p1: u16,
    /// Large-step penalty P2 (before the intensity adaptation).
    pub p2: u16,
    /// Adaptation constant γ (grey levels); 0 = constant P2.
    pub gamma: u16,
}

impl Penalties {
    /// P2 at an intensity step `a → b` along the path.
    #[inline(always)]
    pub fn p2_at(&self, a: u8, b: u8) -> u16 {
        if self.gamma == 0 {
            return self.p2;
        }
        let di = (a as i32 - b as i32).unsigned_abs();
        let g = self.gamma as u32;
        ((self.p2 as u32 * g / (g + di)) as u16).max(self.p1)
    }
}

/// A fresh path buffer (sentinels set).
pub fn path_buffer(ndp: usize) -> Vec<u16> {
    vec![0xFFFF; ndp + 2 * SENT]
}

/// First pixel of a path: `L = C`; adds into `s`, returns min_d L.
#[inline(always)]
pub fn path_start(cost: &[u8], nd: usize, ndp: usize, cur: &mut [u16], s: &mut [u16]) -> u16 {
    let mut m = u16::MAX;
    for d in 0..ndp {
        let l = if d < nd { cost[d] as u16 } else { 0xFFFF };
        cur[SENT + d] = l;
        s[d] = s[d].saturating_add(l);
        m = m.min(l);
    }
    m
}

/// One step of eq. 13 (portable). `prev`/`cur` are path buffers, `s` the pixel's S slice.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn path_step_scalar(prev: &[u16], prev_min: u16, p1: u16, p2: u16, cost: &[u8], nd: usize, ndp: usize, cur: &mut [u16], s: &mut [u16]) -> u16 {
    let pm2 = prev_min.saturating_add(p2);
    let mut m = u16::MAX;
    for d in 0..ndp {
        let l = if d < nd {
            let a = prev[SENT + d];
            let b = prev[SENT + d - 1].saturating_add(p1);
            let c = prev[SENT + d + 1].saturating_add(p1);
            let t = a.min(b).min(c).min(pm2);
            (cost[d] as u16).wrapping_add(t).wrapping_sub(prev_min)
        } else {
            0xFFFF
        };
        cur[SENT + d] = l;
        s[d] = s[d].saturating_add(l);
        m = m.min(l);
    }
    m
}

/// AVX2 version of [`path_step_scalar`] (same operations, 16 lanes at a time).
///
/// # Safety
/// AVX2 must be available; buffers as in [`path_step_scalar`].
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[allow(clippy::too_many_arguments)]
pub unsafe fn path_step_avx2(prev: &[u16], prev_min: u16, p1: u16, p2: u16, cost: &[u8], nd: usize, ndp: usize, cur: &mut [u16], s: &mut [u16]) -> u16 {
    use std::arch::x86_64::*;
    debug_assert!(prev.len() >= ndp + 2 * SENT && cur.len() >= ndp + 2 * SENT && s.len() >= ndp && cost.len() >= ndp);
    let pm2 = _mm256_set1_epi16(prev_min.saturating_add(p2) as i16);
    let pmin = _mm256_set1_epi16(prev_min as i16);
    let vp1 = _mm256_set1_epi16(p1 as i16);
    let mut vmin = _mm256_set1_epi16(-1);
    let lane = _mm256_setr_epi16(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
    let pp = prev.as_ptr().add(SENT);
    let cp = cur.as_mut_ptr().add(SENT);
    let mut j = 0;
    while j < ndp {
        let a = _mm256_loadu_si256(pp.add(j) as *const __m256i);
        let b = _mm256_adds_epu16(_mm256_loadu_si256(pp.add(j).sub(1) as *const __m256i), vp1);
        let c = _mm256_adds_epu16(_mm256_loadu_si256(pp.add(j + 1) as *const __m256i), vp1);
        let t = _mm256_min_epu16(_mm256_min_epu16(a, b), _mm256_min_epu16(c, pm2));
        let cv = _mm256_cvtepu8_epi16(_mm_loadu_si128(cost.as_ptr().add(j) as *const __m128i));
        let mut l = _mm256_sub_epi16(_mm256_add_epi16(cv, t), pmin);
        if j + 16 > nd {
            // lanes d ≥ nd → 0xFFFF
            let dl = _mm256_add_epi16(lane, _mm256_set1_epi16(j as i16));
            let pad = _mm256_cmpgt_epi16(dl, _mm256_set1_epi16(nd as i16 - 1));
            l = _mm256_or_si256(l, pad);
        }
        _mm256_storeu_si256(cp.add(j) as *mut __m256i, l);
        let sp = s.as_mut_ptr().add(j) as *mut __m256i;
        _mm256_storeu_si256(sp, _mm256_adds_epu16(_mm256_loadu_si256(sp), l));
        vmin = _mm256_min_epu16(vmin, l);
        j += 16;
    }
    let m128 = _mm_min_epu16(_mm256_castsi256_si128(vmin), _mm256_extracti128_si256(vmin, 1));
    _mm_extract_epi16(_mm_minpos_epu16(m128), 0) as u16
}

/// Dispatching step.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn path_step(avx2: bool, prev: &[u16], prev_min: u16, p1: u16, p2: u16, cost: &[u8], nd: usize, ndp: usize, cur: &mut [u16], s: &mut [u16]) -> u16 {
    #[cfg(target_arch = "x86_64")]
    if avx2 {
        // SAFETY: `avx2` is only true when the CPU was checked at run time.
        return unsafe { path_step_avx2(prev, prev_min, p1, p2, cost, nd, ndp, cur, s) };
    }
    let _ = avx2;
    path_step_scalar(prev, prev_min, p1, p2, cost, nd, ndp, cur, s)
}

/// Everything the passes read.
pub struct Inputs<'a> {
    /// Census of the left / right image.
    pub census_l: &'a [u64],
    /// Census of the right image.
    pub census_r: &'a [u64],
    /// Left grey image (for the adaptive P2).
    pub gray_l: &'a [u8],
    /// Image height.
    pub h: usize,
    /// Cost geometry.
    pub g: CostGeom,
    /// Vertical tolerance (rows).
    pub vtol: usize,
    /// Penalties.
    pub pen: Penalties,
    /// Use the AVX2 kernels.
    pub avx2: bool,
}

/// Horizontal paths (left→right, right→left) of every row, added into `s` (parallel over rows).
pub fn pass_horizontal(inp: &Inputs, s: &mut [u16]) {
    let g = inp.g;
    let (w, ndp) = (g.w, g.ndp);
    s.par_chunks_mut(w * ndp).enumerate().for_each_init(
        || (vec![0u8; w * ndp], path_buffer(ndp), path_buffer(ndp)),
        |(costs, a, b), (y, srow)| {
            let rows = tolerance_rows(inp.census_r, w, inp.h, y, inp.vtol);
            row_costs(inp.avx2, &g, 0, w, &inp.census_l[y * w..(y + 1) * w], &rows, costs);
            let gray = &inp.gray_l[y * w..(y + 1) * w];
            // left → right
            let mut m = path_start(&costs[..ndp], g.nd, ndp, a, &mut srow[..ndp]);
            for x in 1..w {
                let p2 = inp.pen.p2_at(gray[x], gray[x - 1]);
                let o = x * ndp;
                m = path_step(inp.avx2, a, m, inp.pen.p1, p2, &costs[o..o + ndp], g.nd, ndp, b, &mut srow[o..o + ndp]);
                std::mem::swap(a, b);
            }
            // right → left
            let o = (w - 1) * ndp;
            let mut m = path_start(&costs[o..o + ndp], g.nd, ndp, a, &mut srow[o..o + ndp]);
            for x in (0..w - 1).rev() {
                let p2 = inp.pen.p2_at(gray[x], gray[x + 1]);
                let o = x * ndp;
                m = path_step(inp.avx2, a, m, inp.pen.p1, p2, &costs[o..o + ndp], g.nd, ndp, b, &mut srow[o..o + ndp]);
                std::mem::swap(a, b);
            }
        },
    );
}

/// Raw pointer to S shared by column-chunk workers that touch disjoint columns.
#[derive(Clone, Copy)]
struct SPtr(*mut u16);
// SAFETY: workers write disjoint (row, column) cells only.
unsafe impl Send for SPtr {}
unsafe impl Sync for SPtr {}

/// Columns per chunk of the vertical pass (fixed, so the work split never depends on threads).
pub const COL_CHUNK: usize = 16;

/// Vertical paths (top→bottom, bottom→top) added into `s`, in column chunks (parallel). After
/// the bottom→top step of a pixel its S is final; `finish(x, y, s_pixel)` is called then.
pub fn pass_vertical<F>(inp: &Inputs, s: &mut [u16], finish: F)
where
    F: Fn(usize, usize, &[u16]) + Sync,
{
    let g = inp.g;
    let (w, h, ndp) = (g.w, inp.h, g.ndp);
    assert_eq!(s.len(), w * h * ndp);
    let sp = SPtr(s.as_mut_ptr());
    let n_chunks = w.div_ceil(COL_CHUNK);
    (0..n_chunks).into_par_iter().for_each(|ci| {
        let sp = sp;
        let x0 = ci * COL_CHUNK;
        let x1 = (x0 + COL_CHUNK).min(w);
        let nc = x1 - x0;
        let stride = ndp + 2 * SENT;
        let mut prev = vec![0xFFFFu16; nc * stride];
        let mut cur = vec![0xFFFFu16; nc * stride];
        let mut mins = vec![0u16; nc];
        let mut costs = vec![0u8; nc * ndp];
        for down in [true, false] {
            for step in 0..h {
                let y = if down { step } else { h - 1 - step };
                let rows = tolerance_rows(inp.census_r, w, h, y, inp.vtol);
                row_costs(inp.avx2, &g, x0, x1, &inp.census_l[y * w..(y + 1) * w], &rows, &mut costs);
                for i in 0..nc {
                    let x = x0 + i;
                    // SAFETY: pixel (x, y) belongs to this chunk only.
                    let spx = unsafe { std::slice::from_raw_parts_mut(sp.0.add((y * w + x) * ndp), ndp) };
                    let c = &costs[i * ndp..(i + 1) * ndp];
                    let cb = &mut cur[i * stride..(i + 1) * stride];
                    mins[i] = if step == 0 {
                        path_start(c, g.nd, ndp, cb, spx)
                    } else {
                        let yp = if down { y - 1 } else { y + 1 };
                        let p2 = inp.pen.p2_at(inp.gray_l[y * w + x], inp.gray_l[yp * w + x]);
                        path_step(inp.avx2, &prev[i * stride..(i + 1) * stride], mins[i], inp.pen.p1, p2, c, g.nd, ndp, cb, spx)
                    };
                    if !down {
                        finish(x, y, spx);
                    }
                }
                std::mem::swap(&mut prev, &mut cur);
            }
        }
    });
}

/// Pixels per chunk of a diagonal row step (fixed, independent of the thread count).
pub const DIAG_CHUNK: usize = 64;

/// The four diagonal paths (8-path mode), added into `s`: rows are swept top→bottom then
/// bottom→top; within a row the pixels are independent (parallel in fixed chunks).
pub fn pass_diagonal(inp: &Inputs, s: &mut [u16]) {
    let g = inp.g;
    let (w, h, ndp) = (g.w, inp.h, g.ndp);
    let stride = ndp + 2 * SENT;
    // Two directions per sweep: A comes from (x − 1, y ∓ 1), B from (x + 1, y ∓ 1).
    let mut prev_a = vec![0xFFFFu16; w * stride];
    let mut prev_b = vec![0xFFFFu16; w * stride];
    let mut cur_a = vec![0xFFFFu16; w * stride];
    let mut cur_b = vec![0xFFFFu16; w * stride];
    let mut min_a = vec![0u16; w];
    let mut min_b = vec![0u16; w];
    let mut nmin_a = vec![0u16; w];
    let mut nmin_b = vec![0u16; w];
    for down in [true, false] {
        for step in 0..h {
            let y = if down { step } else { h - 1 - step };
            let yp = if down { y.wrapping_sub(1) } else { y + 1 };
            let rows = tolerance_rows(inp.census_r, w, h, y, inp.vtol);
            let srow = &mut s[y * w * ndp..(y + 1) * w * ndp];
            let (pa, pb, ma, mb) = (&prev_a, &prev_b, &min_a, &min_b);
            srow.par_chunks_mut(DIAG_CHUNK * ndp)
                .zip(cur_a.par_chunks_mut(DIAG_CHUNK * stride))
                .zip(cur_b.par_chunks_mut(DIAG_CHUNK * stride))
                .zip(nmin_a.par_chunks_mut(DIAG_CHUNK))
                .zip(nmin_b.par_chunks_mut(DIAG_CHUNK))
                .enumerate()
                .for_each(|(ci, ((((sc, ca), cb), na), nb))| {
                    let x0 = ci * DIAG_CHUNK;
                    let mut cc = vec![0u8; na.len() * ndp];
                    row_costs(inp.avx2, &g, x0, x0 + na.len(), &inp.census_l[y * w..(y + 1) * w], &rows, &mut cc);
                    for i in 0..na.len() {
                        let x = x0 + i;
                        let c = &cc[i * ndp..(i + 1) * ndp];
                        let spx = &mut sc[i * ndp..(i + 1) * ndp];
                        let ga = &mut ca[i * stride..(i + 1) * stride];
                        na[i] = if step == 0 || x == 0 {
                            path_start(c, g.nd, ndp, ga, spx)
                        } else {
                            let p2 = inp.pen.p2_at(inp.gray_l[y * w + x], inp.gray_l[yp * w + x - 1]);
                            path_step(inp.avx2, &pa[(x - 1) * stride..x * stride], ma[x - 1], inp.pen.p1, p2, c, g.nd, ndp, ga, spx)
                        };
                        let gb = &mut cb[i * stride..(i + 1) * stride];
                        nb[i] = if step == 0 || x + 1 == w {
                            path_start(c, g.nd, ndp, gb, spx)
                        } else {
                            let p2 = inp.pen.p2_at(inp.gray_l[y * w + x], inp.gray_l[yp * w + x + 1]);
                            path_step(inp.avx2, &pb[(x + 1) * stride..(x + 2) * stride], mb[x + 1], inp.pen.p1, p2, c, g.nd, ndp, gb, spx)
                        };
                    }
                });
            std::mem::swap(&mut prev_a, &mut cur_a);
            std::mem::swap(&mut prev_b, &mut cur_b);
            std::mem::swap(&mut min_a, &mut nmin_a);
            std::mem::swap(&mut min_b, &mut nmin_b);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Eq. 13 by hand on 3 disparities.
    #[test]
    fn step_by_hand() {
        let (nd, ndp) = (3, 16);
        let mut prev = path_buffer(ndp);
        prev[SENT..SENT + 3].copy_from_slice(&[10, 4, 30]);
        let cost = {
            let mut c = vec![0u8; ndp];
            c[..3].copy_from_slice(&[5, 7, 2]);
            c
        };
        let (p1, p2) = (3, 20);
        // d0: min(10, 4+3, 4+20) = 7 → 5 + 7 − 4 = 8; d1: min(4, ..) = 4 → 7; d2: min(30, 4+3, 24) = 7 → 2 + 7 − 4 = 5.
        let mut cur = path_buffer(ndp);
        let mut s = vec![1u16; ndp];
        let m = path_step_scalar(&prev, 4, p1, p2, &cost, nd, ndp, &mut cur, &mut s);
        assert_eq!(&cur[SENT..SENT + 3], &[8, 7, 5]);
        assert_eq!(m, 5);
        assert_eq!(&s[..3], &[9, 8, 6]);
        assert!(cur[SENT + 3..].iter().all(|&v| v == 0xFFFF));
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx2_step_matches_scalar() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            eprintln!("SKIP: no AVX2");
            return;
        }
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        for nd in [1usize, 5, 16, 17, 40, 64] {
            let ndp = nd.div_ceil(16) * 16;
            let mut prev = path_buffer(ndp);
            for d in 0..nd {
                prev[SENT + d] = rng.gen_range(0..400);
            }
            let pm = *prev[SENT..SENT + nd].iter().min().unwrap();
            let cost: Vec<u8> = (0..ndp).map(|_| rng.gen_range(0..63)).collect();
            let s0: Vec<u16> = (0..ndp).map(|_| rng.gen_range(0..3000)).collect();
            let (mut c1, mut c2) = (path_buffer(ndp), path_buffer(ndp));
            let (mut s1, mut s2) = (s0.clone(), s0.clone());
            let m1 = path_step_scalar(&prev, pm, 7, 90, &cost, nd, ndp, &mut c1, &mut s1);
            let m2 = unsafe { path_step_avx2(&prev, pm, 7, 90, &cost, nd, ndp, &mut c2, &mut s2) };
            assert_eq!((m1, &c1, &s1), (m2, &c2, &s2), "nd = {nd}");
        }
    }
}
