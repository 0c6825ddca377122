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
use super::select::Selection;
use super::workspace::{put_back, take, Volumes};

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
#[cfg(test)]
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
    /// Store the first sweep's S as bytes ([`narrow_partial_sums`]).
    pub narrow: bool,
}

/// One row of the shared volumes and its selections. The first sweep to reach row `y` computes
/// the row's costs (kept for the other sweep: the cost volume is computed once) and writes its
/// paths' sum to S (`done` set); the second adds its own paths and selects the disparity of each
/// pixel while the pixel's S is still in registers. Every path value is at most
/// `C_max + P2 ≤ 62 + 1000`, so even 8 paths never saturate u16 and the sum does not depend on
/// which sweep came first: the output is the same for any thread count and timing.
pub struct RowSlot<'a> {
    /// Whether one sweep has written this row.
    pub done: bool,
    /// S of the row (`w × ndp`; empty when `s8` is used).
    pub s: &'a mut [u16],
    /// The first sweep's S of the row as bytes (`w × ndp`; empty when `s` is used), see
    /// [`narrow_partial_sums`].
    pub s8: &'a mut [u8],
    /// Costs C of the row (`w × ndp`, written by the first sweep).
    pub cost: &'a mut [u8],
    /// Selections of the row (written by the second sweep).
    pub sel: &'a mut [Selection],
}

/// Whether the first sweep's S fits in bytes: each path value is `L = C + t − min L(p − r)` with
/// `t ≤ min L(p − r) + P2`, so `0 ≤ L ≤ C_max + P2 = 62 + P2` (the adapted P2 is at most P2), and
/// a sweep of 4 paths sums two of them: `2 (62 + P2) ≤ 255` for P2 ≤ 65 (the default mode). Exact,
/// so the output is the same; it halves the memory traffic of the S volume.
pub fn narrow_partial_sums(eight: bool, p2: u16) -> bool {
    !eight && 2 * (super::cost::CENSUS_BITS + p2 as u32) <= 255
}

/// The path buffers `w` pixels wide of the paths coming from the previous row, each `ndp` lanes
/// between [`SENT`] sentinels: data lanes 0 and previous minimum 0 make the first row's step
/// `L = C` (eq. 13 with `L(p − r) ≡ 0`), the same values as a path start.
fn zero_paths(n: usize, ndp: usize) -> Vec<u16> {
    let stride = ndp + 2 * SENT;
    let mut v = vec![0xFFFFu16; n * stride];
    for b in v.chunks_exact_mut(stride) {
        b[SENT..SENT + ndp].fill(0);
    }
    v
}

/// One row of a sweep: the horizontal path and the `n_dirs` paths from the previous row
/// (vertical; with 8 paths the diagonals from `x − 1` and `x + 1`) for every pixel in sweep
/// order; the first sweep writes S, the second selects.
struct RowJob<'a> {
    forward: bool,
    first_row: bool,
    n_dirs: usize,
    w: usize,
    nd: usize,
    ndp: usize,
    p1: u16,
    p2_lut: &'a [u16; 256],
    gray: &'a [u8],
    gprev: &'a [u8],
    cost: &'a [u8],
    prev: &'a [u16],
    pmin: &'a [u16],
    cur: &'a mut [u16],
    cmin: &'a mut [u16],
    zero: &'a [u16],
    s: &'a mut [u16],
    s8: &'a mut [u8],
    narrow: bool,
    sel: &'a mut [Selection],
    second: bool,
}

impl RowJob<'_> {
    /// Pixel `x` at sweep index `i`, its horizontal predecessor.
    #[inline(always)]
    fn pixel(&self, i: usize) -> (usize, usize) {
        let x = if self.forward { i } else { self.w - 1 - i };
        let xq = if i == 0 {
            x
        } else if self.forward {
            x - 1
        } else {
            x + 1
        };
        (x, xq)
    }

    /// The previous-row pixel of path `k` at `x` (vertical, diagonal from x − 1, from x + 1).
    #[inline(always)]
    fn above_of(&self, k: usize, x: usize) -> Option<usize> {
        if self.first_row {
            return None;
        }
        match k {
            0 => Some(x),
            1 => x.checked_sub(1),
            _ => (x + 1 < self.w).then_some(x + 1),
        }
    }

    #[inline(always)]
    fn p2(&self, a: u8, b: u8) -> u16 {
        self.p2_lut[a.abs_diff(b) as usize]
    }
}

