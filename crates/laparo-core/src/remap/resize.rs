//! Resizing and edge-aware point samples, both on the one bilinear kernel of [`super::kernel`].
use super::{check_source, Interp, Texel};
use crate::error::{CoreError, Result};
use crate::image::{Image, Mask};
use rayon::prelude::*;

/// Source position of output sample `i` of a pixel-centre-aligned resize from `n` to `m`
/// samples: (i + ½)·n/m − ½, clamped to [0, n − 1], rounded to `f32` (a `CoordMap` entry).
#[inline]
pub fn resize_position(i: usize, n: usize, m: usize) -> f32 {
    position_f64(i, n, m) as f32
}

#[inline]
fn position_f64(i: usize, n: usize, m: usize) -> f64 {
    ((i as f64 + 0.5) * n as f64 / m as f64 - 0.5).clamp(0.0, (n - 1) as f64)
}

/// Resize `src` to `width`×`height` with pixel centres aligned (OpenCV `resize` convention,
/// `INTER_LINEAR` / `INTER_NEAREST`): output (x, y) samples the source at
/// ([`resize_position`](x), [`resize_position`](y)) under the contract of [`super`]. Bit for bit
/// what [`super::remap`] gives with that coordinate map (it is that remap, with the map's rows
/// generated on the fly). Every position is inside the source, so only non-finite float samples are
/// invalid (`fill`, `false` in the mask).
pub fn resize<T: Texel>(
    src: &Image<T>,
    width: usize,
    height: usize,
    interp: Interp,
    fill: T,
) -> Result<(Image<T>, Mask)> {
    check_source(src, width, height)?;
    if width == 0 || height == 0 {
        return Err(CoreError::invalid("output size", format!("{width}x{height} is empty")));
    }
    let xs: Vec<f32> = (0..width).map(|x| resize_position(x, src.width, width)).collect();
    super::remap_rows(src, width, height, interp, fill, |y, sx, sy| {
        sx.copy_from_slice(&xs);
        sy.fill(resize_position(y, src.height, height));
    })
}

/// Taps of [`resize_exact_u8`] along one axis: (i₀, weight of i₀ + 1 in 1/256) at the f64
/// position of [`resize_position`]; a weight that rounds to 256 moves to the next tap.
fn exact_taps(n: usize, m: usize) -> Vec<(usize, u32)> {
    (0..m)
        .map(|i| {
            let f = position_f64(i, n, m);
            let i0 = f.floor() as usize;
            match ((f - i0 as f64) * 256.0).round() as u32 {
                256 => ((i0 + 1).min(n - 1), 0),
                w => (i0, w),
            }
        })
        .collect()
}

/// Pixel-centre-aligned bilinear resize of a grey 8-bit image with OpenCV's `INTER_LINEAR_EXACT`
/// arithmetic, the second contract of this module: weights rounded to 1/256 per axis, the
/// vertical blend `a·(256 − wy) + b·wy` exact in integers, then the horizontal one, rounded once
/// (`+ 2¹⁵ >> 16`). Bit-equal to OpenCV, which keypoint detectors ported from OpenCV need (ORB's
/// pyramid: a one-grey-level difference moves FAST corners); it differs from [`resize`] by at
/// most one grey level. Runs the vertical blend over whole rows (vectorises), rows in parallel.
pub fn resize_exact_u8(src: &Image<u8>, width: usize, height: usize) -> Result<Image<u8>> {
    check_source(src, width, height)?;
    if src.channels != 1 {
        return Err(CoreError::invalid(
            "image",
            format!("has {} channels; the exact resize takes grey images", src.channels),
        ));
    }
    if width == 0 || height == 0 {
        return Err(CoreError::invalid("output size", format!("{width}x{height} is empty")));
    }
    let (xt, yt) = (exact_taps(src.width, width), exact_taps(src.height, height));
    let sw = src.width;
    let mut out = Image::filled(width, height, 1, 0u8);
    out.data.par_chunks_mut(width).zip(yt.par_iter()).for_each_init(
        || vec![0u32; sw + 1],
        |v, (row, &(y0, wy))| {
            let y1 = (y0 + 1).min(src.height - 1);
            let (r0, r1) = (&src.data[y0 * sw..(y0 + 1) * sw], &src.data[y1 * sw..(y1 + 1) * sw]);
            for ((d, &a), &b) in v.iter_mut().zip(r0).zip(r1) {
                *d = a as u32 * (256 - wy) + b as u32 * wy;
            }
            // x₁ = x₀ + 1 always: the row padded by a copy of its last value.
            v[sw] = v[sw - 1];
            for (o, &(x0, wx)) in row.iter_mut().zip(&xt) {
                let (a, b) = (v[x0], v[x0 + 1]);
                *o = ((a * 256).wrapping_add(b.wrapping_sub(a).wrapping_mul(wx)).wrapping_add(1 << 15) >> 16) as u8;
            }
        },
    );
    Ok(out)
}

/// Edge-aware sample of a map of depths or disparities at the real position (x, y): bilinear
/// (the kernel of [`super`], in f64) when the four neighbours are valid and span at most
/// `max_span` (compared in the map's own type `V`, `f32` or `f64`), else the nearest pixel's value
/// (round half up). `value(x, y)` gives a pixel's value, `None` when it is invalid. Returns `None`
/// outside [−½, w − ½)×[−½, h − ½) or when the nearest pixel is invalid. Interpolating across a
/// depth edge would invent surface between foreground and background; the span test keeps edges
/// sharp.
#[inline]
pub fn sample_smooth<V>(
    w: usize,
    h: usize,
    x: f64,
    y: f64,
    max_span: V,
    value: impl Fn(usize, usize) -> Option<V>,
) -> Option<f64>
where
    V: Copy + PartialOrd + std::ops::Sub<Output = V> + Into<f64>,
{
    if w == 0 || h == 0 || !(x >= -0.5 && y >= -0.5 && x < w as f64 - 0.5 && y < h as f64 - 0.5) {
        return None;
    }
    let nearest = || value(((x + 0.5) as usize).min(w - 1), ((y + 0.5) as usize).min(h - 1)).map(Into::into);
    if w < 2 || h < 2 || !(x >= 0.0 && y >= 0.0 && x <= (w - 1) as f64 && y <= (h - 1) as f64) {
        return nearest();
    }
    // x, y >= 0: truncation is floor.
    let x0 = (x as usize).min(w - 2);
    let y0 = (y as usize).min(h - 2);
    let q = (value(x0, y0), value(x0 + 1, y0), value(x0, y0 + 1), value(x0 + 1, y0 + 1));
    if let (Some(a), Some(b), Some(c), Some(d)) = q {
        let mn = |p: V, q: V| if q < p { q } else { p };
        let mx = |p: V, q: V| if q > p { q } else { p };
        if mx(mx(a, b), mx(c, d)) - mn(mn(a, b), mn(c, d)) <= max_span {
            let (ax, ay) = (x - x0 as f64, y - y0 as f64);
            return Some(super::bilerp(a.into(), b.into(), c.into(), d.into(), ax, ay, true));
        }
    }
    nearest()
}
