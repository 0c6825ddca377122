//! SGM on warped pairs whose canvas reaches outside the source images (rectification with
//! α > 0, self-rectification): the parts outside each image's mask are filled with the row's
//! nearest in-mask pixel before matching (a black wedge has census codes that match each other and
//! pulls the aggregation paths astray near it), and the result is invalid where the left pixel is
//! outside its mask or its match lands outside the right mask (a match against the fill).
use super::{match_pair_with, SgmOutput, SgmParams, SgmWorkspace};
use crate::error::StereoError;
use laparo_core::image::{Image, Mask};
use laparo_core::remap::Texel;
use rayon::prelude::*;

/// A copy of `img` where the pixels outside `mask` take the value of the nearest in-mask pixel of
/// their row (rows without one are left as they are).
pub fn extend_rows<T: Texel>(img: &Image<T>, mask: &Mask) -> Image<T> {
    let mut out = img.clone();
    let (w, c) = (img.width, img.channels);
    out.data.par_chunks_mut(w * c).zip(mask.data.par_chunks(w)).for_each(|(row, m)| {
        let (Some(first), Some(last)) = (m.iter().position(|&v| v), m.iter().rposition(|&v| v)) else { return };
        for x in (0..first).chain(last + 1..w) {
            let src = if x < first { first } else { last };
            for ch in 0..c {
                row[x * c + ch] = row[src * c + ch];
            }
        }
    });
    out
}

/// [`match_pair`](super::match_pair) of a warped pair with the masks of its valid pixels (as returned by the
/// rectification warps): rows extended ([`extend_rows`]), then every disparity whose left pixel is
/// outside `mask_left`, or whose match (x − d, y + dy) rounded to the nearest pixel is outside the
/// image or `mask_right`, made invalid (+∞, confidence 0). `stats.n_valid` counts what is left.
/// Uses a fresh [`SgmWorkspace`] (see [`match_masked_with`]).
pub fn match_masked(
    left: &Image<u8>,
    right: &Image<u8>,
    mask_left: &Mask,
    mask_right: &Mask,
    p: &SgmParams,
) -> Result<SgmOutput, StereoError> {
    match_masked_with(&mut SgmWorkspace::new(), left, right, mask_left, mask_right, p)
}

/// [`match_masked`] with the caller's buffers (see [`super::match_pair_with`]).
pub fn match_masked_with(
    ws: &mut SgmWorkspace,
    left: &Image<u8>,
    right: &Image<u8>,
    mask_left: &Mask,
    mask_right: &Mask,
    p: &SgmParams,
) -> Result<SgmOutput, StereoError> {
    let (w, h) = left.size();
    for (name, m) in [("left mask", mask_left), ("right mask", mask_right)] {
        if m.size() != (w, h) {
            return Err(StereoError::SizeMismatch(format!(
                "{name} is {}x{}, the images are {w}x{h}",
                m.width, m.height
            )));
        }
    }
    if right.size() != (w, h) {
        return Err(StereoError::SizeMismatch(format!(
            "left image is {w}x{h}, right image is {}x{}",
            right.width, right.height
        )));
    }
    let (l, r) = rayon::join(|| extend_rows(left, mask_left), || extend_rows(right, mask_right));
    let mut o = match_pair_with(ws, &l, &r, p)?;
    let dy = o.dy.as_ref().map(|d| &d.data);
    let inside = |i: usize| -> bool {
        let (x, y) = (i % w, i / w);
        let d = o.disparity.data[i] as f64;
        if !mask_left.data[i] {
            return false;
        }
        let dyv = dy.as_ref().map_or(0.0, |v| v[i] as f64);
        let (xr, yr) = ((x as f64 - d + 0.5).floor(), (y as f64 + dyv + 0.5).floor());
        xr >= 0.0 && yr >= 0.0 && xr < w as f64 && yr < h as f64 && mask_right.data[yr as usize * w + xr as usize]
    };
    let drop: Vec<usize> =
        (0..w * h).into_par_iter().filter(|&i| o.disparity.data[i].is_finite() && !inside(i)).collect();
    for &i in &drop {
        o.disparity.data[i] = f32::INFINITY;
        o.confidence.data[i] = 0.0;
        if let Some(d) = o.dy.as_mut() {
            d.data[i] = f32::NAN;
        }
    }
    o.stats.n_valid = o.disparity.data.iter().filter(|v| v.is_finite()).count();
    Ok(o)
}
