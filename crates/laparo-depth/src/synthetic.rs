//! Built-in synthetic surgical-like RGB-D data for the demo and tests (no thesis counterpart:
//! RoDEM's real data is ex-vivo, §3.2.6).
//!
//! * [`organ_scene`]: a procedural "abdominal" scene seen by a pinhole laparoscope — a cavity
//!   wall with two organ-like domes in front of it (irregular outlines, occlusion steps, fine
//!   bumps), metric depth in [5, 20] cm, tissue-coloured procedural texture with vessels, lit by
//!   a light source co-located with the camera (Lambertian + inverse-square fall-off + wet
//!   Blinn–Phong specularities, as in laparoscopy, §2.1).
//! * [`SyntheticMethod`]: stand-ins for monocular depth networks with known output kind
//!   (depth / disparity), scale, shift, noise, geometric flattening and sensitivity to image
//!   degradation, so that evaluations have known answers.
//! * [`organ_sequence`]: a deformation (tool indentation) or incision sequence with a gesture
//!   frame index; frames before it are identical to the clean scene (the clean reference of
//!   eq. 3.4 for gesture perturbations).
//!
//! Everything is deterministic per seed (ChaCha8).
//!
//! Length: ~540 lines of code; the rest are its tests.
use crate::align::PredKind;
use crate::perturb::{Fbm, ValueNoise};
use laparo_core::{CoreError, DepthMap, DepthUnit, Image, Intrinsics, Result};
use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

/// Nearest and farthest depth of the generated scenes, m.
pub const SCENE_DEPTH_RANGE_M: (f64, f64) = (0.05, 0.20);

/// An RGB image with metric depth and the camera that sees both.
#[derive(Clone, Debug)]
pub struct SyntheticScene {
    /// 8-bit RGB laparoscope image.
    pub rgb: Image<u8>,
    /// Depth along the optical axis, metres, all pixels valid.
    pub depth: DepthMap,
    /// Pinhole intrinsics of `rgb` and `depth` (px).
    pub intrinsics: Intrinsics,
}

/// An organ dome: centre and radii in metres on the plane z = `base_m`, outline harmonics.
#[derive(Clone, Debug)]
struct Organ {
    cx: f64,
    cy: f64,
    rx: f64,
    ry: f64,
    base_m: f64,
    height_m: f64,
    harm: [(f64, f64); 3],
    albedo: [f32; 3],
}

impl Organ {
    /// Relative radial distance of lateral point (X, Y) (< 1 inside).
    fn rel(&self, x: f64, y: f64) -> f64 {
        let (dx, dy) = ((x - self.cx) / self.rx, (y - self.cy) / self.ry);
        let th = dy.atan2(dx);
        let mut m = 1.0;
        for (k, (a, ph)) in self.harm.iter().enumerate() {
            m += a * ((k as f64 + 2.0) * th + ph).cos();
        }
        (dx * dx + dy * dy).sqrt() / m
    }
    /// Surface depth at lateral point (X, Y), if inside.
    fn z(&self, x: f64, y: f64) -> Option<f64> {
        let r = self.rel(x, y);
        (r < 1.0).then(|| self.base_m - self.height_m * (1.0 - r * r).sqrt())
    }
}

/// Surface model shared by the scene and the sequences.
#[derive(Clone, Debug)]
struct Surface {
    organs: Vec<Organ>,
    wall_m: f64,
    wall_tilt: (f64, f64),
    bumps: Fbm,
    bump_amp_m: f64,
    tex: Fbm,
    vessels: ValueNoise,
    vessels2: ValueNoise,
    wet: ValueNoise,
    wall_albedo: [f32; 3],
    /// Optional deformation: (centre X, Y in m, radius m, depth m) indentation pushing away from the camera.
    dent: Option<(f64, f64, f64, f64)>,
    /// Optional incision: segment (X0, Y0)-(X1, Y1) in m, half-width m, depth m.
    cut: Option<(f64, f64, f64, f64, f64, f64)>,
}

