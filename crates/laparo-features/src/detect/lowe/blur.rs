//! Separable Gaussian blur of an f32 plane (OpenCV `GaussianBlur`: kernel size round(8σ + 1) | 1,
//! border reflect-101), vertical pass then horizontal pass per output row. The AVX2 path (runtime
//! dispatch) and the portable path run the same code with the same operation order and no FMA,
//! so they are bit-identical: `d = k₀·s₀`, then `d += kₜ·(s₋ₜ + s₊ₜ)` for t = 1 … r.
use rayon::prelude::*;

/// A single-channel f32 image, row-major.
#[derive(Clone, Debug, PartialEq)]
pub struct Plane {
    /// Columns.
    pub w: usize,
    /// Rows.
    pub h: usize,
    /// Row-major values, `w · h`.
    pub data: Vec<f32>,
}

impl Plane {
    /// Row `y`.
    #[inline]
    pub fn row(&self, y: usize) -> &[f32] {
        &self.data[y * self.w..(y + 1) * self.w]
    }

    /// Value at (x, y).
    #[inline]
    pub fn at(&self, x: usize, y: usize) -> f32 {
        self.data[y * self.w + x]
    }
}

/// Reflect-101 index into 0 … n−1 (`cba|abcd|dcb`; n = 1 maps everything to 0).
pub fn reflect101(i: isize, n: usize) -> usize {
    let n = n as isize;
    if n == 1 {
        return 0;
    }
    let mut i = i;
    while i < 0 || i >= n {
        i = if i < 0 { -i } else { 2 * n - 2 - i };
    }
    i as usize
}

/// Half of the normalised Gaussian kernel, [k₀, k₁, …, k_r], size round(8σ + 1) | 1 (OpenCV
/// `getGaussianKernel` for float images: g_i ∝ exp(−x_i² / 2σ²), computed in f64, summing to 1).
pub fn half_kernel(sigma: f64) -> Vec<f32> {
    let n = ((sigma * 8.0 + 1.0).round() as usize) | 1;
    let r = n / 2;
    let g: Vec<f64> = (0..n).map(|i| (-((i as f64 - r as f64).powi(2)) / (2.0 * sigma * sigma)).exp()).collect();
    let s: f64 = g.iter().sum();
    g[r..].iter().map(|v| (v / s) as f32).collect()
}

