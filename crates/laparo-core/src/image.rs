//! A plain, row-major, channel-interleaved image container: `Image<u8>` for 8-bit RGB/gray,
//! `Image<u16>` for 16-bit PNG, `Image<f32>`/`Image<f64>` for float maps (disparity, masks).
use crate::error::{CoreError, Result};

/// Row-major interleaved image: pixel (x, y) channel c is `data[(y * width + x) * channels + c]`.
/// Pixel centres are at integer coordinates (x = 0 is the centre of the first column).
#[derive(Clone, Debug, PartialEq)]
pub struct Image<T> {
    /// Width (px).
    pub width: usize,
    /// Height (px).
    pub height: usize,
    /// Interleaved channels per pixel (1 grey, 3 RGB, 4 RGBA).
    pub channels: usize,
    /// Row-major, channel-interleaved values: `(y * width + x) * channels + c`.
    pub data: Vec<T>,
}

impl<T: Copy> Image<T> {
    /// An image filled with `value`.
    pub fn filled(width: usize, height: usize, channels: usize, value: T) -> Self {
        Image { width, height, channels, data: vec![value; width * height * channels] }
    }

    /// Wrap `data`, checking that its length is `width * height * channels`.
    pub fn from_vec(width: usize, height: usize, channels: usize, data: Vec<T>) -> Result<Self> {
        if channels == 0 {
            return Err(CoreError::invalid("channels", "must be at least 1"));
        }
        if data.len() != width * height * channels {
            return Err(CoreError::SizeMismatch(format!(
                "image data has {} values, {width}x{height}x{channels} needs {}",
                data.len(),
                width * height * channels
            )));
        }
        Ok(Image { width, height, channels, data })
    }

    /// Number of pixels.
    pub fn n_pixels(&self) -> usize {
        self.width * self.height
    }

    /// `(width, height)`.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// Value at integer pixel (x, y), channel c. Panics when out of bounds (like slice indexing).
    #[inline]
    pub fn get(&self, x: usize, y: usize, c: usize) -> T {
        self.data[(y * self.width + x) * self.channels + c]
    }

    /// Set value at integer pixel (x, y), channel c.
    #[inline]
    pub fn set(&mut self, x: usize, y: usize, c: usize, v: T) {
        let i = (y * self.width + x) * self.channels + c;
        self.data[i] = v;
    }

    /// All channels of pixel (x, y).
    #[inline]
    pub fn pixel(&self, x: usize, y: usize) -> &[T] {
        let i = (y * self.width + x) * self.channels;
        &self.data[i..i + self.channels]
    }

    /// Mutable channels of pixel (x, y).
    #[inline]
    pub fn pixel_mut(&mut self, x: usize, y: usize) -> &mut [T] {
        let i = (y * self.width + x) * self.channels;
        &mut self.data[i..i + self.channels]
    }

    /// Apply `f` to every value, keeping the shape.
    pub fn map<U: Copy>(&self, f: impl Fn(T) -> U) -> Image<U> {
        Image {
            width: self.width,
            height: self.height,
            channels: self.channels,
            data: self.data.iter().map(|&v| f(v)).collect(),
        }
    }

    /// Error unless `other` has the same width and height (`what` names the inputs).
    pub fn check_same_size<U>(&self, other: &Image<U>, what: &str) -> Result<()> {
        if self.width != other.width || self.height != other.height {
            return Err(CoreError::SizeMismatch(format!(
                "{what}: {}x{} vs {}x{}",
                self.width, self.height, other.width, other.height
            )));
        }
        Ok(())
    }
}

impl<T: crate::remap::Texel> Image<T> {
    /// Bilinear sample of channel `c` at real pixel coordinates (x, y); `None` outside the
    /// convex hull of pixel centres `[0, w-1] x [0, h-1]` (the contract of [`crate::remap`]).
    #[inline]
    pub fn sample_bilinear(&self, x: f64, y: f64, c: usize) -> Option<f64> {
        crate::remap::sample_bilinear(self, x, y, c)
    }
}

impl<T: Copy> Image<T> {
    /// Nearest-neighbour sample of channel `c` (round half up); `None` outside the image.
    #[inline]
    pub fn sample_nearest(&self, x: f64, y: f64, c: usize) -> Option<T> {
        crate::remap::sample_nearest(self, x, y, c)
    }
}

impl Image<u8> {
    /// Convert to a single-channel luminance image in [0, 255] (Rec. 601 weights).
    pub fn to_gray_f32(&self) -> Image<f32> {
        let mut out = Image::filled(self.width, self.height, 1, 0f32);
        for (i, p) in self.data.chunks_exact(self.channels).enumerate() {
            out.data[i] = if self.channels >= 3 {
                0.299 * p[0] as f32 + 0.587 * p[1] as f32 + 0.114 * p[2] as f32
            } else {
                p[0] as f32
            };
        }
        out
    }

    /// Expand a 1-channel image to 3 channels, or drop alpha from 4 channels.
    pub fn to_rgb(&self) -> Image<u8> {
        match self.channels {
            3 => self.clone(),
            1 => Image {
                width: self.width,
                height: self.height,
                channels: 3,
                data: self.data.iter().flat_map(|&v| [v, v, v]).collect(),
            },
            _ => Image {
                width: self.width,
                height: self.height,
                channels: 3,
                data: self.data.chunks_exact(self.channels).flat_map(|p| [p[0], p[1], p[2]]).collect(),
            },
        }
    }
}

/// A boolean validity / region-of-interest mask, `true` = valid.
pub type Mask = Image<bool>;

