//! Disparity selection (Hirschmüller 2008, §3.3): winner-takes-all `d_p = argmin_d S(p, d)`
//! (ties to the smaller d), the uniqueness test (the best cost must beat every disparity not
//! adjacent to it by `uniqueness` percent, as OpenCV's `uniquenessRatio`), and sub-pixel
//! refinement by a parabola through `S(d − 1), S(d), S(d + 1)`:
//! `d* = d + (S(d−1) − S(d+1)) / (2 (S(d−1) + S(d+1) − 2 S(d)))`.

/// Result of the selection at one pixel (costs are aggregated S values).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Selection {
    /// Index of the best disparity (0-based, d = d_min + best).
    pub best: u16,
    /// S at the best disparity.
    pub smin: u16,
    /// Smallest S over disparities not adjacent to the best (0xFFFF if none).
    pub second: u16,
    /// S(best − 1) (0xFFFF at the range start).
    pub left: u16,
    /// S(best + 1) (0xFFFF at the range end).
    pub right: u16,
}

impl Selection {
    /// Whether the best disparity passes the uniqueness test with `pct` percent (0 = always):
    /// `second · (100 − pct) ≥ best · 100`.
    #[inline]
    pub fn unique(&self, pct: u8) -> bool {
        pct == 0 || self.second as u32 * (100 - pct.min(99) as u32) >= self.smin as u32 * 100
    }

    /// Sub-pixel offset in [−0.5, 0.5] of the parabola fit (0 at the ends of the range or on a
    /// flat triple), rounded to 1/256 px so that `d_min + best + offset` is exact in f32 for
    /// |d| < 32768 (a shift of the range then shifts the output bit for bit).
    #[inline]
    pub fn subpixel_offset(&self) -> f32 {
        if self.left == 0xFFFF || self.right == 0xFFFF {
            return 0.0;
        }
        let (l, r, c) = (self.left as i32, self.right as i32, self.smin as i32);
        let den = l + r - 2 * c;
        if den <= 0 {
            return 0.0;
        }
        round_half_away((l - r) as f32 / (2 * den) as f32 * 256.0) / 256.0
    }

    /// Confidence in [0, 1]: `(second − best) / second` (0 when second is 0).
    #[inline]
    pub fn confidence(&self) -> f32 {
        if self.second == 0 {
            return 0.0;
        }
        (self.second - self.smin) as f32 / self.second as f32
    }
}

/// `v.round()` (half away from zero, sign kept) for |v| < 2³¹ without a libm call (the
/// baseline x86-64 target has no `roundss`).
#[inline(always)]
fn round_half_away(v: f32) -> f32 {
    let t = v as i32;
    let f = v - t as f32; // exact: t and v share their integer part
    let r = t + (f >= 0.5) as i32 - (f <= -0.5) as i32; // branch-free: f is data
    (r as f32).copysign(v)
}

/// Selection over `s[..nd]` (portable).
#[inline(always)]
pub fn select_scalar(s: &[u16], nd: usize) -> Selection {
    let mut best = 0usize;
    let mut smin = u16::MAX;
    for (d, &v) in s[..nd].iter().enumerate() {
        if v < smin {
            smin = v;
            best = d;
        }
    }
    let mut second = u16::MAX;
    for (d, &v) in s[..nd].iter().enumerate() {
        if d + 1 < best || d > best + 1 {
            second = second.min(v);
        }
    }
    finish(s, nd, best, smin, second)
}

#[inline(always)]
fn finish(s: &[u16], nd: usize, best: usize, smin: u16, second: u16) -> Selection {
    Selection {
        best: best as u16,
        smin,
        second,
        left: if best > 0 { s[best - 1] } else { 0xFFFF },
        right: if best + 1 < nd { s[best + 1] } else { 0xFFFF },
    }
}