/// Portable row kernel (the reference for [`row_avx2`]).
fn row_scalar(j: &mut RowJob, ha: &mut Vec<u16>, hb: &mut Vec<u16>) {
    let (w, nd, ndp, p1) = (j.w, j.nd, j.ndp, j.p1);
    let stride = ndp + 2 * SENT;
    let mut tmp = vec![0u16; ndp];
    let mut m = 0u16;
    for i in 0..w {
        let (x, xq) = j.pixel(i);
        let p2 = j.p2(j.gray[x], j.gray[xq]);
        let mut above = [(None, 0u16); 3];
        for (k, a) in above.iter_mut().enumerate().take(j.n_dirs) {
            *a = match j.above_of(k, x) {
                Some(xq) => (Some(xq), j.p2(j.gray[x], j.gprev[xq])),
                None => (None, p2),
            };
        }
        let c = &j.cost[x * ndp..(x + 1) * ndp];
        let sp: &mut [u16] = if j.narrow {
            for (t, &v) in tmp.iter_mut().zip(&j.s8[x * ndp..(x + 1) * ndp]) {
                // Padded lanes were stored saturated (255); any value there sums to 0xFFFF.
                *t = v as u16;
            }
            &mut tmp[..]
        } else {
            &mut j.s[x * ndp..(x + 1) * ndp]
        };
        let (hp, hm) = if i == 0 { (j.zero, 0) } else { (&hb[..], m) };
        m = if j.second {
            path_step_scalar::<true>(hp, hm, p1, p2, c, nd, ndp, ha, sp)
        } else {
            path_step_scalar::<false>(hp, hm, p1, p2, c, nd, ndp, ha, sp)
        };
        std::mem::swap(ha, hb);
        for (k, &a) in above.iter().enumerate().take(j.n_dirs) {
            let (pb, pm, p2) = match a {
                (Some(xq), p2) => (&j.prev[(k * w + xq) * stride..(k * w + xq + 1) * stride], j.pmin[k * w + xq], p2),
                (None, p2) => (j.zero, 0, p2),
            };
            let cb = &mut j.cur[(k * w + x) * stride..(k * w + x + 1) * stride];
            j.cmin[k * w + x] = path_step_scalar::<true>(pb, pm, p1, p2, c, nd, ndp, cb, sp);
        }
        if j.second {
            j.sel[x] = super::select::select_scalar(sp, nd);
        } else if j.narrow {
            for (o, &v) in j.s8[x * ndp..(x + 1) * ndp].iter_mut().zip(sp.iter()) {
                *o = v.min(255) as u8;
            }
        }
    }
}

/// One 16-lane step of eq. 13 from the path buffer at `pp` (lane `j`): `C + min(L(d),
/// L(d ± 1) + P1, min L + P2) − min L` (the operations of [`path_step_avx2`]).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn lane_step(
    pp: *const u16,
    cv: std::arch::x86_64::__m256i,
    vp1: std::arch::x86_64::__m256i,
    pm2: std::arch::x86_64::__m256i,
    pmin: std::arch::x86_64::__m256i,
) -> std::arch::x86_64::__m256i {
    use std::arch::x86_64::*;
    let a = _mm256_loadu_si256(pp as *const __m256i);
    let b = _mm256_adds_epu16(_mm256_loadu_si256(pp.sub(1) as *const __m256i), vp1);
    let c = _mm256_adds_epu16(_mm256_loadu_si256(pp.add(1) as *const __m256i), vp1);
    let t = _mm256_min_epu16(_mm256_min_epu16(a, b), _mm256_min_epu16(c, pm2));
    _mm256_sub_epi16(_mm256_add_epi16(cv, t), pmin)
}

/// [`lane_step`] for the horizontal path, whose buffer the previous pixel has just stored: the
/// `d ± 1` neighbours are built in registers from the three whole 16-lane blocks around lane `j`
/// (loads that each match one earlier store, so that they are forwarded from the store buffer;
/// an unaligned load across two fresh stores would wait for them to retire). The blocks before
/// the first and after the last are the 0xFFFF sentinels, as in [`lane_step`].
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn lane_step_fresh(
    pp: *const u16,
    cv: std::arch::x86_64::__m256i,
    vp1: std::arch::x86_64::__m256i,
    pm2: std::arch::x86_64::__m256i,
    pmin: std::arch::x86_64::__m256i,
) -> std::arch::x86_64::__m256i {
    use std::arch::x86_64::*;
    let a = _mm256_loadu_si256(pp as *const __m256i);
    let ap = _mm256_loadu_si256(pp.sub(16) as *const __m256i);
    let an = _mm256_loadu_si256(pp.add(16) as *const __m256i);
    // [ap15, a0 .. a14] and [a1 .. a15, an0].
    let dm1 = _mm256_alignr_epi8(a, _mm256_permute2x128_si256(a, ap, 0x03), 14);
    let dp1 = _mm256_alignr_epi8(_mm256_permute2x128_si256(a, an, 0x21), a, 2);
    let b = _mm256_adds_epu16(dm1, vp1);
    let c = _mm256_adds_epu16(dp1, vp1);
    let t = _mm256_min_epu16(_mm256_min_epu16(a, b), _mm256_min_epu16(c, pm2));
    _mm256_sub_epi16(_mm256_add_epi16(cv, t), pmin)
}

