//! Synthetic scenes for CPC tests, the demo and feature-matching experiments: a textured surface
//! patch (plane, cylinder, bumpy organ-like bowl) seen by a pinhole camera from a chosen pose,
//! rendered by ray casting. Gives the image, the metric depth (mm), the ROI mask, the ground-truth
//! pose and, per pixel, the surface coordinates (mm) of the visible point (ground-truth
//! correspondences between views).
//!
//! Conventions (those of `../shared/bench/cpc_ref/scene.py`): the surface is a height field
//! z = h(x, y) over the square |x|, |y| ≤ half (local frame, mm); a world point is
//! X = R·(x, y, h) + T in the camera frame (x right, y down, z forward); pixel (u, v) casts the ray
//! t·K⁻¹(u, v, 1) so that t is the depth. [`bumpy_bowl_spec`] reproduces scene.py's bumpy bowl
//! (its eight bumps, drawn there by numpy's `default_rng(7)`, are copied below).
//!
//! Intersection: dense march (0.25 mm steps by default) over the ray's span inside the patch's
//! bounding box (grown by a margin, so that crossings just outside the patch are seen and the ray
//! counted as a miss, as in scene.py), then 60 bisection steps.
use crate::error::{CpcError, Result};
use laparo_core::camera::Intrinsics;
use laparo_core::depth::{DepthMap, DepthUnit};
use laparo_core::image::{Image, Mask};
use laparo_core::se3::Se3;
use nalgebra::{Isometry3, Rotation3, Translation3, UnitQuaternion, Vector3};
use rayon::prelude::*;

/// One Gaussian bump: centre (mm), signed amplitude (mm), width σ (mm).
#[derive(Clone, Copy, Debug)]
pub struct Bump {
    /// Centre x (mm, patch frame).
    pub cx: f64,
    /// Centre y (mm, patch frame).
    pub cy: f64,
    /// Signed amplitude (mm).
    pub amp: f64,
    /// Width σ (mm).
    pub sigma: f64,
}

/// The eight bumps of scene.py (numpy `default_rng(7)`: centres U(−45, 45), |A| U(1.5, 3), σ U(7, 12)).
pub const SCENE_PY_BUMPS: [Bump; 8] = [
    Bump { cx: 11.25859199442003, cy: 35.74924208726179, amp: -2.9932504251515892, sigma: 10.146131272455053 },
    Bump { cx: 24.81171212206742, cy: -24.731352900846733, amp: -2.6889928788206294, sigma: 9.570588232997569 },
    Bump { cx: -17.98503435798971, cy: 33.61981008566357, amp: -2.433268844161744, sigma: 9.48436717696752 },
    Bump { cx: -44.52612258909827, cy: 28.910557654448965, amp: 2.9834402215228275, sigma: 8.237574610136654 },
    Bump { cx: 26.73624858768416, cy: -2.885854244065129, amp: 1.8229630473533984, sigma: 7.058970127712529 },
    Bump { cx: -17.727081586261782, cy: -19.9416949109304, amp: -1.7403180507867668, sigma: 7.962010719926553 },
    Bump { cx: -22.061737111128785, cy: -4.943132470561807, amp: 2.4188094064095464, sigma: 10.460160604409197 },
    Bump { cx: 0.4093433062157956, cy: 4.814761686704323, amp: 1.565913011942075, sigma: 8.003033619934977 },
];

/// The surface shape (height field over the local square).
#[derive(Clone, Debug)]
pub enum Surface {
    /// z = 0.
    Plane,
    /// Half cylinder with its axis along local y, concave towards the camera:
    /// z = r − √(r² − x²) (needs half < r).
    Cylinder {
        /// Cylinder radius (mm).
        radius_mm: f64,
    },
    /// Paraboloid bowl of curvature radius `rcurv_mm` plus Gaussian bumps (non-developable,
    /// organ-like): z = (x² + y²)/(2 r) + Σ A_k exp(−|(x, y) − c_k|² / (2σ_k²)).
    Bumpy {
        /// Curvature radius of the bowl (mm).
        rcurv_mm: f64,
        /// The Gaussian bumps.
        bumps: Vec<Bump>,
    },
}

