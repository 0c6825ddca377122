//! A synthetic, analytically rendered rectified stereo scene with exact disparity ground truth:
//! a slanted textured plane and a textured box in front of it, seen by two pinhole cameras
//! (same K, right camera at (b, 0, 0)). Used by the demo and by tests, which can also render
//! the scene through *augmented* cameras to get the true augmented disparity independently of
//! the augmentation code.
use crate::augment::StereoSample;
use laparo_core::{Image, Intrinsics};
use nalgebra::{Matrix3, Vector3};

/// The scene (units: mm).
#[derive(Clone, Copy, Debug)]
pub struct Scene {
    /// Background plane n·P = c (n not necessarily unit).
    pub plane_n: Vector3<f64>,
    /// Plane offset c of n·P = c (mm).
    pub plane_c: f64,
    /// Axis-aligned box [min, max].
    pub box_min: Vector3<f64>,
    /// Upper corner of the box (mm).
    pub box_max: Vector3<f64>,
}

impl Default for Scene {
    fn default() -> Self {
        // Plane z = 1000 + 0.25 X + 0.1 Y (slanted), box 400 mm wide at z 650..800.
        Scene {
            plane_n: Vector3::new(-0.25, -0.1, 1.0),
            plane_c: 1000.0,
            box_min: Vector3::new(-260.0, -120.0, 650.0),
            box_max: Vector3::new(140.0, 170.0, 800.0),
        }
    }
}

impl Scene {
    /// First intersection of the ray o + t·dir (t > 0): (t, point).
    pub fn intersect(&self, o: &Vector3<f64>, dir: &Vector3<f64>) -> Option<(f64, Vector3<f64>)> {
        let mut best: Option<f64> = None;
        let den = self.plane_n.dot(dir);
        if den.abs() > 1e-12 {
            let t = (self.plane_c - self.plane_n.dot(o)) / den;
            if t > 0.0 {
                best = Some(t);
            }
        }
        // Slab test for the box.
        let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
        let mut hit = true;
        for i in 0..3 {
            if dir[i].abs() < 1e-15 {
                if o[i] < self.box_min[i] || o[i] > self.box_max[i] {
                    hit = false;
                }
            } else {
                let a = (self.box_min[i] - o[i]) / dir[i];
                let b = (self.box_max[i] - o[i]) / dir[i];
                t0 = t0.max(a.min(b));
                t1 = t1.min(a.max(b));
            }
        }
        if hit && t0 <= t1 && t0 > 0.0 && best.is_none_or(|b| t0 < b) {
            best = Some(t0);
        }
        best.map(|t| (t, o + dir * t))
    }

    /// Procedural RGB texture of a surface point (smooth, several octaves, periods >= ~25 mm).
    pub fn texture(p: &Vector3<f64>) -> [f64; 3] {
        let (x, y, z) = (p.x, p.y, p.z);
        let a = (x * 0.045).sin() * (y * 0.031).cos() + 0.5 * ((x + y) * 0.083 + z * 0.05).sin();
        let b = (y * 0.052 + 1.0).sin() * (z * 0.04 - x * 0.02).cos() + 0.4 * (x * 0.11 - y * 0.07).sin();
        let c = ((x - y) * 0.037).cos() + 0.5 * (z * 0.09 + x * 0.06).sin() * (y * 0.05).cos();
        let s = |v: f64| (128.0 + 70.0 * v).clamp(0.0, 255.0);
        [s(a), s(b), s(0.5 * (a + c))]
    }

    /// Render a camera with intrinsics `k`, rotation `r` (world → camera: P_c = R (P − C)) and
    /// centre `c`: RGB image and the depth z_c of each pixel (NaN where nothing is hit).
    /// Each pixel averages `ss`×`ss` sub-samples (anti-aliasing).
    pub fn render(&self, k: &Intrinsics, r: &Matrix3<f64>, c: &Vector3<f64>, ss: usize) -> (Image<u8>, Image<f64>) {
        let (w, h) = (k.width, k.height);
        let mut img = Image::filled(w, h, 3, 0u8);
        let mut depth = Image::filled(w, h, 1, f64::NAN);
        let rt = r.transpose();
        let ss = ss.max(1);
        for y in 0..h {
            for x in 0..w {
                let mut acc = [0.0; 3];
                let mut n = 0.0;
                for sy in 0..ss {
                    for sx in 0..ss {
                        let u = x as f64 + (sx as f64 + 0.5) / ss as f64 - 0.5;
                        let v = y as f64 + (sy as f64 + 0.5) / ss as f64 - 0.5;
                        let (xn, yn) = k.pixel_to_normalized(u, v);
                        let d = rt * Vector3::new(xn, yn, 1.0);
                        if let Some((_, p)) = self.intersect(c, &d) {
                            let t = Self::texture(&p);
                            for (a, ti) in acc.iter_mut().zip(t) {
                                *a += ti;
                            }
                            n += 1.0;
                        }
                    }
                }
                if n > 0.0 {
                    for (i, a) in acc.iter().enumerate() {
                        img.set(x, y, i, (a / n + 0.5) as u8);
                    }
                }
                let (xn, yn) = k.pixel_to_normalized(x as f64, y as f64);
                if let Some((_, p)) = self.intersect(c, &(rt * Vector3::new(xn, yn, 1.0))) {
                    depth.set(x, y, 0, (r * (p - c)).z);
                }
            }
        }
        (img, depth)
    }

    /// A rectified stereo sample (left at the origin, right at (baseline_mm, 0, 0), both with
    /// `k`) with exact left and right disparity d = f b / z.
    pub fn stereo_sample(&self, k: &Intrinsics, baseline_mm: f64, ss: usize) -> StereoSample {
        let i = Matrix3::identity();
        let (l, dl) = self.render(k, &i, &Vector3::zeros(), ss);
        let (r, dr) = self.render(k, &i, &Vector3::new(baseline_mm, 0.0, 0.0), ss);
        let disp = |d: &Image<f64>| {
            d.map(|z| if z.is_finite() && z > 0.0 { (k.fx * baseline_mm / z) as f32 } else { f32::INFINITY })
        };
        StereoSample {
            disp_left: Some(disp(&dl)),
            disp_right: Some(disp(&dr)),
            left: l,
            right: r,
            occ_left: None,
            occ_right: None,
        }
    }
}

/// The default demo / test camera: `width`×`height`, f = 1.1·width, centred principal point.
pub fn default_camera(width: usize, height: usize) -> Intrinsics {
    Intrinsics::new(
        1.1 * width as f64,
        1.1 * width as f64,
        (width as f64 - 1.0) / 2.0,
        (height as f64 - 1.0) / 2.0,
        width,
        height,
    )
    .expect("valid camera")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn disparity_matches_rendered_correspondence() {
        // The right image at x − d must show the same texture point as the left pixel.
        let k = default_camera(96, 64);
        let s = Scene::default().stereo_sample(&k, 60.0, 1);
        let d = s.disp_left.as_ref().unwrap();
        let z = k.fx * 60.0 / d.get(40, 30, 0) as f64;
        let p = k.backproject(40.0, 30.0, z);
        let (u, v) = k.project(&(p - Vector3::new(60.0, 0.0, 0.0))).unwrap();
        assert!((u - (40.0 - d.get(40, 30, 0) as f64)).abs() < 1e-4 && (v - 30.0).abs() < 1e-9);
    }
}
