//! Gaussian and difference-of-Gaussian scale spaces (Lowe 2004 §3; OpenCV `buildGaussianPyramid`,
//! `buildDoGPyramid`): octave base blurred to σ₀, layers σ₀·2^(i/S) by incremental blurs
//! √(σᵢ² − σᵢ₋₁²), next octave = every second pixel of layer S.
use laparo_core::remap::bilerp;
use rayon::prelude::*;

use super::blur::{gaussian_blur, Plane};

/// Blur assumed already present in the input image, px (OpenCV `SIFT_INIT_SIGMA`).
const INIT_SIGMA: f64 = 0.5;

/// Grey u8 → f32 octave base: optional 2× bilinear upsampling (pixel-centre aligned, edge
/// clamped), then a blur bringing the assumed 0.5 px (1 px after doubling) up to `sigma`.
pub fn initial_image(gray: &[u8], w: usize, h: usize, sigma: f64, upsample: bool) -> Plane {
    let src = Plane { w, h, data: gray.iter().map(|&v| v as f32).collect() };
    if !upsample {
        let d = (sigma * sigma - INIT_SIGMA * INIT_SIGMA).max(0.01).sqrt();
        return gaussian_blur(&src, d);
    }
    // Sample positions (x + 0.5)/2 − 0.5: even x = 2i → 0.25·s[i−1] + 0.75·s[i], odd → 0.75·s[i] + 0.25·s[i+1],
    // edges clamped: `laparo_core::remap::resize` bit for bit (tested), with the taps of the exact 2×
    // case written out so the hot loop has no per-pixel floor or validity test (SIFT's largest image).
    let (w2, h2) = (2 * w, 2 * h);
    let tap = |i2: usize, n: usize| -> (usize, usize, f32) {
        let i = i2 / 2;
        if i2.is_multiple_of(2) {
            if i == 0 {
                (0, 0, 0.0)
            } else {
                (i - 1, i, 0.75)
            }
        } else if i + 1 >= n {
            (n - 1, n - 1, 0.0)
        } else {
            (i, i + 1, 0.25)
        }
    };
    let xt: Vec<_> = (0..w2).map(|x| tap(x, w)).collect();
    let mut up = vec![0f32; w2 * h2];
    up.par_chunks_mut(w2).enumerate().for_each(|(y, out)| {
        let (y0, y1, fy) = tap(y, h);
        let (r0, r1) = (src.row(y0), src.row(y1));
        for (o, &(x0, x1, fx)) in out.iter_mut().zip(&xt) {
            *o = bilerp(r0[x0], r0[x1], r1[x0], r1[x1], fx, fy, false);
        }
    });
    let d = (sigma * sigma - 4.0 * INIT_SIGMA * INIT_SIGMA).max(0.01).sqrt();
    gaussian_blur(&Plane { w: w2, h: h2, data: up }, d)
}

/// Number of octaves for a base of `w`×`h` (OpenCV: round(log₂ min(w, h) − 2), first octave
/// counted; at least 1).
pub fn n_octaves(w: usize, h: usize, upsample: bool) -> usize {
    let m = w.min(h).max(1) as f64;
    // With upsampling OpenCV counts on the doubled base and adds one for first octave −1.
    let n = if upsample { ((2.0 * m).log2() - 2.0).round() as i64 + 1 } else { (m.log2() - 2.0).round() as i64 };
    n.max(1) as usize
}

/// Incremental blurs between layers: σ₀, then √(σᵢ² − σᵢ₋₁²) with σᵢ = σ₀·2^(i/S).
pub fn layer_sigmas(sigma: f64, s: usize) -> Vec<f64> {
    let k = 2f64.powf(1.0 / s as f64);
    let mut out = vec![sigma];
    for i in 1..s + 3 {
        let prev = k.powi(i as i32 - 1) * sigma;
        let total = prev * k;
        out.push((total * total - prev * prev).sqrt());
    }
    out
}

