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
use super::select::{select, Selection};

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

/// First pixel of a path: `L = C`; adds into `s` (`ADD`) or writes it, returns min_d L.
#[inline(always)]
pub fn path_start<const ADD: bool>(cost: &[u8], nd: usize, ndp: usize, cur: &mut [u16], s: &mut [u16]) -> u16 {
    let mut m = u16::MAX;
    for d in 0..ndp {
        let l = if d < nd { cost[d] as u16 } else { 0xFFFF };
        cur[SENT + d] = l;
        s[d] = if ADD { s[d].saturating_add(l) } else { l };
        m = m.min(l);
    }
    m
}

/// One step of eq. 13 (portable). `prev`/`cur` are path buffers, `s` the pixel's S slice.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn path_step_scalar<const ADD: bool>(
    prev: &[u16],
    prev_min: u16,
    p1: u16,
    p2: u16,
    cost: &[u8],
    nd: usize,
    ndp: usize,
    cur: &mut [u16],
    s: &mut [u16],
) -> u16 {
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
        s[d] = if ADD { s[d].saturating_add(l) } else { l };
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
pub unsafe fn path_step_avx2<const ADD: bool>(
    prev: &[u16],
    prev_min: u16,
    p1: u16,
    p2: u16,
    cost: &[u8],
    nd: usize,
    ndp: usize,
    cur: &mut [u16],
    s: &mut [u16],
) -> u16 {
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
        if ADD {
            _mm256_storeu_si256(sp, _mm256_adds_epu16(_mm256_loadu_si256(sp), l));
        } else {
            _mm256_storeu_si256(sp, l);
        }
        vmin = _mm256_min_epu16(vmin, l);
        j += 16;
    }
    let m128 = _mm_min_epu16(_mm256_castsi256_si128(vmin), _mm256_extracti128_si256(vmin, 1));
    _mm_extract_epi16(_mm_minpos_epu16(m128), 0) as u16
}

/// Dispatching step.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn path_step<const ADD: bool>(
    avx2: bool,
    prev: &[u16],
    prev_min: u16,
    p1: u16,
    p2: u16,
    cost: &[u8],
    nd: usize,
    ndp: usize,
    cur: &mut [u16],
    s: &mut [u16],
) -> u16 {
    #[cfg(target_arch = "x86_64")]
    if avx2 {
        // SAFETY: `avx2` is only true when the CPU was checked at run time.
        return unsafe { path_step_avx2::<ADD>(prev, prev_min, p1, p2, cost, nd, ndp, cur, s) };
    }
    let _ = avx2;
    path_step_scalar::<ADD>(prev, prev_min, p1, p2, cost, nd, ndp, cur, s)
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

/// One row of the shared S volume and its selections. The first sweep to reach row `y` writes
/// its paths' sum there (`done` set); the second adds its own paths and selects the disparity of
/// each pixel while the pixel's S is still in cache. Every path value is at most
/// `C_max + P2 ≤ 62 + 1000`, so even 8 paths never saturate u16 and the sum does not depend on
/// which sweep came first: the output is the same for any thread count and timing.
pub struct RowSlot<'a> {
    /// Whether one sweep has written this row.
    pub done: bool,
    /// S of the row (`w × ndp`).
    pub s: &'a mut [u16],
    /// Selections of the row (written by the second sweep).
    pub sel: &'a mut [Selection],
}

