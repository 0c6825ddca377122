//! CATS configuration (TOML, serde): the distributions camera augmentation draws from
//! (thesis §3.3.5, eqs. 3.7–3.9, Table 3.6), and the seeded sampler.
//!
//! A config looks like (every field but `left.euler_deg` / `right.euler_deg` is optional):
//!
//! ```toml
//! source = "Table 3.6, SCARED+StMIS"
//! [left.euler_deg]            # R = Rz(z) Ry(y) Rx(x), degrees (eq. 3.7)
//! x = { dist = "normal", mean = -0.0001, std = 0.0004 }
//! y = { dist = "normal", mean = 0.0564, std = 0.1666 }
//! z = { dist = "normal", mean = 0.0280, std = 0.3487 }
//! [right.euler_deg]
//! x = { dist = "normal", mean = -0.0016, std = 0.0047 }
//! y = { dist = "normal", mean = 0.0854, std = 0.1594 }
//! z = { dist = "normal", mean = 0.0289, std = 0.3489 }
//! [disparity_offset]
//! dx_right_px = { dist = "uniform", min = -100.0, max = 0.0 }
//! ```
//!
//! **Sign of Δx_right.** The thesis defines Δx_right = c'_x,right − c_x,right (eq. 3.9) *and*
//! "adjusts all disparity values by adding Δx_right". With p' = H p (eq. 3.6) and
//! d = f b / z + (c_x^L − c_x^R) (§3.3.8) these two statements have opposite signs. laparo keeps
//! the observable one: `dx_right_px` is the amount **added to every disparity**, so the right
//! principal point moves by −Δx_right (K_rel,right = [[1, 0, −Δx_right], [0, 1, 0], [0, 0, 1]]).
//! With U(−100, 0) this gives the negative principal-point offsets of real laparoscopes
//! (SCARED ds1–3: c_x^L − c_x^R = −91.4 px; EndoVis 2017 kidney: −97.3 px) and the mix of
//! positive and negative disparities the thesis aims at (Fig. 3.8). `cats stats` can therefore
//! fit `dx_right_px` directly to c_x^L − c_x^R of real calibrations.
use crate::augment::{CameraAugmentation, StereoAugmentation};
use laparo_core::{Distortion, Intrinsics};
use nalgebra::Matrix3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::error::{Result, StereoError};

/// A scalar distribution: fixed value, Gaussian N(mean, std²) or uniform U(min, max).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "dist", rename_all = "lowercase")]
pub enum Dist {
    /// Always `value`.
    Fixed {
        /// The value.
        value: f64,
    },
    /// Gaussian N(mean, std²) (eq. 3.7).
    Normal {
        /// Mean.
        mean: f64,
        /// Standard deviation.
        std: f64,
    },
    /// Uniform on [min, max] (Δx_right ~ U(−100, 0), §3.3.5).
    Uniform {
        /// Lower bound.
        min: f64,
        /// Upper bound.
        max: f64,
    },
}

impl Dist {
    /// A fixed value.
    pub const fn fixed(value: f64) -> Self {
        Dist::Fixed { value }
    }
    /// A Gaussian.
    pub const fn normal(mean: f64, std: f64) -> Self {
        Dist::Normal { mean, std }
    }
    /// A uniform distribution.
    pub const fn uniform(min: f64, max: f64) -> Self {
        Dist::Uniform { min, max }
    }

    /// Check finiteness, std >= 0, min <= max; `what` names the field in the error.
    pub fn validate(&self, what: &str) -> Result<()> {
        let ok = match *self {
            Dist::Fixed { value } => value.is_finite(),
            Dist::Normal { mean, std } => mean.is_finite() && std.is_finite() && std >= 0.0,
            Dist::Uniform { min, max } => min.is_finite() && max.is_finite() && min <= max,
        };
        if ok {
            Ok(())
        } else {
            Err(StereoError::Config(format!("{what}: {self:?} (need finite values, std >= 0, min <= max)")))
        }
    }