/// Horizontal minimum of 16 u16 lanes.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn hmin16(v: std::arch::x86_64::__m256i) -> u16 {
    use std::arch::x86_64::*;
    let m = _mm_min_epu16(_mm256_castsi256_si128(v), _mm256_extracti128_si256(v, 1));
    _mm_extract_epi16(_mm_minpos_epu16(m), 0) as u16
}

/// AVX2 row kernel: all paths of a pixel in one pass over its lanes (costs widened once, S
/// summed in registers, stored by the first sweep, selected from by the second); the same u16
/// operations in the same order as [`row_scalar`].
///
/// # Safety
/// AVX2, popcnt and BMI1 must be available.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,popcnt,bmi1")]
unsafe fn row_avx2<const NDIRS: usize, const SECOND: bool, const NARROW: bool>(
    j: &mut RowJob,
    ha: &mut Vec<u16>,
    hb: &mut Vec<u16>,
) {
    use std::arch::x86_64::*;
    let (w, nd, ndp) = (j.w, j.nd, j.ndp);
    let stride = ndp + 2 * SENT;
    assert!(j.cost.len() >= w * ndp && j.sel.len() >= w);
    assert!(if NARROW { j.s8.len() >= w * ndp } else { j.s.len() >= w * ndp });
    assert!(j.prev.len() >= NDIRS * w * stride && j.cur.len() >= NDIRS * w * stride);
    assert!(j.pmin.len() >= NDIRS * w && j.cmin.len() >= NDIRS * w && j.zero.len() >= stride);
    assert!(ha.len() >= stride && hb.len() >= stride);
    let vp1 = _mm256_set1_epi16(j.p1 as i16);
    // Lanes d ≥ nd of the last block → 0xFFFF.
    let lane = _mm256_setr_epi16(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
    let last = ndp - 16;
    let pad =
        _mm256_cmpgt_epi16(_mm256_add_epi16(lane, _mm256_set1_epi16(last as i16)), _mm256_set1_epi16(nd as i16 - 1));
    let mut sbuf = [0u16; super::MAX_DISPARITIES];
    let mut m = 0u16;
    let (mut hcur, mut hprev) = (ha.as_mut_ptr(), hb.as_mut_ptr());
    for i in 0..w {
        let (x, xq) = j.pixel(i);
        let cp = j.cost.as_ptr().add(x * ndp);
        let sp = if NARROW { std::ptr::null_mut() } else { j.s.as_mut_ptr().add(x * ndp) };
        let sp8 = if NARROW { j.s8.as_mut_ptr().add(x * ndp) } else { std::ptr::null_mut() };
        let (hp, hm) = if i == 0 { (j.zero.as_ptr(), 0) } else { (hprev as *const u16, m) };
        let hpen = j.p2(j.gray[x], j.gray[xq]);
        let h_pm2 = _mm256_set1_epi16(hm.saturating_add(hpen) as i16);
        let h_pmin = _mm256_set1_epi16(hm as i16);
        let mut vp = [std::ptr::null::<u16>(); NDIRS];
        let mut v_pm2 = [_mm256_setzero_si256(); NDIRS];
        let mut v_pmin = [_mm256_setzero_si256(); NDIRS];
        for k in 0..NDIRS {
            let (pb, pm, p2) = match j.above_of(k, x) {
                Some(xq) => {
                    (j.prev.as_ptr().add((k * w + xq) * stride), j.pmin[k * w + xq], j.p2(j.gray[x], j.gprev[xq]))
                }
                None => (j.zero.as_ptr(), 0, hpen),
            };
            vp[k] = pb.add(SENT);
            v_pm2[k] = _mm256_set1_epi16(pm.saturating_add(p2) as i16);
            v_pmin[k] = _mm256_set1_epi16(pm as i16);
        }
        let hp = hp.add(SENT);
        let hc = hcur.add(SENT);
        let mut hmin_v = _mm256_set1_epi16(-1);
        let mut vmin_v = [_mm256_set1_epi16(-1); NDIRS];
        let mut smin_v = _mm256_set1_epi16(-1);
        let mut l = 0;
        while l < ndp {
            let cv = _mm256_cvtepu8_epi16(_mm_loadu_si128(cp.add(l) as *const __m128i));
            let padv = if l == last { pad } else { _mm256_setzero_si256() };
            let lh = _mm256_or_si256(lane_step_fresh(hp.add(l), cv, vp1, h_pm2, h_pmin), padv);
            _mm256_storeu_si256(hc.add(l) as *mut __m256i, lh);
            hmin_v = _mm256_min_epu16(hmin_v, lh);
            let mut s = if !SECOND {
                lh
            } else if NARROW {
                _mm256_adds_epu16(_mm256_cvtepu8_epi16(_mm_loadu_si128(sp8.add(l) as *const __m128i)), lh)
            } else {
                _mm256_adds_epu16(_mm256_loadu_si256(sp.add(l) as *const __m256i), lh)
            };
            for k in 0..NDIRS {
                let lv = _mm256_or_si256(lane_step(vp[k].add(l), cv, vp1, v_pm2[k], v_pmin[k]), padv);
                _mm256_storeu_si256(j.cur.as_mut_ptr().add((k * w + x) * stride + SENT + l) as *mut __m256i, lv);
                vmin_v[k] = _mm256_min_epu16(vmin_v[k], lv);
                s = _mm256_adds_epu16(s, lv);
            }
            if SECOND {
                _mm256_storeu_si256(sbuf.as_mut_ptr().add(l) as *mut __m256i, s);
                smin_v = _mm256_min_epu16(smin_v, s);
            } else if NARROW {
                // u16 → u8 with unsigned saturation (exact on data lanes), lanes back in order.
                let p = _mm256_permute4x64_epi64(_mm256_packus_epi16(s, s), 0b1000);
                _mm_storeu_si128(sp8.add(l) as *mut __m128i, _mm256_castsi256_si128(p));
            } else {
                _mm256_storeu_si256(sp.add(l) as *mut __m256i, s);
            }
            l += 16;
        }
        m = hmin16(hmin_v);
        for (k, v) in vmin_v.iter().enumerate() {
            *j.cmin.get_unchecked_mut(k * w + x) = hmin16(*v);
        }
        if SECOND {
            *j.sel.get_unchecked_mut(x) = super::select::select_avx2_min(&sbuf[..ndp], nd, ndp, hmin16(smin_v));
        }
        std::mem::swap(&mut hcur, &mut hprev);
    }
}

/// One sweep over the rows, forward (top→bottom: left→right, top→bottom and, with `eight`, the
/// two downward diagonals) or backward (bottom→top: right→left, bottom→top, upward diagonals).
/// All paths of a pixel are processed together so that its S stays in registers. A sweep is
/// sequential over rows; the forward and the backward sweep run in parallel
/// ([`aggregate_select`]), meeting in [`RowSlot`]s.
pub fn sweep(inp: &Inputs, forward: bool, eight: bool, slots: &[std::sync::Mutex<RowSlot>], finish: &RowFinish) {
    let g = inp.g;
    let (w, h, ndp) = (g.w, inp.h, g.ndp);
    let (mut ha, mut hb) = (path_buffer(ndp), path_buffer(ndp));
    let n_dirs = if eight { 3 } else { 1 }; // vertical, diagonal from x − 1, diagonal from x + 1
    let mut prev = zero_paths(n_dirs * w, ndp);
    let mut cur = zero_paths(n_dirs * w, ndp);
    let zero = zero_paths(1, ndp);
    let mut pmin = vec![0u16; n_dirs * w];
    let mut cmin = vec![0u16; n_dirs * w];
    // P2 by |ΔI| (the division of `p2_at` once per grey step, not per pixel and path).
    let mut p2_lut = [0u16; 256];
    for (di, v) in p2_lut.iter_mut().enumerate() {
        *v = inp.pen.p2_at(di as u8, 0);
    }
    for step in 0..h {
        let y = if forward { step } else { h - 1 - step };
        let yp = if forward { y.wrapping_sub(1) } else { y + 1 };
        let gray = &inp.gray_l[y * w..(y + 1) * w];
        let gprev = if step > 0 { &inp.gray_l[yp * w..(yp + 1) * w] } else { gray };
        let mut guard = slots[y].lock().unwrap_or_else(|e| e.into_inner());
        let slot = &mut *guard;
        let second = slot.done;
        if !second {
            let rows = tolerance_rows(inp.census_r, w, h, y, inp.vtol);
            row_costs(inp.avx2, &g, 0, w, &inp.census_l[y * w..(y + 1) * w], &rows, slot.cost);
        }
        let mut job = RowJob {
            forward,
            first_row: step == 0,
            n_dirs,
            w,
            nd: g.nd,
            ndp,
            p1: inp.pen.p1,
            p2_lut: &p2_lut,
            gray,
            gprev,
            cost: slot.cost,
            prev: &prev,
            pmin: &pmin,
            cur: &mut cur,
            cmin: &mut cmin,
            zero: &zero,
            s: slot.s,
            s8: slot.s8,
            narrow: inp.narrow,
            sel: slot.sel,
            second,
        };
        run_row(inp.avx2, &mut job, &mut ha, &mut hb);
        if second {
            finish(y, slot.sel);
        }
        slot.done = true;
        drop(guard);
        std::mem::swap(&mut prev, &mut cur);
        std::mem::swap(&mut pmin, &mut cmin);
    }
}

/// Dispatch a row to the AVX2 or the portable kernel.
fn run_row(avx2: bool, job: &mut RowJob, ha: &mut Vec<u16>, hb: &mut Vec<u16>) {
    #[cfg(target_arch = "x86_64")]
    if avx2 {
        // SAFETY: `avx2` is only true when AVX2, popcnt and BMI1 were detected at run time.
        unsafe {
            match (job.n_dirs, job.second, job.narrow) {
                (1, false, false) => row_avx2::<1, false, false>(job, ha, hb),
                (1, true, false) => row_avx2::<1, true, false>(job, ha, hb),
                (1, false, true) => row_avx2::<1, false, true>(job, ha, hb),
                (1, true, true) => row_avx2::<1, true, true>(job, ha, hb),
                (_, false, _) => row_avx2::<3, false, false>(job, ha, hb),
                (_, true, _) => row_avx2::<3, true, false>(job, ha, hb),
            }
        }
        return;
    }
    let _ = avx2;
    row_scalar(job, ha, hb)
}

/// Aggregate all paths (eq. 14) and select (see [`super::select`]): the forward and the backward
/// [`sweep`] in parallel (`rayon::join`) over one shared S volume and one cost volume; each row's
/// selections go to `finish` once.
pub(crate) fn aggregate_select(inp: &Inputs, eight: bool, finish: &RowFinish, ws: &mut Volumes) {
    let (w, h, ndp) = (inp.g.w, inp.h, inp.g.ndp);
    assert!(!inp.narrow || !eight, "byte partial sums need 4 paths");
    let n = w * h * ndp;
    let mut s = take(&mut ws.s, if inp.narrow { 0 } else { n });
    let mut s8 = take(&mut ws.s8, if inp.narrow { n } else { 0 });
    let mut cost = take(&mut ws.cost, n);
    let mut sel = take(&mut ws.sel, w * h);
    {
        // Row slices of whichever S volume is used, empty slices for the other.
        let s_rows = s.chunks_mut(w * ndp).chain(std::iter::repeat_with(|| &mut [][..]));
        let s8_rows = s8.chunks_mut(w * ndp).chain(std::iter::repeat_with(|| &mut [][..]));
        let slots: Vec<std::sync::Mutex<RowSlot>> = s_rows
            .zip(s8_rows)
            .zip(cost.chunks_mut(w * ndp))
            .zip(sel.chunks_mut(w))
            .map(|(((s, s8), cost), sel)| std::sync::Mutex::new(RowSlot { done: false, s, s8, cost, sel }))
            .collect();
        rayon::join(|| sweep(inp, true, eight, &slots, finish), || sweep(inp, false, eight, &slots, finish));
    }
    put_back(&mut ws.s, s);
    put_back(&mut ws.s8, s8);
    put_back(&mut ws.cost, cost);
    put_back(&mut ws.sel, sel);
}

/// What the second sweep does with each finished row `y` and its selections (the post-processing
/// of [`super::match_gray`], run while the row is hot and split between the two sweeps).
pub type RowFinish<'a> = dyn Fn(usize, &[Selection]) + Sync + 'a;

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