impl Mask {
    /// Number of `true` pixels.
    pub fn count(&self) -> usize {
        self.data.iter().filter(|&&b| b).count()
    }

    /// Squared Euclidean distance (px²) from every pixel to the nearest `false` pixel of channel 0
    /// (0 on `false` pixels, `f64::INFINITY` if there is none); exact, separable (Felzenszwalb &
    /// Huttenlocher 2012). Pixels outside the image are not `false`.
    pub fn sq_distance_to_false(&self) -> Image<f64> {
        let (w, h) = (self.width, self.height);
        let mut d: Vec<f64> =
            (0..w * h).map(|i| if self.data[i * self.channels] { f64::INFINITY } else { 0.0 }).collect();
        let mut f = vec![0.0; w.max(h)];
        let mut out = vec![0.0; w.max(h)];
        for x in 0..w {
            for y in 0..h {
                f[y] = d[y * w + x];
            }
            sq_dt_1d(&f[..h], &mut out[..h]);
            for y in 0..h {
                d[y * w + x] = out[y];
            }
        }
        for row in d.chunks_exact_mut(w.max(1)) {
            f[..w].copy_from_slice(row);
            sq_dt_1d(&f[..w], &mut out[..w]);
            row.copy_from_slice(&out[..w]);
        }
        Image { width: w, height: h, channels: 1, data: d }
    }

    /// Erosion by a disk of radius `radius_px`: a pixel stays `true` iff every pixel within
    /// Euclidean distance `radius_px` is `true` (channel 0; outside the image counts as `true`).
    /// The thesis keeps keypoints in the ROI eroded by a 25 px disk (§4.5.1).
    pub fn erode_disk(&self, radius_px: f64) -> Mask {
        let r2 = radius_px * radius_px;
        let d = self.sq_distance_to_false();
        Image { width: self.width, height: self.height, channels: 1, data: d.data.iter().map(|&v| v > r2).collect() }
    }
}

/// 1D squared distance transform of the sampled function `f` (lower envelope of parabolas).
fn sq_dt_1d(f: &[f64], out: &mut [f64]) {
    let n = f.len();
    let sites: Vec<usize> = (0..n).filter(|&q| f[q].is_finite()).collect();
    if sites.is_empty() {
        out.fill(f64::INFINITY);
        return;
    }
    let mut v: Vec<usize> = Vec::with_capacity(sites.len());
    let mut z: Vec<f64> = Vec::with_capacity(sites.len() + 1);
    for &q in &sites {
        let qf = q as f64;
        loop {
            match v.last() {
                None => {
                    v.push(q);
                    z.push(f64::NEG_INFINITY);
                    break;
                }
                Some(&p) => {
                    let pf = p as f64;
                    let s = ((f[q] + qf * qf) - (f[p] + pf * pf)) / (2.0 * (qf - pf));
                    if s <= *z.last().unwrap() {
                        v.pop();
                        z.pop();
                    } else {
                        v.push(q);
                        z.push(s);
                        break;
                    }
                }
            }
        }
    }
    let mut k = 0;
    for (q, o) in out.iter_mut().enumerate() {
        while k + 1 < v.len() && z[k + 1] < q as f64 {
            k += 1;
        }
        let d = q as f64 - v[k] as f64;
        *o = d * d + f[v[k]];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bilinear_hand_values() {
        let img = Image::from_vec(2, 2, 1, vec![0.0f64, 10.0, 20.0, 30.0]).unwrap();
        assert_eq!(img.sample_bilinear(0.0, 0.0, 0), Some(0.0));
        assert_eq!(img.sample_bilinear(1.0, 1.0, 0), Some(30.0));
        assert_eq!(img.sample_bilinear(0.5, 0.5, 0), Some(15.0));
        assert_eq!(img.sample_bilinear(0.25, 0.0, 0), Some(2.5));
        assert_eq!(img.sample_bilinear(1.01, 0.0, 0), None);
        assert!(Image::from_vec(2, 2, 1, vec![0u8; 3]).is_err());
    }

    /// Distance transform and disk erosion against brute force on a random-ish mask.
    #[test]
    fn erode_disk_matches_brute_force() {
        let (w, h) = (37, 23);
        let mut m = Mask::filled(w, h, 1, true);
        let mut s = 12345u64;
        for _ in 0..9 {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            m.set((s >> 33) as usize % w, (s >> 45) as usize % h, 0, false);
        }
        let d = m.sq_distance_to_false();
        for y in 0..h {
            for x in 0..w {
                let mut best = f64::INFINITY;
                for yy in 0..h {
                    for xx in 0..w {
                        if !m.get(xx, yy, 0) {
                            best = best.min((x as f64 - xx as f64).powi(2) + (y as f64 - yy as f64).powi(2));
                        }
                    }
                }
                assert_eq!(d.get(x, y, 0), best, "({x}, {y})");
            }
        }
        let e = m.erode_disk(3.0);
        for y in 0..h {
            for x in 0..w {
                assert_eq!(e.get(x, y, 0), d.get(x, y, 0) > 9.0);
            }
        }
        // A single false pixel at (10, 10): (13, 10) is at distance 3 (eroded), (13, 12) is not.
        let mut one = Mask::filled(20, 20, 1, true);
        one.set(10, 10, 0, false);
        let e = one.erode_disk(3.0);
        assert!(!e.get(13, 10, 0) && e.get(13, 12, 0) && e.get(0, 0, 0));
        assert!(Mask::filled(4, 4, 1, true).sq_distance_to_false().data.iter().all(|v| v.is_infinite()));
    }
}
