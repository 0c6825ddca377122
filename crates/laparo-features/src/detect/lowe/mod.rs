//! laparo's SIFT, written after Lowe (2004) and OpenCV's `cv::SIFT` (`sift.simd.hpp`): f32
//! scale space with an AVX2 separable blur, DoG extrema with Taylor refinement, orientation
//! histograms and the 4×4×8 descriptor. Keypoints are sorted and de-duplicated as OpenCV does,
//! so the output does not depend on the number of threads.
use rayon::prelude::*;

pub(crate) mod blur;
mod descriptor;
mod extrema;
mod fastmath;
mod orientation;
mod pyramid;

use blur::Plane;
use extrema::{Extremum, BORDER};

/// Detector settings (OpenCV `SIFT_create` parameters).
#[derive(Clone, Copy, Debug)]
pub struct Settings {
    /// Keep at most this many (best response first); 0 = all.
    pub n_features: usize,
    /// Layers per octave S.
    pub layers: usize,
    /// Contrast threshold on [0, 1] intensities (divided by S).
    pub contrast: f64,
    /// Curvature ratio limit r.
    pub edge: f64,
    /// σ₀.
    pub sigma: f64,
    /// Start at octave −1 (2× upsampled base).
    pub upsample: bool,
}

/// An oriented keypoint in input-image px with its descriptor.
#[derive(Clone, Copy, Debug)]
pub struct SiftPoint {
    /// Column, px.
    pub x: f32,
    /// Row, px.
    pub y: f32,
    /// Diameter, px (OpenCV `KeyPoint::size`).
    pub size: f32,
    /// Angle, degrees (OpenCV convention).
    pub angle: f32,
    /// |D(x̂)|.
    pub response: f32,
    /// Octave (−1 = upsampled).
    pub octave: i32,
    /// Layer within the octave.
    layer: usize,
}

/// Detect and describe on a grey u8 image (`w`×`h`, row-major).
pub fn sift(gray: &[u8], w: usize, h: usize, s: &Settings) -> (Vec<SiftPoint>, Vec<f32>) {
    if w == 0 || h == 0 || s.layers == 0 {
        return (vec![], vec![]);
    }
    let first = if s.upsample { -1 } else { 0 };
    let base = pyramid::initial_image(gray, w, h, s.sigma, s.upsample);
    let octaves = pyramid::n_octaves(w, h, s.upsample);
    let gauss = pyramid::gaussian_pyramid(base, octaves, s.layers, s.sigma);
    let dog = pyramid::dog_pyramid(&gauss);
    let mut kps = detect(&gauss, &dog, s, first);
    // OpenCV's KeyPoint12_LessThan order, then drop exact duplicates (same x, y, size, angle).
    kps.sort_by(|a, b| {
        a.x.total_cmp(&b.x)
            .then(a.y.total_cmp(&b.y))
            .then(b.size.total_cmp(&a.size))
            .then(a.angle.total_cmp(&b.angle))
            .then(b.response.total_cmp(&a.response))
            .then(b.octave.cmp(&a.octave))
            .then(a.layer.cmp(&b.layer))
    });
    kps.dedup_by(|b, a| a.x == b.x && a.y == b.y && a.size == b.size && a.angle == b.angle);
    if s.n_features > 0 && kps.len() > s.n_features {
        retain_best(&mut kps, s.n_features);
    }
    // Describe in (octave, layer, row) order so consecutive windows share cached image rows;
    // each descriptor is written to its keypoint's slot, so the output order is unchanged.
    let mut order: Vec<usize> = (0..kps.len()).collect();
    order.sort_by(|&a, &b| {
        let (p, q) = (&kps[a], &kps[b]);
        (p.octave, p.layer).cmp(&(q.octave, q.layer)).then(p.y.total_cmp(&q.y)).then(a.cmp(&b))
    });
    let described: Vec<(usize, [f32; descriptor::DIM])> = order
        .par_iter()
        .map(|&i| {
            let k = &kps[i];
            let o = (k.octave - first) as usize;
            let scale = 2f32.powi(-k.octave);
            let img = &gauss[o][k.layer];
            let angle = 360.0 - k.angle;
            let angle = if (angle - 360.0).abs() < f32::EPSILON { 0.0 } else { angle };
            (i, descriptor::describe(img, (k.x * scale, k.y * scale), angle, k.size * scale * 0.5))
        })
        .collect();
    let mut desc = vec![0f32; kps.len() * descriptor::DIM];
    for (i, d) in described {
        desc[i * descriptor::DIM..(i + 1) * descriptor::DIM].copy_from_slice(&d);
    }
    (kps, desc)
}

