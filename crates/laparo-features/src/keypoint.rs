//! Keypoints, descriptors, matches and matching options (thesis §4.2: SIFT, ORB, UBC matcher).
use serde::{Deserialize, Serialize};

/// A keypoint in pixel coordinates (pixel centres at integers, laparo's convention).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Keypoint {
    /// Column in px (0 = centre of the first column).
    pub x: f64,
    /// Row in px (0 = centre of the first row).
    pub y: f64,
    /// Diameter of the meaningful neighbourhood in px (OpenCV `KeyPoint::size`).
    pub size_px: f64,
    /// Orientation in radians, measured from +x towards +y (image axes, y down), as OpenCV.
    pub angle_rad: f64,
    /// Detector response (larger = stronger).
    pub response: f64,
    /// Pyramid octave the keypoint was detected in.
    pub octave: i32,
}

/// Descriptors of a keypoint set, one row per keypoint.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Descriptors {
    /// Float descriptors (SIFT: `dim` = 128), row-major, `data.len() = n · dim`.
    Float {
        /// Length of one descriptor.
        dim: usize,
        /// Row-major values.
        data: Vec<f32>,
    },
    /// Binary descriptors (ORB: `bytes` = 32), row-major, `data.len() = n · bytes`.
    Binary {
        /// Bytes per descriptor.
        bytes: usize,
        /// Row-major bytes.
        data: Vec<u8>,
    },
}

impl Descriptors {
    /// Number of descriptor rows.
    pub fn len(&self) -> usize {
        match self {
            Descriptors::Float { dim, data } => data.len().checked_div(*dim).unwrap_or(0),
            Descriptors::Binary { bytes, data } => data.len().checked_div(*bytes).unwrap_or(0),
        }
    }

    /// True when there are no descriptors.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Keep only the rows listed in `keep` (in that order).
    pub fn select(&self, keep: &[usize]) -> Descriptors {
        match self {
            Descriptors::Float { dim, data } => Descriptors::Float {
                dim: *dim,
                data: keep.iter().flat_map(|&i| data[i * dim..(i + 1) * dim].iter().copied()).collect(),
            },
            Descriptors::Binary { bytes, data } => Descriptors::Binary {
                bytes: *bytes,
                data: keep.iter().flat_map(|&i| data[i * bytes..(i + 1) * bytes].iter().copied()).collect(),
            },
        }
    }
}

/// Keypoints and their descriptors (row i of `descriptors` belongs to `keypoints[i]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Features {
    /// The keypoints.
    pub keypoints: Vec<Keypoint>,
    /// One descriptor per keypoint.
    pub descriptors: Descriptors,
}

impl Features {
    /// Number of keypoints.
    pub fn len(&self) -> usize {
        self.keypoints.len()
    }

    /// True when there are no keypoints.
    pub fn is_empty(&self) -> bool {
        self.keypoints.is_empty()
    }

    /// Keypoint positions as `[x, y]` px.
    pub fn points(&self) -> Vec<[f64; 2]> {
        self.keypoints.iter().map(|k| [k.x, k.y]).collect()
    }
}

/// A putative correspondence: keypoint `i1` of image 1 with keypoint `i2` of image 2.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Match {
    /// Index into image 1's keypoints.
    pub i1: u32,
    /// Index into image 2's keypoints.
    pub i2: u32,
    /// Descriptor distance (L2 for float, Hamming bit count for binary).
    pub distance: f32,
}

/// Ratio test applied to the two nearest neighbours.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum RatioTest {
    /// Plain nearest neighbour.
    None,
    /// Lowe's ratio: accept iff d_best < r · d_second.
    Lowe(f32),
    /// VLFeat `vl_ubcmatch` (squared distances): accept iff thr · d²_best < d²_second
    /// (1.5 ≡ Lowe 0.816, 2.8 ≡ Lowe 0.598).
    Ubc(f32),
}

/// Matching options.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct MatchConfig {
    /// Ratio test on the two nearest neighbours.
    pub ratio: RatioTest,
    /// Keep only mutual nearest neighbours (cross check).
    pub mutual: bool,
}

impl Default for MatchConfig {
    /// Lowe 0.8 + mutual check (the OpenCV peer `features_ref.py`).
    fn default() -> Self {
        MatchConfig { ratio: RatioTest::Lowe(0.8), mutual: true }
    }
}