/// Which surface a ray hits.
#[derive(Clone, Copy, PartialEq)]
enum Hit {
    Wall,
    Organ(usize),
}

impl Surface {
    fn new(rng: &mut ChaCha8Rng) -> Surface {
        // Texture fields live in metric lateral coordinates scaled to "pixels" of 0.1 mm.
        let span = 4000; // 40 cm of lateral extent at 0.1 mm per unit
        let organs = vec![
            Organ {
                cx: rng.gen_range(-0.025..-0.01),
                cy: rng.gen_range(-0.01..0.01),
                rx: rng.gen_range(0.045..0.055),
                ry: rng.gen_range(0.035..0.045),
                base_m: 0.15,
                height_m: rng.gen_range(0.05..0.06),
                harm: std::array::from_fn(|_| (rng.gen_range(0.0..0.08), rng.gen_range(0.0..std::f64::consts::TAU))),
                albedo: [0.50, 0.13, 0.10], // liver-like
            },
            Organ {
                cx: rng.gen_range(0.02..0.035),
                cy: rng.gen_range(0.0..0.015),
                rx: rng.gen_range(0.022..0.028),
                ry: rng.gen_range(0.017..0.022),
                base_m: 0.11,
                height_m: rng.gen_range(0.03..0.035),
                harm: std::array::from_fn(|_| (rng.gen_range(0.0..0.06), rng.gen_range(0.0..std::f64::consts::TAU))),
                albedo: [0.62, 0.24, 0.20], // kidney-like
            },
        ];
        Surface {
            organs,
            wall_m: 0.185,
            wall_tilt: (rng.gen_range(-0.05..0.05), rng.gen_range(0.0..0.08)),
            bumps: Fbm::new(rng, span, span, 250.0, 3),
            bump_amp_m: 0.003,
            tex: Fbm::new(rng, span, span, 120.0, 4),
            vessels: ValueNoise::new(rng, span, span, 90.0),
            vessels2: ValueNoise::new(rng, span, span, 40.0),
            wet: ValueNoise::new(rng, span, span, 60.0),
            wall_albedo: [0.78, 0.52, 0.42], // peritoneum / fat
            dent: None,
            cut: None,
        }
    }

    /// Texture coordinates (0.1 mm units, offset to be positive) of lateral point (X, Y) in m.
    fn uv(x: f64, y: f64) -> (f64, f64) {
        ((x + 0.2) * 1e4, (y + 0.2) * 1e4)
    }

    /// Depth of surface `hit` at lateral (X, Y), m (None if that organ does not cover it).
    fn z_of(&self, hit: Hit, x: f64, y: f64) -> Option<f64> {
        let (u, v) = Self::uv(x, y);
        let bump = self.bump_amp_m * (self.bumps.at(u, v) as f64 - 0.5);
        let mut z = match hit {
            Hit::Wall => self.wall_m + self.wall_tilt.0 * x + self.wall_tilt.1 * y + bump,
            Hit::Organ(i) => self.organs[i].z(x, y)? + 0.5 * bump,
        };
        if let (Hit::Organ(0), Some((dx, dy, r, d))) = (hit, self.dent) {
            let q = ((x - dx).powi(2) + (y - dy).powi(2)) / (r * r);
            z += d * (-q).exp();
        }
        if let (Hit::Organ(0), Some(c)) = (hit, self.cut) {
            let dist = seg_dist(x, y, c);
            if dist < c.4 {
                z += c.5 * (1.0 - (dist / c.4).powi(2));
            }
        }
        Some(z)
    }

    /// Intersect the ray through normalised coordinates (xn, yn): returns (z, surface).
    /// Each surface is a height field z = f(X, Y); the ray point is found by fixed-point
    /// iteration z ← f(xn z, yn z) (contractive for these gentle surfaces), nearest wins.
    fn intersect(&self, xn: f64, yn: f64) -> (f64, Hit) {
        let mut best = (f64::INFINITY, Hit::Wall);
        for hit in std::iter::once(Hit::Wall).chain((0..self.organs.len()).map(Hit::Organ)) {
            let mut z = 0.12;
            let mut ok = true;
            for _ in 0..40 {
                match self.z_of(hit, xn * z, yn * z) {
                    Some(zn) => {
                        let done = (zn - z).abs() < 1e-10;
                        z = zn;
                        if done {
                            break;
                        }
                    }
                    None => {
                        ok = false;
                        break;
                    }
                }
            }
            if ok && z < best.0 {
                best = (z, hit);
            }
        }
        best
    }