/// Keep the `n` strongest (and every tie with the n-th, OpenCV `retainBest`), in list order.
fn retain_best(kps: &mut Vec<SiftPoint>, n: usize) {
    let mut r: Vec<f32> = kps.iter().map(|k| k.response).collect();
    r.sort_by(|a, b| b.total_cmp(a));
    let edge = r[n - 1];
    let mut above = kps.iter().filter(|k| k.response > edge).count();
    kps.retain(|k| {
        if k.response > edge {
            true
        } else if k.response == edge && above < n {
            above += 1;
            true
        } else {
            false
        }
    });
}

/// Extrema of every octave and layer, refined and oriented (input-image px).
fn detect(gauss: &[Vec<Plane>], dog: &[Vec<Plane>], s: &Settings, first: i32) -> Vec<SiftPoint> {
    let thr = (0.5 * s.contrast / s.layers as f64 * 255.0).floor() as f32;
    let mut jobs = vec![];
    for (o, oct) in dog.iter().enumerate() {
        let h = oct[0].h;
        if h <= 2 * BORDER || oct[0].w <= 2 * BORDER {
            continue;
        }
        for i in 1..=s.layers {
            // Bands of 16 rows keep the parallel split fine and the result order fixed.
            let mut y = BORDER;
            while y < h - BORDER {
                let y1 = (y + 16).min(h - BORDER);
                jobs.push((o, i, y..y1));
                y = y1;
            }
        }
    }
    jobs.into_par_iter()
        .flat_map_iter(|(o, i, rows)| {
            let oct = &dog[o];
            extrema::candidates(oct, i, thr, rows)
                .into_iter()
                .filter_map(move |(c, r)| {
                    extrema::refine(oct, o, (i, c, r), s.layers, s.contrast as f32, s.edge as f32)
                })
                .flat_map(move |e| orient(gauss, &e, s, first))
                .collect::<Vec<_>>()
        })
        .collect()
}

/// Keypoints (one per orientation peak) of a refined extremum.
fn orient(gauss: &[Vec<Plane>], e: &Extremum, s: &Settings, first: i32) -> Vec<SiftPoint> {
    let oscale = 2f32.powi(e.octave as i32);
    let size_oct = s.sigma as f32 * 2f32.powf((e.layer as f32 + e.xi) / s.layers as f32) * 2.0;
    let scl_octv = size_oct * 0.5;
    let hist = orientation::histogram(
        &gauss[e.octave][e.layer],
        e.c,
        e.r,
        (orientation::RADIUS_FCTR * scl_octv).round() as i64,
        orientation::SIG_FCTR * scl_octv,
    );
    // Back to input px: octave o of a pyramid starting at `first` has scale 2^(o + first).
    let to_img = oscale * 2f32.powi(first);
    orientation::peak_angles(&hist)
        .into_iter()
        .map(|angle| SiftPoint {
            x: (e.c as f32 + e.xc) * to_img,
            y: (e.r as f32 + e.xr) * to_img,
            size: size_oct * to_img,
            angle,
            response: e.contrast,
            octave: e.octave as i32 + first,
            layer: e.layer,
        })
        .collect()
}