impl Surface {
    /// Height h(x, y) (mm).
    pub fn height(&self, x: f64, y: f64) -> f64 {
        match self {
            Surface::Plane => 0.0,
            Surface::Cylinder { radius_mm: r } => r - (r * r - x * x).max(0.0).sqrt(),
            Surface::Bumpy { rcurv_mm, bumps } => {
                let mut h = (x * x + y * y) / (2.0 * rcurv_mm);
                for b in bumps {
                    let d2 = (x - b.cx).powi(2) + (y - b.cy).powi(2);
                    h += b.amp * (-d2 / (2.0 * b.sigma * b.sigma)).exp();
                }
                h
            }
        }
    }

    /// Gradient (∂h/∂x, ∂h/∂y).
    pub fn gradient(&self, x: f64, y: f64) -> (f64, f64) {
        match self {
            Surface::Plane => (0.0, 0.0),
            Surface::Cylinder { radius_mm: r } => (x / (r * r - x * x).max(1e-12).sqrt(), 0.0),
            Surface::Bumpy { rcurv_mm, bumps } => {
                let (mut gx, mut gy) = (x / rcurv_mm, y / rcurv_mm);
                for b in bumps {
                    let e = b.amp * (-((x - b.cx).powi(2) + (y - b.cy).powi(2)) / (2.0 * b.sigma * b.sigma)).exp();
                    gx -= e * (x - b.cx) / (b.sigma * b.sigma);
                    gy -= e * (y - b.cy) / (b.sigma * b.sigma);
                }
                (gx, gy)
            }
        }
    }
}

/// Surface appearance (albedo as a function of the local coordinates).
#[derive(Clone, Debug)]
pub enum Texture {
    /// A photograph stretched over the whole patch.
    Photo(Image<u8>),
    /// scene.py's checkerboard (squares of `square_mm`) with colour ramps.
    Checker {
        /// Square size (mm).
        square_mm: f64,
    },
    /// Deterministic multi-scale value noise with colour blobs (rich in corners), seeded.
    Procedural {
        /// Seed of the noise.
        seed: u64,
    },
}

/// What to render.
#[derive(Clone, Debug)]
pub struct SceneSpec {
    /// Camera intrinsics (px).
    pub intrinsics: Intrinsics,
    /// Surface shape.
    pub surface: Surface,
    /// Half-size of the square patch (mm).
    pub half_mm: f64,
    /// Camera-from-surface pose: X_cam = R X_local + T (mm).
    pub pose: Se3,
    /// Texture painted on the surface.
    pub texture: Texture,
    /// Ray-march step (mm of depth).
    pub march_step_mm: f64,
}

/// A rendered scene.
#[derive(Clone, Debug)]
pub struct Scene {
    /// RGB image.
    pub image: Image<u8>,
    /// Depth (mm), NaN where the ray misses the patch.
    pub depth: DepthMap,
    /// Pixels whose ray hits the patch.
    pub roi: Mask,
    /// Camera intrinsics (px).
    pub intrinsics: Intrinsics,
    /// Camera-from-surface pose (mm).
    pub pose: Se3,
    /// 2 channels: local surface coordinates (x, y) in mm of the visible point (NaN on misses).
    pub surface_xy: Image<f64>,
}

/// The pose of scene.py: patch centre at `dist_mm` on the optical axis, its mean normal tilted by
/// `tilt_deg` about the camera x axis (local z ↦ (0, −sin a, cos a)).
pub fn tilted_pose(tilt_deg: f64, dist_mm: f64) -> Se3 {
    tilted_pose_xy(tilt_deg, 0.0, dist_mm)
}

/// Like [`tilted_pose`], followed by a rotation of `yaw_deg` about the camera y axis.
pub fn tilted_pose_xy(tilt_deg: f64, yaw_deg: f64, dist_mm: f64) -> Se3 {
    let r = Rotation3::from_axis_angle(&Vector3::y_axis(), yaw_deg.to_radians())
        * Rotation3::from_axis_angle(&Vector3::x_axis(), tilt_deg.to_radians());
    Isometry3::from_parts(Translation3::new(0.0, 0.0, dist_mm), UnitQuaternion::from_rotation_matrix(&r))
}