    fn albedo(&self, hit: Hit, x: f64, y: f64) -> [f32; 3] {
        let (u, v) = Self::uv(x, y);
        let base = match hit {
            Hit::Wall => self.wall_albedo,
            Hit::Organ(i) => self.organs[i].albedo,
        };
        let t = 0.75 + 0.5 * self.tex.at(u, v);
        let mut c = base.map(|b| b * t);
        // Vessels: thin dark-red curves where smooth noise crosses 0.5.
        let vs = (self.vessels.at(u, v) - 0.5).abs().min((self.vessels2.at(u, v) - 0.5).abs() * 1.6);
        let vess = 1.0 - smooth01((vs - 0.006) / 0.012);
        let vcol = [0.35, 0.04, 0.08];
        for k in 0..3 {
            c[k] = c[k] * (1.0 - 0.7 * vess) + vcol[k] * 0.7 * vess;
        }
        if let (Hit::Organ(0), Some(cut)) = (hit, self.cut) {
            let d = seg_dist(x, y, cut);
            if d < cut.4 {
                let a = 1.0 - (d / cut.4) as f32;
                let inner = [0.45, 0.03, 0.04];
                for k in 0..3 {
                    c[k] = c[k] * (1.0 - a) + inner[k] * a;
                }
            }
        }
        c
    }
}

