//! Sub-pixel refinement of point matches at full resolution: the left point is fixed at its
//! nearest pixel, the right point moves to the peak of the normalised cross-correlation (NCC)
//! of a square patch over integer offsets around its prediction, refined by a parabola through
//! the peak and its two neighbours in x and in y (Δ = (s₋ − s₊) / (2 (s₋ − 2 s₀ + s₊))), then by
//! a few inverse-compositional Lucas–Kanade steps (translation, mean-offset invariant), which
//! remove the parabola's pull towards integer offsets.
//!
//! Integer sums (i64) make the NCC exact; every match is computed on its own in scalar f64, so the
//! result is independent of thread count and CPU.
use laparo_core::image::Image;
use rayon::prelude::*;

use crate::error::{FeaturesError, Result};

/// Options of [`refine_matches_ncc`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RefineParams {
    /// Patch half-size: the patch is (2 half + 1)² px (5 → 11 × 11).
    pub half: usize,
    /// Integer search radius around the predicted right point, px (the peak must lie strictly inside).
    pub radius: usize,
    /// Smallest accepted NCC at the peak (matches below are dropped).
    pub min_ncc: f64,
    /// Lucas–Kanade iterations after the parabola (0 = parabola only).
    pub lk_iters: usize,
}

impl Default for RefineParams {
    fn default() -> Self {
        RefineParams { half: 5, radius: 3, min_ncc: 0.8, lk_iters: 10 }
    }
}

/// One refined match: left pixel (integer), right point (sub-pixel), peak NCC.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Refined {
    /// Left point `[x, y]` (the rounded input point), px.
    pub left: [f64; 2],
    /// Right point `[x, y]`, sub-pixel, px.
    pub right: [f64; 2],
    /// NCC at the integer peak.
    pub ncc: f64,
}

/// Σa, Σa² of the patch of `img` centred at (x, y) (caller checks bounds).
#[inline]
fn patch_sums(img: &Image<u8>, x: usize, y: usize, h: usize) -> (i64, i64) {
    let (mut s, mut s2) = (0i64, 0i64);
    for r in y - h..=y + h {
        for &v in &img.data[r * img.width + x - h..=r * img.width + x + h] {
            s += v as i64;
            s2 += (v as i64) * (v as i64);
        }
    }
    (s, s2)
}

/// NCC of the left patch at (lx, ly) (sums sa, var_a = n Σa² − (Σa)²) and the right patch at (rx, ry).
#[inline]
fn ncc(
    a: &Image<u8>,
    b: &Image<u8>,
    (lx, ly): (usize, usize),
    (rx, ry): (usize, usize),
    h: usize,
    sa: i64,
    var_a: i64,
) -> f64 {
    let n = ((2 * h + 1) * (2 * h + 1)) as i64;
    let (mut sb, mut sb2, mut sab) = (0i64, 0i64, 0i64);
    for k in 0..=2 * h {
        let ra = &a.data[(ly - h + k) * a.width + lx - h..=(ly - h + k) * a.width + lx + h];
        let rb = &b.data[(ry - h + k) * b.width + rx - h..=(ry - h + k) * b.width + rx + h];
        let (mut s1, mut s2, mut s3) = (0u32, 0u32, 0u32);
        for (&u, &v) in ra.iter().zip(rb) {
            s1 += v as u32;
            s2 += (v as u32) * (v as u32);
            s3 += (u as u32) * (v as u32);
        }
        sb += s1 as i64;
        sb2 += s2 as i64;
        sab += s3 as i64;
    }
    let var_b = n * sb2 - sb * sb;
    if var_a <= 0 || var_b <= 0 {
        return -1.0;
    }
    (n * sab - sa * sb) as f64 / ((var_a as f64) * (var_b as f64)).sqrt()
}

/// Parabola vertex offset through (−1, s₋), (0, s₀), (1, s₊), clamped to ±0.5.
#[inline]
fn vertex(sm: f64, s0: f64, sp: f64) -> f64 {
    let den = sm - 2.0 * s0 + sp;
    if den >= 0.0 {
        return 0.0;
    }
    (0.5 * (sm - sp) / den).clamp(-0.5, 0.5)
}