/// Every second pixel (OpenCV `resize(…, INTER_NEAREST)` to half size).
fn halve(p: &Plane) -> Plane {
    let (w, h) = (p.w / 2, p.h / 2);
    let mut data = Vec::with_capacity(w * h);
    for y in 0..h {
        let r = p.row(2 * y);
        data.extend((0..w).map(|x| r[2 * x]));
    }
    Plane { w, h, data }
}

/// Gaussian pyramid: `octaves` × (S + 3) layers.
pub fn gaussian_pyramid(base: Plane, octaves: usize, s: usize, sigma: f64) -> Vec<Vec<Plane>> {
    let sig = layer_sigmas(sigma, s);
    let mut pyr: Vec<Vec<Plane>> = Vec::with_capacity(octaves);
    let mut first = Some(base);
    for o in 0..octaves {
        let b = match first.take() {
            Some(b) => b,
            None => {
                let prev: &Plane = &pyr[o - 1][s];
                if prev.w < 2 || prev.h < 2 {
                    break;
                }
                halve(prev)
            }
        };
        let mut layers = vec![b];
        for &si in &sig[1..] {
            let next = gaussian_blur(layers.last().expect("non-empty"), si);
            layers.push(next);
        }
        pyr.push(layers);
    }
    pyr
}

/// DoG layers `G[i+1] − G[i]`, S + 2 per octave.
pub fn dog_pyramid(g: &[Vec<Plane>]) -> Vec<Vec<Plane>> {
    g.iter()
        .map(|oct| {
            oct.windows(2)
                .map(|p| Plane {
                    w: p[0].w,
                    h: p[0].h,
                    data: p[1].data.iter().zip(&p[0].data).map(|(a, b)| a - b).collect(),
                })
                .collect()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn octave_count_matches_opencv() {
        // 640×480 doubled: round(log₂ 960 − 2) = round(7.91) = 8, + 1 for octave −1 = 9.
        assert_eq!(n_octaves(640, 480, true), 9);
        // Not doubled: round(log₂ 480 − 2) = 7.
        assert_eq!(n_octaves(640, 480, false), 7);
    }

    #[test]
    fn layer_sigmas_compose_to_the_geometric_series() {
        let s = layer_sigmas(1.6, 3);
        let mut tot = 1.6f64;
        for (i, si) in s.iter().enumerate().skip(1) {
            tot = (tot * tot + si * si).sqrt();
            assert!((tot - 1.6 * 2f64.powf(i as f64 / 3.0)).abs() < 1e-12);
        }
    }

    #[test]
    fn upsampling_equals_the_core_resize_bit_for_bit() {
        let (w, h) = (13, 7);
        let g: Vec<u8> = (0..w * h).map(|i| ((i * 97 + 31) % 256) as u8).collect();
        let img = laparo_core::Image::from_vec(w, h, 1, g.iter().map(|&v| v as f32).collect()).unwrap();
        let (r, _) = laparo_core::remap::resize(&img, 2 * w, 2 * h, laparo_core::remap::Interp::Bilinear, 0.0).unwrap();
        // Same positions and arithmetic; compare before the blur by undoing nothing: blur both.
        let ours = initial_image(&g, w, h, 1.6, true);
        let d = (1.6f64 * 1.6 - 4.0 * INIT_SIGMA * INIT_SIGMA).max(0.01).sqrt();
        let theirs = gaussian_blur(&Plane { w: 2 * w, h: 2 * h, data: r.data }, d);
        assert_eq!(ours.data, theirs.data);
    }

    #[test]
    fn upsampling_interpolates_at_quarter_offsets() {
        // Row [0, 4, 8]: doubled = [0, 1, 3, 5, 7, 8] before the blur (checked with a tiny σ).
        let p = initial_image(&[0, 4, 8], 3, 1, 1.0, true);
        assert_eq!(p.w, 6);
        // σ_diff = √max(1 − 1, 0.01) = 0.1: kernel size 1, so no blur.
        for (a, b) in p.data.iter().zip([0.0, 1.0, 3.0, 5.0, 7.0, 8.0]) {
            assert!((a - b).abs() < 1e-6, "{:?}", p.data);
        }
    }
}
