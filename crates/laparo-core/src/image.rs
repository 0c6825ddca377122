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
}