/// Inverse-compositional Lucas–Kanade (Baker & Matthews 2004) for a translation with a
/// mean-offset invariance: minimise Σ ((I(x + p) − Ī) − (T(x) − T̄))² over p, T = the left
/// patch (central-difference gradients ∇T, constant Hessian H = Σ ∇T ∇Tᵀ), Δp = H⁻¹ Σ ∇T e,
/// p ← p − Δp. `None` when H is singular, the patch leaves `b` or p moves by more than 1 px.
fn lk_refine(
    a: &Image<u8>,
    b: &Image<u8>,
    (lx, ly): (usize, usize),
    r0: [f64; 2],
    h: usize,
    iters: usize,
) -> Option<[f64; 2]> {
    let hi = h as i64;
    if lx < h + 1 || ly < h + 1 || lx + h + 1 >= a.width || ly + h + 1 >= a.height {
        return None;
    }
    let side = 2 * h + 1;
    let (mut t, mut gx, mut gy) = (vec![0f64; side * side], vec![0f64; side * side], vec![0f64; side * side]);
    let at = |x: usize, y: usize| a.data[y * a.width + x] as f64;
    for j in 0..side {
        for i in 0..side {
            let (x, y) = (lx + i - h, ly + j - h);
            t[j * side + i] = at(x, y);
            gx[j * side + i] = 0.5 * (at(x + 1, y) - at(x - 1, y));
            gy[j * side + i] = 0.5 * (at(x, y + 1) - at(x, y - 1));
        }
    }
    let n = (side * side) as f64;
    let tm = t.iter().sum::<f64>() / n;
    let (mut hxx, mut hxy, mut hyy) = (0.0, 0.0, 0.0);
    let (mx, my) = (gx.iter().sum::<f64>() / n, gy.iter().sum::<f64>() / n);
    for k in 0..side * side {
        // gradients of the mean-subtracted template (the mean term projects out)
        let (u, v) = (gx[k] - mx, gy[k] - my);
        gx[k] = u;
        gy[k] = v;
        hxx += u * u;
        hxy += u * v;
        hyy += v * v;
    }
    let det = hxx * hyy - hxy * hxy;
    if det <= 1e-9 * (hxx * hyy).max(1e-300) {
        return None;
    }
    let mut r = r0;
    let mut ib = vec![0f64; side * side];
    for _ in 0..iters {
        let (x0, y0) = (r[0] - h as f64, r[1] - h as f64);
        if x0 < 0.0
            || y0 < 0.0
            || x0 + 2.0 * hi as f64 + 1.0 >= b.width as f64
            || y0 + 2.0 * hi as f64 + 1.0 >= b.height as f64
        {
            return None;
        }
        for j in 0..side {
            for i in 0..side {
                // in bounds (checked above): the sampler of laparo_core::remap, f64
                ib[j * side + i] = b.sample_bilinear(x0 + i as f64, y0 + j as f64, 0).unwrap_or(f64::NAN);
            }
        }
        let im = ib.iter().sum::<f64>() / n;
        let (mut ex, mut ey) = (0.0, 0.0);
        for k in 0..side * side {
            let e = (ib[k] - im) - (t[k] - tm);
            ex += gx[k] * e;
            ey += gy[k] * e;
        }
        let (dx, dy) = ((hyy * ex - hxy * ey) / det, (hxx * ey - hxy * ex) / det);
        r = [r[0] - dx, r[1] - dy];
        if (r[0] - r0[0]).abs() > 1.0 || (r[1] - r0[1]).abs() > 1.0 {
            return None;
        }
        if dx.abs() < 1e-3 && dy.abs() < 1e-3 {
            break;
        }
    }
    Some(r)
}