/// One sweep over the rows, forward (top→bottom: left→right, top→bottom and, with `eight`, the
/// two downward diagonals) or backward (bottom→top: right→left, bottom→top, upward diagonals).
/// The paths of a sweep share each pixel's costs, computed on the fly; all paths of a pixel are
/// processed together so that its S stays in cache. A sweep is sequential over rows; the forward
/// and the backward sweep run in parallel ([`aggregate_select`]), meeting in [`RowSlot`]s.
pub fn sweep(inp: &Inputs, forward: bool, eight: bool, slots: &[std::sync::Mutex<RowSlot>]) {
    let g = inp.g;
    let (w, h, ndp) = (g.w, inp.h, g.ndp);
    let stride = ndp + 2 * SENT;
    let mut costs = vec![0u8; ndp];
    let (mut ha, mut hb) = (path_buffer(ndp), path_buffer(ndp));
    let n_dirs = if eight { 3 } else { 1 }; // vertical, diagonal from x − 1, diagonal from x + 1
    let mut prev = vec![0xFFFFu16; n_dirs * w * stride];
    let mut cur = vec![0xFFFFu16; n_dirs * w * stride];
    let mut pmin = vec![0u16; n_dirs * w];
    let mut cmin = vec![0u16; n_dirs * w];
    let (p1, avx2, nd) = (inp.pen.p1, inp.avx2, g.nd);
    // P2 by |ΔI| (the division of `p2_at` once per grey step, not per pixel and path).
    let p2_lut: Vec<u16> = (0..=255u8).map(|di| inp.pen.p2_at(di, 0)).collect();
    let p2_at = |a: u8, b: u8| p2_lut[a.abs_diff(b) as usize];
    for step in 0..h {
        let y = if forward { step } else { h - 1 - step };
        let yp = if forward { y.wrapping_sub(1) } else { y + 1 };
        let rows = tolerance_rows(inp.census_r, w, h, y, inp.vtol);
        let cl_row = &inp.census_l[y * w..(y + 1) * w];
        let gray = &inp.gray_l[y * w..(y + 1) * w];
        let gprev = if step > 0 { &inp.gray_l[yp * w..(yp + 1) * w] } else { gray };
        let mut guard = slots[y].lock().unwrap_or_else(|e| e.into_inner());
        let slot = &mut *guard;
        let second = slot.done;
        let mut m = 0u16;
        for i in 0..w {
            let x = if forward { i } else { w - 1 - i };
            row_costs(avx2, &g, x, x + 1, cl_row, &rows, &mut costs);
            let sp = &mut slot.s[x * ndp..(x + 1) * ndp];
            // Horizontal path: writes S (first sweep) or adds to it (second).
            m = match (i, second) {
                (0, false) => path_start::<false>(&costs, nd, ndp, &mut ha, sp),
                (0, true) => path_start::<true>(&costs, nd, ndp, &mut ha, sp),
                _ => {
                    let xq = if forward { x - 1 } else { x + 1 };
                    let p2 = p2_at(gray[x], gray[xq]);
                    if second {
                        path_step::<true>(avx2, &hb, m, p1, p2, &costs, nd, ndp, &mut ha, sp)
                    } else {
                        path_step::<false>(avx2, &hb, m, p1, p2, &costs, nd, ndp, &mut ha, sp)
                    }
                }
            };
            std::mem::swap(&mut ha, &mut hb);
            // Vertical and diagonal paths, from the previous row.
            for k in 0..n_dirs {
                let xq = match k {
                    0 => Some(x),
                    1 => x.checked_sub(1),
                    _ => (x + 1 < w).then_some(x + 1),
                };
                let cb = &mut cur[(k * w + x) * stride..(k * w + x + 1) * stride];
                cmin[k * w + x] = match xq {
                    Some(xq) if step > 0 => {
                        let pb = &prev[(k * w + xq) * stride..(k * w + xq + 1) * stride];
                        let p2 = p2_at(gray[x], gprev[xq]);
                        path_step::<true>(avx2, pb, pmin[k * w + xq], p1, p2, &costs, nd, ndp, cb, sp)
                    }
                    _ => path_start::<true>(&costs, nd, ndp, cb, sp),
                };
            }
            if second {
                slot.sel[x] = select(avx2, sp, nd, ndp);
            }
        }
        slot.done = true;
        drop(guard);
        std::mem::swap(&mut prev, &mut cur);
        std::mem::swap(&mut pmin, &mut cmin);
    }
}

/// Aggregate all paths (eq. 14) and select (see [`super::select`]): the forward and the backward
/// [`sweep`] in parallel (`rayon::join`) over one shared S volume; returns the `w × h`
/// selections.
pub fn aggregate_select(inp: &Inputs, eight: bool) -> Vec<Selection> {
    let (w, h, ndp) = (inp.g.w, inp.h, inp.g.ndp);
    let mut s = take_buffer(w * h * ndp);
    let mut sel = vec![Selection::default(); w * h];
    {
        let slots: Vec<std::sync::Mutex<RowSlot>> = s
            .chunks_mut(w * ndp)
            .zip(sel.chunks_mut(w))
            .map(|(s, sel)| std::sync::Mutex::new(RowSlot { done: false, s, sel }))
            .collect();
        rayon::join(|| sweep(inp, true, eight, &slots), || sweep(inp, false, eight, &slots));
    }
    recycle(s);
    sel
}

/// Reused S volumes: a video or a benchmark matches pair after pair of one size, and a fresh
/// 50–300 MB allocation per pair costs more in page faults than the matching itself.
static POOL: std::sync::Mutex<Vec<Vec<u16>>> = std::sync::Mutex::new(Vec::new());

/// A buffer of `n` u16 (contents unspecified: [`sweep`] writes every row before use).
fn take_buffer(n: usize) -> Vec<u16> {
    let mut v = POOL.lock().map(|mut p| p.pop()).ok().flatten().unwrap_or_default();
    v.resize(n, 0);
    v
}

/// Give an S volume back for the next pair (at most two are kept).
fn recycle(v: Vec<u16>) {
    if let Ok(mut p) = POOL.lock() {
        if p.len() < 2 {
            p.push(v);
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
        let m = path_step_scalar::<true>(&prev, 4, p1, p2, &cost, nd, ndp, &mut cur, &mut s);
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
            let m1 = path_step_scalar::<true>(&prev, pm, 7, 90, &cost, nd, ndp, &mut c1, &mut s1);
            let m2 = unsafe { path_step_avx2::<true>(&prev, pm, 7, 90, &cost, nd, ndp, &mut c2, &mut s2) };
            assert_eq!((m1, &c1, &s1), (m2, &c2, &s2), "nd = {nd}");
        }
    }
}