    /// Draw one value. Always consumes exactly one uniform or normal draw, so the sequence of
    /// the other parameters does not depend on which distributions are fixed.
    pub fn sample<R: Rng>(&self, rng: &mut R) -> f64 {
        let u: f64 = rng.gen();
        match *self {
            Dist::Fixed { value } => value,
            Dist::Uniform { min, max } => min + (max - min) * u,
            Dist::Normal { mean, std } => {
                // Box–Muller (fixed number of draws, unlike a ziggurat sampler).
                let v: f64 = rng.gen();
                let r = (-2.0 * (1.0 - u).ln()).sqrt();
                mean + std * r * (2.0 * std::f64::consts::PI * v).cos()
            }
        }
    }

    /// Mean of the distribution.
    pub fn mean(&self) -> f64 {
        match *self {
            Dist::Fixed { value } => value,
            Dist::Normal { mean, .. } => mean,
            Dist::Uniform { min, max } => 0.5 * (min + max),
        }
    }
}

/// Per-angle distributions of one camera's rotation, degrees; R = Rz(z) Ry(y) Rx(x) (eq. 3.7).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct EulerDist {
    /// Rotation about X (φ), degrees.
    pub x: Dist,
    /// Rotation about Y (θ), degrees.
    pub y: Dist,
    /// Rotation about Z (ψ), degrees.
    pub z: Dist,
}

/// Distributions of the augmented camera's Brown–Conrady coefficients θ' (eq. 3.5); all 0 by default.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct DistortionDist {
    /// Distribution of k1.
    #[serde(default = "zero")]
    pub k1: Dist,
    /// Distribution of k2.
    #[serde(default = "zero")]
    pub k2: Dist,
    /// Distribution of p1.
    #[serde(default = "zero")]
    pub p1: Dist,
    /// Distribution of p2.
    #[serde(default = "zero")]
    pub p2: Dist,
    /// Distribution of k3.
    #[serde(default = "zero")]
    pub k3: Dist,
}

fn zero() -> Dist {
    Dist::fixed(0.0)
}
fn one() -> Dist {
    Dist::fixed(1.0)
}

/// Distributions for one camera of the pair: rotation, relative intrinsics K_rel (s_x, s_y and
/// principal-point shifts c'_x − s_x c_x, c'_y − s_y c_y) and output distortion.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraDist {
    /// Euler angles, degrees (eq. 3.7).
    pub euler_deg: EulerDist,
    /// Focal ratio s_x = f'_x / f_x (thesis: 1).
    #[serde(default = "one")]
    pub s_x: Dist,
    /// Focal ratio s_y = f'_y / f_y (thesis: 1).
    #[serde(default = "one")]
    pub s_y: Dist,
    /// Principal-point shift c'_x − c_x, px (on top of the Δx_right rule; scaling is about the principal point).
    #[serde(default = "zero")]
    pub dcx_px: Dist,
    /// Principal-point shift c'_y − c_y, px (thesis: c'_y = c_y, i.e. 0).
    #[serde(default = "zero")]
    pub dcy_px: Dist,
    /// Output lens distortion θ' (thesis: omitted).
    #[serde(default)]
    pub distortion: Option<DistortionDist>,
}

/// The principal-point offset model of §3.3.5.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct DisparityOffsetDist {
    /// Δx_right, px, **added to every disparity**; the right principal point moves by −Δx_right
    /// (see the module docs for the sign). Thesis: U(−100, 0).
    pub dx_right_px: Dist,
}

/// The source dataset's pinhole camera (both views), when the layout does not provide it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SourceCamera {
    /// Focal lengths, px.
    pub fx: f64,
    /// Focal length along y, px.
    pub fy: f64,
    /// Principal point, px; image centre ((w − 1)/2, (h − 1)/2) when absent.
    #[serde(default)]
    pub cx: Option<f64>,
    /// Principal point y, px; image centre when absent.
    #[serde(default)]
    pub cy: Option<f64>,
    /// Right principal point x, px, when it differs from the left one (Middlebury cx1).
    #[serde(default)]
    pub cx_right: Option<f64>,
}