fn smooth01(t: f32) -> f32 {
    let t = t.clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

fn seg_dist(x: f64, y: f64, c: (f64, f64, f64, f64, f64, f64)) -> f64 {
    let (ax, ay, bx, by) = (c.0, c.1, c.2, c.3);
    let (vx, vy) = (bx - ax, by - ay);
    let l2 = vx * vx + vy * vy;
    let t = if l2 > 0.0 { (((x - ax) * vx + (y - ay) * vy) / l2).clamp(0.0, 1.0) } else { 0.0 };
    ((x - ax - t * vx).powi(2) + (y - ay - t * vy).powi(2)).sqrt()
}

/// Laparoscope-like intrinsics for a `width × height` image: 70° horizontal field of view,
/// centred principal point.
pub fn default_intrinsics(width: usize, height: usize) -> Result<Intrinsics> {
    let f = width as f64 / 2.0 / (35f64.to_radians()).tan();
    Intrinsics::new(f, f, (width as f64 - 1.0) / 2.0, (height as f64 - 1.0) / 2.0, width, height)
}

fn render(surface: &Surface, k: &Intrinsics) -> Result<SyntheticScene> {
    let (w, h) = (k.width, k.height);
    // Pass 1: depth and surface id per pixel.
    let hits: Vec<(f64, Hit)> = (0..w * h)
        .into_par_iter()
        .map(|i| {
            let (xn, yn) = k.pixel_to_normalized((i % w) as f64, (i / w) as f64);
            let (z, hit) = surface.intersect(xn, yn);
            (z.clamp(SCENE_DEPTH_RANGE_M.0, SCENE_DEPTH_RANGE_M.1), hit)
        })
        .collect();
    // Pass 2: shading with a light at the camera centre.
    let mut rgb = vec![0u8; w * h * 3];
    rgb.par_chunks_mut(w * 3).enumerate().for_each(|(y, row)| {
        for x in 0..w {
            let (z, hit) = hits[y * w + x];
            let p = k.backproject(x as f64, y as f64, z);
            // Normal from neighbouring points on the same surface (one-sided where needed).
            let nb = |dx: isize, dy: isize| -> Option<Vector3<f64>> {
                let (xx, yy) = (x as isize + dx, y as isize + dy);
                if xx < 0 || yy < 0 || xx >= w as isize || yy >= h as isize {
                    return None;
                }
                let (zz, hh) = hits[yy as usize * w + xx as usize];
                (hh == hit).then(|| k.backproject(xx as f64, yy as f64, zz))
            };
            let tx = match (nb(1, 0), nb(-1, 0)) {
                (Some(a), Some(b)) => a - b,
                (Some(a), None) => a - p,
                (None, Some(b)) => p - b,
                _ => Vector3::x(),
            };
            let ty = match (nb(0, 1), nb(0, -1)) {
                (Some(a), Some(b)) => a - b,
                (Some(a), None) => a - p,
                (None, Some(b)) => p - b,
                _ => Vector3::y(),
            };
            let mut n = tx.cross(&ty);
            if n.norm() < 1e-15 {
                n = -Vector3::z();
            }
            n = n.normalize();
            let l = -p.normalize();
            if n.dot(&l) < 0.0 {
                n = -n;
            }
            let ndl = n.dot(&l).max(0.0) as f32;
            let fall = ((0.11 / z).powi(2) as f32).min(1.4);
            let (u, v) = Surface::uv(p.x, p.y);
            let wet = 0.25 + 0.75 * surface.wet.at(u, v);
            let spec = 0.9 * wet * ndl.powf(60.0) * fall.min(1.5);
            let a = surface.albedo(hit, p.x, p.y);
            for c in 0..3 {
                let v = a[c] * (0.12 + 0.88 * ndl) * fall * 1.25 + spec;
                row[3 * x + c] = (v.clamp(0.0, 1.0) * 255.0).round() as u8;
            }
        }
    });
    Ok(SyntheticScene {
        rgb: Image::from_vec(w, h, 3, rgb)?,
        depth: DepthMap::new(w, h, DepthUnit::M, hits.iter().map(|h| h.0).collect())?,
        intrinsics: *k,
    })
}

fn check_size(width: usize, height: usize) -> Result<()> {
    if width < 16 || height < 16 || width > 8192 || height > 8192 {
        return Err(CoreError::invalid("scene size", format!("{width}x{height} (expected 16..=8192 px per side)")));
    }
    Ok(())
}

/// A procedural organ scene of `width × height` px (deterministic per seed).
pub fn organ_scene(width: usize, height: usize, seed: u64) -> Result<SyntheticScene> {
    check_size(width, height)?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let surface = Surface::new(&mut rng);
    render(&surface, &default_intrinsics(width, height)?)
}

/// Surgical gesture of a sequence (thesis §3.2.6: organ deformation, incision).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Gesture {
    /// A tool presses into the large organ: a Gaussian indentation growing to 1 cm.
    Deformation,
    /// A cut grows across the large organ: a groove 4 mm deep, dark red inside.
    Incision,
}

impl Gesture {
    /// Perturbation key (as in the manifest vocabulary).
    pub fn name(self) -> &'static str {
        match self {
            Gesture::Deformation => "deformation",
            Gesture::Incision => "incision",
        }
    }
}

/// A gesture sequence: frames `..gesture_frame` show the untouched scene (clean reference).
#[derive(Clone, Debug)]
pub struct SyntheticSequence {
    /// The gesture shown.
    pub gesture: Gesture,
    /// The frames, untouched scene first.
    pub frames: Vec<SyntheticScene>,
    /// Index of the first frame at or after the gesture.
    pub gesture_frame: usize,
}