/// `dst[x] = k₀·c[x] + Σₜ kₜ·(aₜ[x] + bₜ[x])`, accumulated in the order t = 1 … r.
#[inline(always)]
fn accumulate_impl(dst: &mut [f32], c: &[f32], pairs: &[(&[f32], &[f32])], k: &[f32]) {
    let k0 = k[0];
    for (d, &v) in dst.iter_mut().zip(c) {
        *d = k0 * v;
    }
    for (t, (a, b)) in pairs.iter().enumerate() {
        let kt = k[t + 1];
        let (a, b) = (&a[..dst.len()], &b[..dst.len()]);
        for ((d, &x), &y) in dst.iter_mut().zip(a).zip(b) {
            *d += kt * (x + y);
        }
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn accumulate_avx2(dst: &mut [f32], c: &[f32], pairs: &[(&[f32], &[f32])], k: &[f32]) {
    accumulate_impl(dst, c, pairs, k)
}

/// Portable path (SSE2 at most on x86-64), bit-identical to the AVX2 path.
pub fn accumulate_portable(dst: &mut [f32], c: &[f32], pairs: &[(&[f32], &[f32])], k: &[f32]) {
    accumulate_impl(dst, c, pairs, k)
}

/// Runtime-dispatched symmetric accumulation (AVX2 when present).
#[inline]
pub fn accumulate(dst: &mut [f32], c: &[f32], pairs: &[(&[f32], &[f32])], k: &[f32]) {
    #[cfg(target_arch = "x86_64")]
    if is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2 (checked just above).
        unsafe { accumulate_avx2(dst, c, pairs, k) };
        return;
    }
    accumulate_portable(dst, c, pairs, k)
}

/// Gaussian blur with standard deviation `sigma` (px), border reflect-101.
pub fn gaussian_blur(src: &Plane, sigma: f64) -> Plane {
    gaussian_blur_with(src, sigma, accumulate)
}

/// Gaussian blur through a given accumulation kernel (tests compare the paths bit for bit).
pub fn gaussian_blur_with(src: &Plane, sigma: f64, acc: AccumulateFn) -> Plane {
    separable_blur(src, &half_kernel(sigma), acc)
}

/// Signature of the symmetric accumulation kernels.
pub type AccumulateFn = fn(&mut [f32], &[f32], &[(&[f32], &[f32])], &[f32]);

/// Blur by the symmetric separable kernel with half `k` = [k₀, k₁, …, k_r] (reflect-101).
pub fn separable_blur(src: &Plane, k: &[f32], acc: AccumulateFn) -> Plane {
    separable_blur_rows(src, k, acc, None)
}

/// `separable_blur` of the output rows with `rows[y]` true only (others 0); `None` = all.
pub fn separable_blur_rows(src: &Plane, k: &[f32], acc: AccumulateFn, rows: Option<&[bool]>) -> Plane {
    let r = k.len() - 1;
    let (w, h) = (src.w, src.h);
    let mut data = vec![0f32; w * h];
    if w == 0 || h == 0 {
        return Plane { w, h, data };
    }
    data.par_chunks_mut(w).enumerate().for_each_init(
        || vec![0f32; w + 2 * r],
        |tmp, (y, out)| {
            if rows.is_some_and(|m| !m[y]) {
                return;
            }
            // Vertical pass into the middle of a padded row.
            let rows: Vec<(&[f32], &[f32])> = (1..=r)
                .map(|t| {
                    let a = reflect101(y as isize - t as isize, h);
                    let b = reflect101(y as isize + t as isize, h);
                    (src.row(a), src.row(b))
                })
                .collect();
            acc(&mut tmp[r..r + w], src.row(y), &rows, k);
            // Reflect-101 padding of the row, then the horizontal pass.
            for i in 0..r {
                tmp[r - 1 - i] = tmp[r + reflect101(-(i as isize) - 1, w)];
                tmp[r + w + i] = tmp[r + reflect101((w + i) as isize, w)];
            }
            let tmp: &[f32] = tmp;
            let pairs: Vec<(&[f32], &[f32])> =
                (1..=r).map(|t| (&tmp[r - t..r - t + w], &tmp[r + t..r + t + w])).collect();
            acc(out, &tmp[r..r + w], &pairs, k);
        },
    );
    Plane { w, h, data }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn noise(w: usize, h: usize) -> Plane {
        let mut s = 12345u32;
        let data = (0..w * h)
            .map(|_| {
                s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                (s >> 24) as f32
            })
            .collect();
        Plane { w, h, data }
    }

    #[test]
    fn kernel_is_normalised_with_opencv_size() {
        // σ = 1.6: round(13.8) | 1 = 15 taps → r = 7.
        let k = half_kernel(1.6);
        assert_eq!(k.len(), 8);
        let s: f32 = k[0] + 2.0 * k[1..].iter().sum::<f32>();
        assert!((s - 1.0).abs() < 1e-6);
    }

    #[test]
    fn avx2_and_portable_paths_are_bit_identical() {
        for (w, h, s) in [(37, 23, 1.249), (100, 60, 3.09), (5, 4, 2.0), (1, 9, 1.6)] {
            let p = noise(w, h);
            let a = gaussian_blur_with(&p, s, accumulate);
            let b = gaussian_blur_with(&p, s, accumulate_portable);
            assert!(a.data.iter().zip(&b.data).all(|(x, y)| x.to_bits() == y.to_bits()), "{w}x{h}");
        }
    }

    #[test]
    fn constant_is_preserved_and_impulse_gives_the_kernel() {
        let c = Plane { w: 30, h: 20, data: vec![7.0; 600] };
        assert!(gaussian_blur(&c, 1.6).data.iter().all(|&v| (v - 7.0).abs() < 1e-5));
        let mut d = Plane { w: 41, h: 41, data: vec![0.0; 41 * 41] };
        d.data[20 * 41 + 20] = 1.0;
        let b = gaussian_blur(&d, 1.6);
        let k = half_kernel(1.6);
        // Separable: out(20 + i, 20 + j) = k_i · k_j.
        assert!((b.at(20, 20) - k[0] * k[0]).abs() < 1e-9);
        assert!((b.at(23, 22) - k[3] * k[2]).abs() < 1e-9);
    }
}