impl SourceCamera {
    /// SceneFlow's camera (f = 1050 px at 960×540, centred principal point).
    pub const SCENEFLOW: SourceCamera = SourceCamera { fx: 1050.0, fy: 1050.0, cx: None, cy: None, cx_right: None };

    /// The (left, right) intrinsics for an image of `width`×`height`.
    pub fn intrinsics(&self, width: usize, height: usize) -> Result<(Intrinsics, Intrinsics)> {
        let cx = self.cx.unwrap_or((width as f64 - 1.0) / 2.0);
        let cy = self.cy.unwrap_or((height as f64 - 1.0) / 2.0);
        let l = Intrinsics::new(self.fx, self.fy, cx, cy, width, height)
            .map_err(|source| StereoError::ConfigField { what: "camera".into(), source })?;
        let r = Intrinsics::new(self.fx, self.fy, self.cx_right.unwrap_or(cx), cy, width, height)
            .map_err(|source| StereoError::ConfigField { what: "camera".into(), source })?;
        Ok((l, r))
    }
}

/// The whole CATS configuration (TOML). See the module docs for an example.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CatsConfig {
    /// Where the statistics come from (free text, copied to every sidecar).
    #[serde(default)]
    pub source: String,
    /// Left camera distributions.
    pub left: CameraDist,
    /// Right camera distributions.
    pub right: CameraDist,
    /// Δx_right (eq. 3.9, §3.3.5).
    #[serde(default = "default_offset")]
    pub disparity_offset: DisparityOffsetDist,
    /// Source camera; defaults per layout (SceneFlow f = 1050 px; Middlebury calib.txt).
    #[serde(default)]
    pub camera: Option<SourceCamera>,
}

fn default_offset() -> DisparityOffsetDist {
    DisparityOffsetDist { dx_right_px: Dist::uniform(-100.0, 0.0) }
}

/// Table 3.6 rows (μ, σ in degrees) for left x, y, z then right x, y, z.
pub const TABLE_3_6: [(&str, [(f64, f64); 6]); 4] = [
    (
        "SCARED",
        [(0.0000, 0.0001), (-0.0325, 0.0129), (0.0904, 0.3597), (-0.0014, 0.0053), (0.0013, 0.0266), (0.0910, 0.3602)],
    ),
    (
        "StereoMIS",
        [
            (-0.0006, 0.0006),
            (0.3673, 0.0032),
            (-0.1907, 0.1812),
            (-0.0020, 0.0008),
            (0.3799, 0.0187),
            (-0.1887, 0.1809),
        ],
    ),
    (
        "RIS2017",
        [(-0.0004, 0.0014), (-0.3386, 0.1652), (0.2637, 0.4680), (0.0002, 0.0076), (-0.2744, 0.1640), (0.2639, 0.4681)],
    ),
    (
        "SCARED+StMIS",
        [(-0.0001, 0.0004), (0.0564, 0.1666), (0.0280, 0.3487), (-0.0016, 0.0047), (0.0854, 0.1594), (0.0289, 0.3489)],
    ),
];

impl CatsConfig {
    /// The thesis' CATS configuration: Gaussians of a Table 3.6 row (default "SCARED+StMIS",
    /// the one used for training), s_x = s_y = 1, c'_y = c_y, Δx_right ~ U(−100, 0), no distortion.
    pub fn thesis(row: &str) -> Result<Self> {
        let (name, v) = TABLE_3_6
            .iter()
            .find(|(n, _)| n.eq_ignore_ascii_case(row))
            .ok_or_else(|| StereoError::Config(format!("unknown Table 3.6 row '{row}'")))?;
        let cam = |o: usize| CameraDist {
            euler_deg: EulerDist {
                x: Dist::normal(v[o].0, v[o].1),
                y: Dist::normal(v[o + 1].0, v[o + 1].1),
                z: Dist::normal(v[o + 2].0, v[o + 2].1),
            },
            s_x: one(),
            s_y: one(),
            dcx_px: zero(),
            dcy_px: zero(),
            distortion: None,
        };
        Ok(CatsConfig {
            source: format!("thesis Table 3.6, {name}; dx_right ~ U(-100, 0) px"),
            left: cam(0),
            right: cam(3),
            disparity_offset: default_offset(),
            camera: None,
        })
    }

