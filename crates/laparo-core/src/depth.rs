//! Depth maps with explicit units. Invalid depth is stored as NaN or a value <= 0
//! (use [`DepthMap::is_valid`]); no sentinel is silently treated as a distance.
use crate::error::{CoreError, Result};
use crate::image::{Image, Mask};
use serde::{Deserialize, Serialize};

/// Unit of a depth value along the optical axis (z, not ray length).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DepthUnit {
    /// Metres.
    #[serde(alias = "metres", alias = "meters")]
    M,
    /// Millimetres.
    #[serde(alias = "millimetres", alias = "millimeters")]
    Mm,
}

impl DepthUnit {
    /// Metres per unit (1 for m, 1e-3 for mm).
    pub fn to_metres(self) -> f64 {
        match self {
            DepthUnit::M => 1.0,
            DepthUnit::Mm => 1e-3,
        }
    }
}

impl std::str::FromStr for DepthUnit {
    type Err = CoreError;
    fn from_str(s: &str) -> Result<Self> {
        match s.to_ascii_lowercase().as_str() {
            "m" | "metres" | "meters" => Ok(DepthUnit::M),
            "mm" | "millimetres" | "millimeters" => Ok(DepthUnit::Mm),
            _ => Err(CoreError::invalid("depth unit", format!("'{s}' (expected m or mm)"))),
        }
    }
}

impl std::fmt::Display for DepthUnit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            DepthUnit::M => "m",
            DepthUnit::Mm => "mm",
        })
    }
}

/// A depth map (z along the optical axis) in a stated unit; row-major, f64.
#[derive(Clone, Debug, PartialEq)]
pub struct DepthMap {
    /// Width (px).
    pub width: usize,
    /// Height (px).
    pub height: usize,
    /// Unit of `data`.
    pub unit: DepthUnit,
    /// Row-major depth values (z along the optical axis); non-finite or ≤ 0 = invalid.
    pub data: Vec<f64>,
}

impl DepthMap {
    /// Wrap `data`, checking its length.
    pub fn new(width: usize, height: usize, unit: DepthUnit, data: Vec<f64>) -> Result<Self> {
        if data.len() != width * height {
            return Err(CoreError::SizeMismatch(format!(
                "depth data has {} values, {width}x{height} needs {}",
                data.len(),
                width * height
            )));
        }
        Ok(DepthMap { width, height, unit, data })
    }

    /// From a single-channel float image.
    pub fn from_image<T: Copy + Into<f64>>(img: &Image<T>, unit: DepthUnit) -> Result<Self> {
        if img.channels != 1 {
            return Err(CoreError::invalid("depth image", format!("has {} channels, expected 1", img.channels)));
        }
        Self::new(img.width, img.height, unit, img.data.iter().map(|&v| v.into()).collect())
    }

    /// As a single-channel image (same unit).
    pub fn to_image(&self) -> Image<f64> {
        Image { width: self.width, height: self.height, channels: 1, data: self.data.clone() }
    }

    /// Depth at (x, y).
    #[inline]
    pub fn get(&self, x: usize, y: usize) -> f64 {
        self.data[y * self.width + x]
    }

    /// True where the depth is finite and > 0.
    #[inline]
    pub fn is_valid(v: f64) -> bool {
        v.is_finite() && v > 0.0
    }

    /// Mask of valid pixels.
    pub fn valid_mask(&self) -> Mask {
        Image {
            width: self.width,
            height: self.height,
            channels: 1,
            data: self.data.iter().map(|&v| Self::is_valid(v)).collect(),
        }
    }

    /// The same map expressed in `unit`.
    pub fn to_unit(&self, unit: DepthUnit) -> DepthMap {
        let k = self.unit.to_metres() / unit.to_metres();
        DepthMap { width: self.width, height: self.height, unit, data: self.data.iter().map(|v| v * k).collect() }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn unit_conversion() {
        let d = DepthMap::new(2, 1, DepthUnit::M, vec![0.05, f64::NAN]).unwrap();
        let mm = d.to_unit(DepthUnit::Mm);
        assert!((mm.data[0] - 50.0).abs() < 1e-12);
        assert!(mm.data[1].is_nan());
        assert_eq!(d.valid_mask().count(), 1);
        assert_eq!("mm".parse::<DepthUnit>().unwrap(), DepthUnit::Mm);
        assert!("cm".parse::<DepthUnit>().is_err());
    }
}