/// Refine matches `pa[i]` (image `a`) ↔ `pb[i]` (image `b`), both grey u8 of the same size.
/// Returns one entry per input match: `None` where a patch leaves the image, the peak lies on
/// the search border, the patch is flat, or the peak NCC is below `min_ncc`.
pub fn refine_matches_ncc(
    a: &Image<u8>,
    b: &Image<u8>,
    pa: &[[f64; 2]],
    pb: &[[f64; 2]],
    p: &RefineParams,
) -> Result<Vec<Option<Refined>>> {
    if a.channels != 1 || b.channels != 1 {
        return Err(FeaturesError::invalid("refine images", "need grey (1-channel) images"));
    }
    if (a.width, a.height) != (b.width, b.height) {
        return Err(FeaturesError::invalid(
            "refine images",
            format!("sizes differ: {}x{} vs {}x{}", a.width, a.height, b.width, b.height),
        ));
    }
    if pa.len() != pb.len() {
        return Err(FeaturesError::invalid("refine matches", format!("{} vs {} points", pa.len(), pb.len())));
    }
    if p.half == 0 || p.radius == 0 || !p.min_ncc.is_finite() {
        return Err(FeaturesError::invalid(
            "refine parameters",
            format!("need half ≥ 1, radius ≥ 1, finite min_ncc ({p:?})"),
        ));
    }
    let (w, h) = (a.width as i64, a.height as i64);
    let (hh, rr) = (p.half as i64, p.radius as i64);
    let n = ((2 * p.half + 1) * (2 * p.half + 1)) as i64;
    Ok(pa
        .par_iter()
        .zip(pb)
        .with_min_len(32)
        .map(|(l, r)| {
            let (lx, ly) = (l[0].round(), l[1].round());
            if !(lx.is_finite() && ly.is_finite() && r[0].is_finite() && r[1].is_finite()) {
                return None;
            }
            // the right prediction moves with the left rounding
            let (cx, cy) = ((r[0] + lx - l[0]).round() as i64, (r[1] + ly - l[1]).round() as i64);
            let (lx, ly) = (lx as i64, ly as i64);
            let inside = |x: i64, y: i64, m: i64| x - m >= 0 && y - m >= 0 && x + m < w && y + m < h;
            if !inside(lx, ly, hh) || !inside(cx, cy, hh + rr) {
                return None;
            }
            let (la, lb) = (lx as usize, ly as usize);
            let (sa, sa2) = patch_sums(a, la, lb, p.half);
            let var_a = n * sa2 - sa * sa;
            if var_a <= 0 {
                return None;
            }
            let side = (2 * rr + 1) as usize;
            let mut s = vec![0f64; side * side];
            for dy in -rr..=rr {
                for dx in -rr..=rr {
                    let k = (dy + rr) as usize * side + (dx + rr) as usize;
                    s[k] = ncc(a, b, (la, lb), ((cx + dx) as usize, (cy + dy) as usize), p.half, sa, var_a);
                }
            }
            // first maximum in row-major order (deterministic tie-break)
            let mut best = 0;
            for k in 1..s.len() {
                if s[k] > s[best] {
                    best = k;
                }
            }
            let (bx, by) = (best % side, best / side);
            if bx == 0 || by == 0 || bx == side - 1 || by == side - 1 || s[best] < p.min_ncc {
                return None;
            }
            let ox = vertex(s[best - 1], s[best], s[best + 1]);
            let oy = vertex(s[best - side], s[best], s[best + side]);
            let mut right = [(cx + bx as i64 - rr) as f64 + ox, (cy + by as i64 - rr) as f64 + oy];
            if p.lk_iters > 0 {
                right = lk_refine(a, b, (la, lb), right, p.half, p.lk_iters)?;
            }
            Some(Refined { left: [lx as f64, ly as f64], right, ncc: s[best] })
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A smooth texture sampled at (x − tx, y − ty), rounded to u8.
    fn tex(w: usize, h: usize, tx: f64, ty: f64) -> Image<u8> {
        let mut img = Image::filled(w, h, 1, 0u8);
        for y in 0..h {
            for x in 0..w {
                let (u, v) = (x as f64 - tx, y as f64 - ty);
                let s = (u * 0.31).sin() * (v * 0.23).cos() + 0.5 * (u * 0.11 + v * 0.17).sin();
                img.set(x, y, 0, (128.0 + 80.0 * s).round() as u8);
            }
        }
        img
    }

    #[test]
    fn integer_shift_is_recovered_exactly() {
        let (a, b) = (tex(80, 60, 0.0, 0.0), tex(80, 60, -3.0, 2.0));
        // b(x, y) = a(x + 3, y − 2): the left point (40, 30) is at (37, 32) in b
        let r = refine_matches_ncc(&a, &b, &[[40.2, 29.9]], &[[38.0, 31.0]], &RefineParams::default()).unwrap();
        let r = r[0].unwrap();
        assert_eq!(r.left, [40.0, 30.0]);
        // the parabola is off-centre (asymmetric neighbours); LK stops once a step is < 1e-3 px
        assert!((r.right[0] - 37.0).abs() < 1e-3 && (r.right[1] - 32.0).abs() < 1e-3, "{:?}", r.right);
        assert!((r.ncc - 1.0).abs() < 1e-12);
    }

    #[test]
    fn subpixel_shift_is_recovered_within_a_tenth() {
        let (a, b) = (tex(120, 90, 0.0, 0.0), tex(120, 90, 0.3, -0.25));
        let pa: Vec<[f64; 2]> = (0..5).map(|i| [30.0 + 12.0 * i as f64, 45.0]).collect();
        let r = refine_matches_ncc(&a, &b, &pa, &pa, &RefineParams::default()).unwrap();
        for (p, q) in pa.iter().zip(&r) {
            let q = q.unwrap();
            assert!((q.right[0] - p[0] - 0.3).abs() < 0.1 && (q.right[1] - p[1] + 0.25).abs() < 0.1, "{q:?}");
        }
    }

    #[test]
    fn border_flat_and_bad_input() {
        let a = tex(40, 40, 0.0, 0.0);
        let flat = Image::filled(40, 40, 1, 7u8);
        let p = RefineParams::default();
        assert_eq!(refine_matches_ncc(&a, &a, &[[2.0, 20.0]], &[[2.0, 20.0]], &p).unwrap()[0], None);
        assert_eq!(refine_matches_ncc(&flat, &a, &[[20.0, 20.0]], &[[20.0, 20.0]], &p).unwrap()[0], None);
        assert!(refine_matches_ncc(&a, &tex(41, 40, 0.0, 0.0), &[], &[], &p).is_err());
        assert!(refine_matches_ncc(&a, &a, &[[1.0, 1.0]], &[], &p).is_err());
    }
}