/// AVX2 version of [`select_scalar`]; `s` has `ndp` lanes (multiple of 16) whose lanes ≥ nd
/// hold 0xFFFF.
///
/// # Safety
/// AVX2 must be available.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,bmi1")]
#[cfg(test)]
pub unsafe fn select_avx2(s: &[u16], nd: usize, ndp: usize) -> Selection {
    use std::arch::x86_64::*;
    debug_assert!(s.len() >= ndp && ndp.is_multiple_of(16));
    let p = s.as_ptr();
    let mut vmin = _mm256_set1_epi16(-1);
    let mut j = 0;
    while j < ndp {
        vmin = _mm256_min_epu16(vmin, _mm256_loadu_si256(p.add(j) as *const __m256i));
        j += 16;
    }
    let hmin = |v: __m256i| -> u16 {
        let m = _mm_min_epu16(_mm256_castsi256_si128(v), _mm256_extracti128_si256(v, 1));
        _mm_extract_epi16(_mm_minpos_epu16(m), 0) as u16
    };
    select_avx2_min(s, nd, ndp, hmin(vmin))
}

/// [`select_avx2`] given the minimum `smin` of `s[..ndp]`.
///
/// # Safety
/// AVX2 must be available.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,bmi1")]
#[inline]
pub unsafe fn select_avx2_min(s: &[u16], nd: usize, ndp: usize, smin: u16) -> Selection {
    use std::arch::x86_64::*;
    debug_assert!(s.len() >= ndp && ndp.is_multiple_of(16));
    let p = s.as_ptr();
    let hmin = |v: __m256i| -> u16 {
        let m = _mm_min_epu16(_mm256_castsi256_si128(v), _mm256_extracti128_si256(v, 1));
        _mm_extract_epi16(_mm_minpos_epu16(m), 0) as u16
    };
    let target = _mm256_set1_epi16(smin as i16);
    let mut best = 0usize;
    let mut j = 0;
    while j < ndp {
        let eq = _mm256_cmpeq_epi16(_mm256_loadu_si256(p.add(j) as *const __m256i), target);
        let mask = _mm256_movemask_epi8(eq) as u32;
        if mask != 0 {
            best = j + (mask.trailing_zeros() as usize) / 2;
            break;
        }
        j += 16;
    }
    // Second minimum outside [best − 1, best + 1].
    let lane = _mm256_setr_epi16(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
    let lo = _mm256_set1_epi16(best as i16 - 2);
    let hi = _mm256_set1_epi16(best as i16 + 2);
    let mut vsec = _mm256_set1_epi16(-1);
    j = 0;
    while j < ndp {
        let dl = _mm256_add_epi16(lane, _mm256_set1_epi16(j as i16));
        let near = _mm256_and_si256(_mm256_cmpgt_epi16(dl, lo), _mm256_cmpgt_epi16(hi, dl));
        let v = _mm256_or_si256(_mm256_loadu_si256(p.add(j) as *const __m256i), near);
        vsec = _mm256_min_epu16(vsec, v);
        j += 16;
    }
    finish(s, nd, best, smin, hmin(vsec))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rounding_as_std() {
        for v in [0.0f32, -0.0, 0.3, -0.3, 0.5, -0.5, 1.5, -1.5, 2.5, 127.49998, -127.5, 0.49999997, -0.49999997] {
            assert_eq!(round_half_away(v).to_bits(), v.round().to_bits(), "{v}");
        }
    }

    #[test]
    fn selection_by_hand() {
        let mut s = vec![0xFFFFu16; 16];
        s[..6].copy_from_slice(&[50, 40, 12, 20, 11, 60]);
        let sel = select_scalar(&s, 6);
        assert_eq!(sel, Selection { best: 4, smin: 11, second: 12, left: 20, right: 60 });
        // parabola through (3, 20), (4, 11), (5, 60): offset (20 − 60) / (2 · 58)
        assert_eq!(sel.subpixel_offset(), (-40.0f32 / 116.0 * 256.0).round() / 256.0);
        assert!(sel.unique(5) && !sel.unique(10));
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("bmi1") {
            assert_eq!(unsafe { select_avx2(&s, 6, 16) }, sel);
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx2_selection_matches_scalar_on_random_costs() {
        if !(std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("bmi1")) {
            eprintln!("SKIP: no AVX2");
            return;
        }
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        for nd in [1usize, 2, 3, 15, 16, 33, 64, 128] {
            let ndp = nd.div_ceil(16) * 16;
            for _ in 0..200 {
                let mut s = vec![0xFFFFu16; ndp];
                for v in &mut s[..nd] {
                    *v = rng.gen_range(0..40);
                }
                assert_eq!(unsafe { select_avx2(&s, nd, ndp) }, select_scalar(&s, nd), "nd {nd}: {s:?}");
            }
        }
    }
}