/// scene.py's bumpy bowl: 640×480, f = 500 px, tilt 58°, 100 mm, r = 150 mm, half 55 mm, checkerboard.
pub fn bumpy_bowl_spec() -> SceneSpec {
    SceneSpec {
        intrinsics: Intrinsics::new(500.0, 500.0, 320.0, 240.0, 640, 480).expect("valid intrinsics"),
        surface: Surface::Bumpy { rcurv_mm: 150.0, bumps: SCENE_PY_BUMPS.to_vec() },
        half_mm: 55.0,
        pose: tilted_pose(58.0, 100.0),
        texture: Texture::Checker { square_mm: 5.0 },
        march_step_mm: 0.25,
    }
}

/// The texture photograph at `path` (e.g. `../shared/data/textures/retina.jpg`) if it can be
/// read, else the procedural texture with `seed` (so that demos work without the shared data).
pub fn photo_or_procedural(path: &std::path::Path, seed: u64) -> Texture {
    match laparo_core::io::read_rgb8(path) {
        Ok(img) => Texture::Photo(img),
        Err(_) => Texture::Procedural { seed },
    }
}

fn hash2(seed: u64, i: i64, j: i64) -> f64 {
    let mut h = seed ^ (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ (j as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F);
    h ^= h >> 33;
    h = h.wrapping_mul(0xFF51_AFD7_ED55_8CCD);
    h ^= h >> 33;
    h = h.wrapping_mul(0xC4CE_B9FE_1A85_EC53);
    h ^= h >> 33;
    (h >> 11) as f64 / (1u64 << 53) as f64
}

fn value_noise(seed: u64, x: f64, y: f64) -> f64 {
    let (i, j) = (x.floor() as i64, y.floor() as i64);
    let (fx, fy) = (x - i as f64, y - j as f64);
    let s = |t: f64| t * t * (3.0 - 2.0 * t);
    let (sx, sy) = (s(fx), s(fy));
    let v00 = hash2(seed, i, j);
    let v10 = hash2(seed, i + 1, j);
    let v01 = hash2(seed, i, j + 1);
    let v11 = hash2(seed, i + 1, j + 1);
    (v00 * (1.0 - sx) + v10 * sx) * (1.0 - sy) + (v01 * (1.0 - sx) + v11 * sx) * sy
}

impl Texture {
    /// RGB albedo in [0, 255] at local (x, y) mm on a patch of half-size `half`.
    pub fn rgb(&self, x: f64, y: f64, half: f64) -> [f64; 3] {
        match self {
            Texture::Photo(img) => {
                let u = (x + half) / (2.0 * half) * (img.width - 1) as f64;
                let v = (y + half) / (2.0 * half) * (img.height - 1) as f64;
                let u = u.clamp(0.0, (img.width - 1) as f64);
                let v = v.clamp(0.0, (img.height - 1) as f64);
                let c = |k: usize| img.sample_bilinear(u, v, k.min(img.channels - 1)).unwrap_or(0.0);
                [c(0), c(1), c(2)]
            }
            Texture::Checker { square_mm: sq } => {
                let chk = ((x / sq).floor() + (y / sq).floor()).rem_euclid(2.0);
                [
                    255.0 * (0.25 + 0.6 * chk),
                    255.0 * (0.25 + 0.6 * chk * (0.5 + 0.5 * (x / 20.0).cos())),
                    255.0 * (0.3 + 0.4 * (y + half) / (2.0 * half)),
                ]
            }
            Texture::Procedural { seed } => {
                let mut n = 0.0;
                let mut amp = 0.5;
                let mut f = 1.0 / 12.0;
                for o in 0..5 {
                    n += amp * value_noise(seed.wrapping_add(o), x * f, y * f);
                    amp *= 0.5;
                    f *= 2.0;
                }
                let blob = value_noise(seed ^ 0xABCD, x / 6.0, y / 6.0);
                let spots = if blob > 0.72 { 0.45 } else { 1.0 };
                [
                    255.0 * (0.35 + 0.6 * n) * spots,
                    255.0 * (0.15 + 0.45 * n * n) * spots,
                    255.0 * (0.12 + 0.35 * (1.0 - n)) * spots,
                ]
            }
        }
    }
}

impl SceneSpec {
    /// Render by ray casting (rayon over rows, deterministic).
    pub fn render(&self) -> Result<Scene> {
        let k = self.intrinsics;
        k.validate().map_err(|e| CpcError::invalid("scene intrinsics", e.to_string()))?;
        if !(self.half_mm > 0.0 && self.march_step_mm > 0.0) {
            return Err(CpcError::invalid("scene", "half size and march step must be > 0"));
        }
        if let Surface::Cylinder { radius_mm } = self.surface {
            if self.half_mm.is_nan() || radius_mm.is_nan() || self.half_mm >= radius_mm {
                return Err(CpcError::invalid("scene", "cylinder radius must exceed the patch half-size"));
            }
        }
        let half = self.half_mm;
        let margin = 0.2 * half;
        // Height bounds over the grown square.
        let (mut hmin, mut hmax) = (f64::INFINITY, f64::NEG_INFINITY);
        let n = 200;
        let ext = match self.surface {
            Surface::Cylinder { radius_mm } => (half + margin).min(radius_mm * 0.999),
            _ => half + margin,
        };
        for i in 0..=n {
            for j in 0..=n {
                let x = -ext + 2.0 * ext * i as f64 / n as f64;
                let y = -ext + 2.0 * ext * j as f64 / n as f64;
                let h = self.surface.height(x, y);
                hmin = hmin.min(h);
                hmax = hmax.max(h);
            }
        }
        hmin -= 1.0;
        hmax += 1.0;
        let rot = self.pose.rotation.to_rotation_matrix();
        let rt = rot.matrix().transpose();
        let t = self.pose.translation.vector;
        let o = rt * (-t);
        let (w, h) = (k.width, k.height);
        /// One rendered pixel: ray parameter (depth, mm), surface coordinates (mm), RGB.
        type RenderedPixel = (f64, [f64; 2], [u8; 3]);
        let rows: Vec<Vec<RenderedPixel>> = (0..h)
            .into_par_iter()
            .map(|v| {
                (0..w)
                    .map(|u| {
                        let (xn, yn) = k.pixel_to_normalized(u as f64, v as f64);
                        let d = rt * Vector3::new(xn, yn, 1.0);
                        match self.cast(&o, &d, ext, hmin, hmax) {
                            Some((tt, x, y)) => {
                                let c = self.texture.rgb(x, y, half);
                                (tt, [x, y], c.map(|v| v.round().clamp(0.0, 255.0) as u8))
                            }
                            None => (f64::NAN, [f64::NAN; 2], [0, 0, 0]),
                        }
                    })
                    .collect()
            })
            .collect();
        let mut image = Image::filled(w, h, 3, 0u8);
        let mut depth = vec![f64::NAN; w * h];
        let mut roi = Image::filled(w, h, 1, false);
        let mut sxy = Image::filled(w, h, 2, f64::NAN);
        for (v, row) in rows.into_iter().enumerate() {
            for (u, (tt, xy, c)) in row.into_iter().enumerate() {
                let i = v * w + u;
                depth[i] = tt;
                roi.data[i] = tt.is_finite();
                image.data[3 * i..3 * i + 3].copy_from_slice(&c);
                sxy.data[2 * i] = xy[0];
                sxy.data[2 * i + 1] = xy[1];
            }
        }
        Ok(Scene {
            image,
            depth: DepthMap::new(w, h, DepthUnit::Mm, depth)?,
            roi,
            intrinsics: k,
            pose: self.pose,
            surface_xy: sxy,
        })
    }

    /// First intersection of the local ray o + t d with the patch: (t, x, y).
    fn cast(&self, o: &Vector3<f64>, d: &Vector3<f64>, ext: f64, hmin: f64, hmax: f64) -> Option<(f64, f64, f64)> {
        // Slab clipping against [−ext, ext]² × [hmin, hmax].
        let (mut t0, mut t1) = (1e-9_f64, f64::INFINITY);
        let lo = [-ext, -ext, hmin];
        let hi = [ext, ext, hmax];
        for a in 0..3 {
            if d[a].abs() < 1e-15 {
                if o[a] < lo[a] || o[a] > hi[a] {
                    return None;
                }
            } else {
                let (ta, tb) = ((lo[a] - o[a]) / d[a], (hi[a] - o[a]) / d[a]);
                t0 = t0.max(ta.min(tb));
                t1 = t1.min(ta.max(tb));
            }
        }
        if t0.is_nan() || t1.is_nan() || t0 >= t1 {
            return None;
        }
        let g = |t: f64| {
            let p = o + d * t;
            p.z - self.surface.height(p.x, p.y)
        };
        let step = self.march_step_mm;
        let mut ta = t0;
        let mut ga = g(ta);
        loop {
            let tb = (ta + step).min(t1);
            let gb = g(tb);
            if (ga > 0.0) != (gb > 0.0) {
                let (mut lo, mut hi, mut glo) = (ta, tb, ga);
                for _ in 0..60 {
                    let mid = 0.5 * (lo + hi);
                    let gm = g(mid);
                    if (gm > 0.0) == (glo > 0.0) {
                        lo = mid;
                        glo = gm;
                    } else {
                        hi = mid;
                    }
                }
                let tt = 0.5 * (lo + hi);
                let p = o + d * tt;
                return if p.x.abs() <= self.half_mm && p.y.abs() <= self.half_mm {
                    Some((tt, p.x, p.y))
                } else {
                    None
                };
            }
            if tb >= t1 {
                return None;
            }
            ta = tb;
            ga = gb;
        }
    }
}

impl Scene {
    /// Angle (deg) between the viewing ray and the surface normal at every ROI pixel (NaN elsewhere).
    pub fn view_angles_deg(&self, surface: &Surface) -> Vec<f64> {
        let rot = self.pose.rotation.to_rotation_matrix();
        let t = self.pose.translation.vector;
        (0..self.roi.data.len())
            .map(|i| {
                let (x, y) = (self.surface_xy.data[2 * i], self.surface_xy.data[2 * i + 1]);
                if !x.is_finite() {
                    return f64::NAN;
                }
                let (gx, gy) = surface.gradient(x, y);
                let n = rot * Vector3::new(-gx, -gy, 1.0).normalize();
                let p = rot * Vector3::new(x, y, surface.height(x, y)) + t;
                n.dot(&p.normalize()).abs().clamp(0.0, 1.0).acos().to_degrees()
            })
            .collect()
    }
}

/// The two viewpoints of a rendered two-view pair (see [`pair_spec`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum PairKind {
    /// Small viewpoint change: view 1 at 20° tilt, view 2 at 26° tilt and 4° yaw (≈ 7°).
    Easy,
    /// Strong, oblique viewpoint change: view 1 at 10° tilt, view 2 at 62° tilt and 15° yaw
    /// (≈ 55°): view 2 sees the bumpy surface obliquely.
    Hard,
}