    /// Parse and validate TOML text.
    pub fn from_toml_str(s: &str) -> Result<Self> {
        let c: CatsConfig = toml::from_str(s)?;
        c.validate()?;
        Ok(c)
    }

    /// Serialise to TOML.
    pub fn to_toml_string(&self) -> String {
        toml::to_string_pretty(self).expect("CatsConfig is always TOML-serialisable")
    }

    /// Validate every distribution (names the offending field).
    pub fn validate(&self) -> Result<()> {
        for (side, c) in [("left", &self.left), ("right", &self.right)] {
            c.euler_deg.x.validate(&format!("{side}.euler_deg.x"))?;
            c.euler_deg.y.validate(&format!("{side}.euler_deg.y"))?;
            c.euler_deg.z.validate(&format!("{side}.euler_deg.z"))?;
            c.s_x.validate(&format!("{side}.s_x"))?;
            c.s_y.validate(&format!("{side}.s_y"))?;
            c.dcx_px.validate(&format!("{side}.dcx_px"))?;
            c.dcy_px.validate(&format!("{side}.dcy_px"))?;
            for (n, s) in [("s_x", &c.s_x), ("s_y", &c.s_y)] {
                let lo = match *s {
                    Dist::Fixed { value } => value,
                    Dist::Uniform { min, .. } => min,
                    Dist::Normal { mean, std } => mean - 6.0 * std,
                };
                if lo <= 0.0 {
                    return Err(StereoError::Config(format!("{side}.{n}: focal ratios must stay > 0 ({s:?})")));
                }
            }
            if let Some(d) = &c.distortion {
                for (n, v) in [("k1", &d.k1), ("k2", &d.k2), ("p1", &d.p1), ("p2", &d.p2), ("k3", &d.k3)] {
                    v.validate(&format!("{side}.distortion.{n}"))?;
                }
            }
        }
        self.disparity_offset.dx_right_px.validate("disparity_offset.dx_right_px")?;
        if let Some(c) = &self.camera {
            if !(c.fx.is_finite() && c.fx > 0.0 && c.fy.is_finite() && c.fy > 0.0) {
                return Err(StereoError::Config(format!(
                    "camera: fx = {}, fy = {} must be finite and > 0",
                    c.fx, c.fy
                )));
            }
        }
        Ok(())
    }

    /// Draw the parameters of one stereo sample (eqs. 3.7–3.9) for source cameras `k_left`,
    /// `k_right` (with their distortion `dist_left`, `dist_right`), from `rng`.
    pub fn sample<R: Rng>(
        &self,
        rng: &mut R,
        k_left: &Intrinsics,
        dist_left: &Distortion,
        k_right: &Intrinsics,
        dist_right: &Distortion,
    ) -> StereoAugmentation {
        // Fixed draw order: left x, y, z, s_x, s_y, dcx, dcy, distortion(5); right ...; dx_right.
        let mut draw_cam = |c: &CameraDist| {
            let e = [c.euler_deg.x.sample(rng), c.euler_deg.y.sample(rng), c.euler_deg.z.sample(rng)];
            let s = [c.s_x.sample(rng), c.s_y.sample(rng)];
            let dc = [c.dcx_px.sample(rng), c.dcy_px.sample(rng)];
            let d =
                c.distortion.unwrap_or(DistortionDist { k1: zero(), k2: zero(), p1: zero(), p2: zero(), k3: zero() });
            let dist = Distortion::brown_conrady(
                d.k1.sample(rng),
                d.k2.sample(rng),
                d.p1.sample(rng),
                d.p2.sample(rng),
                d.k3.sample(rng),
            );
            (e, s, dc, dist)
        };
        let l = draw_cam(&self.left);
        let r = draw_cam(&self.right);
        let dx = self.disparity_offset.dx_right_px.sample(rng);
        let make = |k: &Intrinsics,
                    kd: &Distortion,
                    (e, s, dc, dist): ([f64; 3], [f64; 2], [f64; 2], Distortion),
                    extra_dx: f64| {
            let t_x = dc[0] + extra_dx + (1.0 - s[0]) * k.cx;
            let t_y = dc[1] + (1.0 - s[1]) * k.cy;
            // K_rel = [[s_x, 0, c'_x − s_x c_x], [0, s_y, c'_y − s_y c_y], [0, 0, 1]] with
            // c'_x = c_x + dcx (scaling about the principal point), so K_rel[0,2] = dcx + (1 − s_x) c_x.
            let k_rel = Matrix3::new(s[0], 0.0, t_x, 0.0, s[1], t_y, 0.0, 0.0, 1.0);
            CameraAugmentation::from_euler_deg(*k, *kd, e, k_rel, dist)
        };
        StereoAugmentation {
            left: make(k_left, dist_left, l, 0.0),
            right: make(k_right, dist_right, r, -dx),
            dx_right_px: dx,
        }
    }
}