/// A deformation or incision sequence of `n_frames` frames whose gesture starts at
/// `gesture_frame` and reaches full amplitude at the last frame (deterministic per seed).
pub fn organ_sequence(
    width: usize,
    height: usize,
    n_frames: usize,
    gesture_frame: usize,
    gesture: Gesture,
    seed: u64,
) -> Result<SyntheticSequence> {
    check_size(width, height)?;
    if n_frames == 0 || gesture_frame >= n_frames {
        return Err(CoreError::invalid(
            "sequence",
            format!("gesture_frame {gesture_frame} must be < n_frames {n_frames} (n_frames >= 1)"),
        ));
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let base = Surface::new(&mut rng);
    let k = default_intrinsics(width, height)?;
    let o = &base.organs[0];
    let (cx, cy) = (o.cx + rng.gen_range(-0.2..0.2) * o.rx, o.cy + rng.gen_range(-0.2..0.2) * o.ry);
    let ang: f64 = rng.gen_range(0.0..std::f64::consts::PI);
    let half_len = 0.6 * o.rx.min(o.ry);
    let frames = (0..n_frames)
        .map(|f| {
            let mut s = base.clone();
            if f >= gesture_frame {
                let prog = (f - gesture_frame + 1) as f64 / (n_frames - gesture_frame) as f64;
                match gesture {
                    Gesture::Deformation => s.dent = Some((cx, cy, 0.012, 0.010 * prog)),
                    Gesture::Incision => {
                        let l = half_len * prog;
                        s.cut = Some((
                            cx - l * ang.cos(),
                            cy - l * ang.sin(),
                            cx + l * ang.cos(),
                            cy + l * ang.sin(),
                            0.0025,
                            0.004,
                        ))
                    }
                }
            }
            render(&s, &k)
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(SyntheticSequence { gesture, frames, gesture_frame })
}

/// A stand-in monocular depth method with known behaviour.
///
/// With true disparity `q = 1/z*` (1/m), image degradation `D ∈ [0, 1]` (local mean of the
/// absolute luminance change between observed and clean image, ×`4`, clipped) and mean disparity
/// `q̄`, the method "sees" `q̃ = (1 − f) q + f q̄` with flattening `f = flatten + sensitivity·D`
/// (networks tend to flatten bumpy organs, thesis App. C.1), multiplied by `1 + ε`, where `ε` is
/// smooth low-frequency noise (amplitude a) plus white noise (0.1 a), a = `noise_rel·(1 + 2·sensitivity·D)`.
/// The output is `scale·q̃ + shift` (disparity) or `scale/q̃ + shift` (depth).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SyntheticMethod {
    /// Method name.
    pub name: String,
    /// Whether the output is depth or disparity.
    pub kind: PredKind,
    /// Output scale.
    pub scale: f64,
    /// Output shift.
    pub shift: f64,
    /// Relative noise amplitude a0.
    pub noise_rel: f64,
    /// Base flattening f0 towards the mean disparity.
    pub flatten: f64,
    /// Extra flattening and noise per unit of image degradation.
    pub sensitivity: f64,
}

/// Four methods spanning the thesis' families (§3.2.7): an up-to-scale self-supervised
/// surgical model (the mCE baseline, like AF-SfM), an affine-invariant disparity foundation
/// model (like DA), a noisier affine disparity model (like MiDaS), and a biased metric model.
pub fn default_methods() -> Vec<SyntheticMethod> {
    vec![
        SyntheticMethod {
            name: "SfM-like".into(),
            kind: PredKind::Depth,
            scale: 0.3,
            shift: 0.0,
            noise_rel: 0.08,
            flatten: 0.25,
            sensitivity: 0.9,
        },
        SyntheticMethod {
            name: "Foundation-like".into(),
            kind: PredKind::Disparity,
            scale: 0.02,
            shift: 1.5,
            noise_rel: 0.03,
            flatten: 0.05,
            sensitivity: 0.35,
        },
        SyntheticMethod {
            name: "Affine-noisy".into(),
            kind: PredKind::Disparity,
            scale: 0.05,
            shift: 0.3,
            noise_rel: 0.05,
            flatten: 0.12,
            sensitivity: 0.7,
        },
        SyntheticMethod {
            name: "Metric-biased".into(),
            kind: PredKind::Depth,
            scale: 1.15,
            shift: 0.0,
            noise_rel: 0.06,
            flatten: 0.15,
            sensitivity: 0.5,
        },
    ]
}

/// Degradation map D ∈ [0, 1]: box mean (radius ~ 1/40 of the width) of |ΔL|/255 × 4.
pub fn degradation_map(clean: &Image<u8>, observed: &Image<u8>) -> Result<Vec<f32>> {
    clean.check_same_size(observed, "clean vs observed image")?;
    let (w, h) = (clean.width, clean.height);
    let (a, b) = (clean.to_gray_f32(), observed.to_gray_f32());
    let diff: Vec<f32> = a.data.iter().zip(&b.data).map(|(x, y)| (x - y).abs() / 255.0).collect();
    let r = (w / 40).max(1);
    // Separable box filter with clamped windows.
    let box1 = |src: &[f32], n: usize, stride: usize, len: usize, count: usize| -> Vec<f32> {
        let mut out = vec![0f32; src.len()];
        for line in 0..count {
            let base = line * if stride == 1 { len } else { 1 };
            let mut pre = vec![0f64; len + 1];
            for i in 0..len {
                pre[i + 1] = pre[i] + src[base + i * stride] as f64;
            }
            for i in 0..len {
                let (lo, hi) = (i.saturating_sub(n), (i + n).min(len - 1));
                out[base + i * stride] = ((pre[hi + 1] - pre[lo]) / (hi - lo + 1) as f64) as f32;
            }
        }
        out
    };
    let hpass = box1(&diff, r, 1, w, h);
    let v = box1(&hpass, r, w, h, w);
    Ok(v.into_iter().map(|d| (4.0 * d).min(1.0)).collect())
}

impl SyntheticMethod {
    /// Predict from the observed image (see the type documentation for the model).
    /// `gt` must be valid everywhere (as [`organ_scene`] makes it). Deterministic per seed.
    pub fn predict(&self, gt: &DepthMap, clean: &Image<u8>, observed: &Image<u8>, seed: u64) -> Result<Image<f64>> {
        let (w, h) = (gt.width, gt.height);
        if clean.width != w || clean.height != h {
            return Err(CoreError::SizeMismatch(format!("GT {w}x{h} vs image {}x{}", clean.width, clean.height)));
        }
        let to_m = gt.unit.to_metres();
        let q: Vec<f64> = gt.data.iter().map(|z| 1.0 / (z * to_m)).collect();
        if !q.iter().all(|v| v.is_finite() && *v > 0.0) {
            return Err(CoreError::invalid("synthetic GT", "must be finite and > 0 everywhere"));
        }
        let qbar = q.iter().sum::<f64>() / q.len() as f64;
        let deg = degradation_map(clean, observed)?;
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x005e_ed0f_3e7d);
        let smooth = Fbm::new(&mut rng, w, h, w as f64 / 4.0, 3);
        let row_seed: u64 = rng.gen();
        let mut out = vec![0f64; w * h];
        out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
            let mut r = ChaCha8Rng::seed_from_u64(row_seed.wrapping_add(y as u64 * 0x9e37_79b9_7f4a_7c15));
            for (x, o) in row.iter_mut().enumerate() {
                let i = y * w + x;
                let d = deg[i] as f64;
                let f = (self.flatten + self.sensitivity * d).min(1.0);
                let amp = self.noise_rel * (1.0 + 2.0 * self.sensitivity * d);
                let eps = amp * (2.0 * (smooth.at(x as f64, y as f64) as f64 - 0.5) + 0.1 * r.gen_range(-1.0..1.0));
                let qt = ((1.0 - f) * q[i] + f * qbar) * (1.0 + eps);
                *o = match self.kind {
                    PredKind::Disparity => self.scale * qt + self.shift,
                    PredKind::Depth => self.scale / qt + self.shift,
                };
            }
        });
        Image::from_vec(w, h, 1, out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scene_is_deterministic_and_in_range() {
        let a = organ_scene(96, 72, 3).unwrap();
        let b = organ_scene(96, 72, 3).unwrap();
        let c = organ_scene(96, 72, 4).unwrap();
        assert_eq!(a.rgb, b.rgb);
        assert_eq!(a.depth, b.depth);
        assert_ne!(a.rgb, c.rgb);
        let (lo, hi) = a.depth.data.iter().fold((f64::MAX, f64::MIN), |(l, h), &z| (l.min(z), h.max(z)));
        assert!(lo >= 0.05 && hi <= 0.20, "{lo} {hi}");
        assert!(hi - lo > 0.05, "scene should have relief: {lo}..{hi}");
        // Tissue colours: red dominates green and blue on average.
        let m: Vec<f64> =
            (0..3).map(|c| a.rgb.data.iter().skip(c).step_by(3).map(|&v| v as f64).sum::<f64>()).collect();
        assert!(m[0] > m[1] && m[0] > m[2]);
    }

    #[test]
    fn depth_matches_ray_surface_intersection() {
        // The depth of every pixel lies on its surface: z = f(xn z, yn z) to 1e-8.
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let s = Surface::new(&mut rng);
        let k = default_intrinsics(64, 48).unwrap();
        for (x, y) in [(3.0, 4.0), (32.0, 24.0), (60.0, 40.0), (10.0, 30.0)] {
            let (xn, yn) = k.pixel_to_normalized(x, y);
            let (z, hit) = s.intersect(xn, yn);
            let f = s.z_of(hit, xn * z, yn * z).unwrap();
            assert!((f - z).abs() < 1e-8);
        }
    }

    #[test]
    fn clean_prediction_has_known_scale_and_shift() {
        let sc = organ_scene(64, 48, 1).unwrap();
        // No noise, no flattening: a disparity method returns exactly s/z + t.
        let m = SyntheticMethod {
            name: "exact".into(),
            kind: PredKind::Disparity,
            scale: 2.0,
            shift: 0.5,
            noise_rel: 0.0,
            flatten: 0.0,
            sensitivity: 1.0,
        };
        let p = m.predict(&sc.depth, &sc.rgb, &sc.rgb, 0).unwrap();
        for (pv, z) in p.data.iter().zip(&sc.depth.data) {
            assert!((pv - (2.0 / z + 0.5)).abs() < 1e-9);
        }
        let m = SyntheticMethod { kind: PredKind::Depth, shift: 0.0, ..m };
        let p = m.predict(&sc.depth, &sc.rgb, &sc.rgb, 0).unwrap();
        for (pv, z) in p.data.iter().zip(&sc.depth.data) {
            assert!((pv - 2.0 * z).abs() < 1e-12);
        }
    }

    #[test]
    fn degradation_increases_prediction_error() {
        let sc = organ_scene(96, 72, 2).unwrap();
        let m = &default_methods()[0];
        let err = |obs: &Image<u8>| {
            let p = m.predict(&sc.depth, &sc.rgb, obs, 5).unwrap();
            // Relative error after the known scale is removed.
            p.data.iter().zip(&sc.depth.data).map(|(pv, z)| (pv / m.scale - z).abs() / z).sum::<f64>()
                / p.data.len() as f64
        };
        let e0 = err(&sc.rgb);
        let e3 = err(&crate::perturb::apply(&sc.rgb, crate::perturb::Perturbation::Smoke, 3, 1).unwrap());
        assert!(e3 > e0 * 1.2, "{e0} {e3}");
    }

    #[test]
    fn sequence_clean_before_gesture() {
        for g in [Gesture::Deformation, Gesture::Incision] {
            let s = organ_sequence(64, 48, 5, 2, g, 9).unwrap();
            assert_eq!(s.frames.len(), 5);
            let clean = organ_scene(64, 48, 9).unwrap();
            assert_eq!(s.frames[0].depth, clean.depth);
            assert_eq!(s.frames[1].rgb, clean.rgb);
            // After the gesture the surface changes more and more.
            let diff = |f: &SyntheticScene| {
                f.depth.data.iter().zip(&clean.depth.data).map(|(a, b)| (a - b).abs()).sum::<f64>()
            };
            let (d2, d4) = (diff(&s.frames[2]), diff(&s.frames[4]));
            assert!(d2 > 0.0 && d4 > d2, "{g:?}: {d2} {d4}");
        }
        assert!(organ_sequence(64, 48, 3, 3, Gesture::Incision, 0).is_err());
    }
}