impl std::str::FromStr for PairKind {
    type Err = CpcError;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "easy" => Ok(PairKind::Easy),
            "hard" => Ok(PairKind::Hard),
            o => Err(CpcError::invalid("pair", format!("'{o}' is not easy or hard"))),
        }
    }
}

impl PairKind {
    /// (tilt, yaw) in degrees of view 1 and view 2 ([`tilted_pose_xy`], 100 mm).
    pub fn tilts_yaws_deg(self) -> [(f64, f64); 2] {
        match self {
            PairKind::Easy => [(20.0, 0.0), (26.0, 4.0)],
            PairKind::Hard => [(10.0, 0.0), (62.0, 15.0)],
        }
    }
}

/// Two rendered views of one surface with exact ground truth (poses, depth, surface coordinates).
#[derive(Clone, Debug)]
pub struct ScenePair {
    /// View 1.
    pub view1: Scene,
    /// View 2.
    pub view2: Scene,
    /// Angle (deg) of the relative rotation between the two cameras.
    pub viewpoint_change_deg: f64,
}

/// The specs of the two views of `kind`: the bumpy bowl of [`bumpy_bowl_spec`] with `texture`,
/// seen from the poses of [`PairKind::tilts_yaws_deg`] at 100 mm.
pub fn pair_spec(kind: PairKind, texture: Texture) -> [SceneSpec; 2] {
    let mut base = bumpy_bowl_spec();
    base.texture = texture;
    kind.tilts_yaws_deg().map(|(t, y)| SceneSpec { pose: tilted_pose_xy(t, y, 100.0), ..base.clone() })
}

/// Render both views of `specs` (same surface and texture, two poses).
pub fn render_pair(specs: &[SceneSpec; 2]) -> Result<ScenePair> {
    let view1 = specs[0].render()?;
    let view2 = specs[1].render()?;
    let rel = view2.pose.rotation * view1.pose.rotation.inverse();
    Ok(ScenePair { viewpoint_change_deg: rel.angle().to_degrees(), view1, view2 })
}