/// Seed of one sample, derived from the run seed and the sample's id only (so results do not
/// depend on thread count or processing order): FNV-1a of the id, mixed with SplitMix64.
pub fn sample_seed(seed: u64, sample_id: &str) -> u64 {
    let mut h: u64 = 0xcbf29ce484222325;
    for b in sample_id.as_bytes() {
        h ^= *b as u64;
        h = h.wrapping_mul(0x100000001b3);
    }
    let mut z = seed ^ h.rotate_left(17) ^ 0x9e3779b97f4a7c15;
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58476d1ce4e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d049bb133111eb);
    z ^ (z >> 31)
}

/// The ChaCha8 generator of one sample.
pub fn sample_rng(seed: u64, sample_id: &str) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(sample_seed(seed, sample_id))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thesis_config_toml_round_trip() {
        let c = CatsConfig::thesis("SCARED+StMIS").unwrap();
        let s = c.to_toml_string();
        let back = CatsConfig::from_toml_str(&s).unwrap();
        assert_eq!(c, back);
        assert_eq!(c.right.euler_deg.z, Dist::normal(0.0289, 0.3489));
    }

    #[test]
    fn minimal_toml_uses_thesis_defaults() {
        let s = r#"
[left.euler_deg]
x = { dist = "fixed", value = 0.0 }
y = { dist = "normal", mean = 0.1, std = 0.2 }
z = { dist = "uniform", min = -1.0, max = 1.0 }
[right.euler_deg]
x = { dist = "fixed", value = 0.0 }
y = { dist = "fixed", value = 0.0 }
z = { dist = "fixed", value = 0.0 }
"#;
        let c = CatsConfig::from_toml_str(s).unwrap();
        assert_eq!(c.disparity_offset.dx_right_px, Dist::uniform(-100.0, 0.0));
        assert_eq!(c.left.s_x, Dist::fixed(1.0));
        let bad = s.replace("std = 0.2", "std = -0.2");
        let e = CatsConfig::from_toml_str(&bad).unwrap_err().to_string();
        assert!(e.contains("left.euler_deg.y"), "{e}");
    }

    #[test]
    fn normal_sampler_moments() {
        let d = Dist::normal(0.3, 2.0);
        let mut rng = sample_rng(7, "x");
        let n = 200_000;
        let v: Vec<f64> = (0..n).map(|_| d.sample(&mut rng)).collect();
        let m = v.iter().sum::<f64>() / n as f64;
        let s = (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / n as f64).sqrt();
        // Standard error of the mean 2/sqrt(2e5) = 0.0045; of the std ~0.0032.
        assert!((m - 0.3).abs() < 0.02 && (s - 2.0).abs() < 0.02, "{m} {s}");
        let u = Dist::uniform(-100.0, 0.0);
        assert!((0..1000).map(|_| u.sample(&mut rng)).all(|x| (-100.0..=0.0).contains(&x)));
    }

    #[test]
    fn seeds_depend_on_id_and_seed() {
        assert_ne!(sample_seed(1, "a"), sample_seed(1, "b"));
        assert_ne!(sample_seed(1, "a"), sample_seed(2, "a"));
        assert_eq!(sample_seed(3, "scene/0001"), sample_seed(3, "scene/0001"));
    }
}
