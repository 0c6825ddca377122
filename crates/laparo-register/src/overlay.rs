//! Augmented-reality overlay (§5.4.3): the registered surface and the tumour projected with a pinhole +
//! distortion camera (laparo-core `Intrinsics`, `Distortion`) over an image, z-buffered, Lambert-shaded
//! and alpha-blended; the tumour is drawn through the organ (x-ray view, as surgeons' AR displays do).
use laparo_core::image::Image;
use laparo_core::{Distortion, Intrinsics};
use nalgebra::{Matrix3, Vector3};

/// A model → camera rigid transform (camera: x right, y down, z forward; mm).
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct CameraPose {
    /// Rotation.
    pub rotation: Matrix3<f64>,
    /// Translation (mm).
    pub translation: Vector3<f64>,
}

impl CameraPose {
    /// A pose that puts the centre of `points` on the optical axis at the depth where their bounding
    /// box spans `fill` of the image width (model axes = camera axes).
    pub fn framing(points: &[Vector3<f64>], k: &Intrinsics, fill: f64) -> Self {
        let mut lo = points[0];
        let mut hi = points[0];
        for p in points {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        let c = (lo + hi) / 2.0;
        let size = (hi[0] - lo[0]).max(hi[1] - lo[1]);
        let z = k.fx * size / (fill * k.width as f64) + (hi[2] - lo[2]) / 2.0;
        CameraPose { rotation: Matrix3::identity(), translation: Vector3::new(-c[0], -c[1], z - c[2]) }
    }
}

/// Project a model point to distorted pixel coordinates and depth (None behind the camera).
pub fn project(p: &Vector3<f64>, pose: &CameraPose, k: &Intrinsics, dist: &Distortion) -> Option<(f64, f64, f64)> {
    let c = pose.rotation * p + pose.translation;
    if c[2] <= 1e-9 {
        return None;
    }
    let (xd, yd) = dist.distort_normalized(c[0] / c[2], c[1] / c[2]);
    let (u, v) = k.normalized_to_pixel(xd, yd);
    Some((u, v, c[2]))
}

/// A mesh layer of the overlay.
pub struct Layer<'a> {
    /// Vertices (model mm).
    pub vertices: &'a [Vector3<f64>],
    /// Triangles.
    pub faces: &'a [[usize; 3]],
    /// RGB colour.
    pub color: [u8; 3],
    /// Opacity.
    pub alpha: f64,
}

/// Render the layers over `background` (RGB, the camera's size); each layer has its own z-buffer, so a
/// later layer is seen through earlier ones.
pub fn render_overlay(
    background: &Image<u8>,
    layers: &[Layer],
    pose: &CameraPose,
    k: &Intrinsics,
    dist: &Distortion,
) -> Image<u8> {
    let (w, h) = (background.width, background.height);
    let mut out = if background.channels == 3 {
        background.clone()
    } else {
        let mut o = Image::filled(w, h, 3, 0u8);
        for i in 0..w * h {
            for c in 0..3 {
                o.data[3 * i + c] = background.data[i * background.channels + c.min(background.channels - 1)];
            }
        }
        o
    };
    for layer in layers {
        let mut zbuf = vec![f64::INFINITY; w * h];
        let mut shade = vec![-1.0f64; w * h];
        let proj: Vec<Option<(f64, f64, f64)>> = layer.vertices.iter().map(|p| project(p, pose, k, dist)).collect();
        for f in layer.faces {
            let (Some(a), Some(b), Some(c)) = (proj[f[0]], proj[f[1]], proj[f[2]]) else { continue };
            let n = (pose.rotation * (layer.vertices[f[1]] - layer.vertices[f[0]]))
                .cross(&(pose.rotation * (layer.vertices[f[2]] - layer.vertices[f[0]])));
            let cam = pose.rotation * layer.vertices[f[0]] + pose.translation;
            let lambert = if n.norm() > 0.0 { (n.normalize().dot(&cam.normalize())).abs() } else { 0.0 };
            let area = (b.0 - a.0) * (c.1 - a.1) - (c.0 - a.0) * (b.1 - a.1);
            if area.abs() < 1e-12 {
                continue;
            }
            let x0 = a.0.min(b.0).min(c.0).floor().max(0.0) as i64;
            let x1 = a.0.max(b.0).max(c.0).ceil().min(w as f64 - 1.0) as i64;
            let y0 = a.1.min(b.1).min(c.1).floor().max(0.0) as i64;
            let y1 = a.1.max(b.1).max(c.1).ceil().min(h as f64 - 1.0) as i64;
            for y in y0..=y1 {
                for x in x0..=x1 {
                    let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
                    let w0 = ((b.0 - px) * (c.1 - py) - (c.0 - px) * (b.1 - py)) / area;
                    let w1 = ((c.0 - px) * (a.1 - py) - (a.0 - px) * (c.1 - py)) / area;
                    let w2 = 1.0 - w0 - w1;
                    if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                        continue;
                    }
                    let z = w0 * a.2 + w1 * b.2 + w2 * c.2;
                    let i = y as usize * w + x as usize;
                    if z < zbuf[i] {
                        zbuf[i] = z;
                        shade[i] = lambert;
                    }
                }
            }
        }
        for i in 0..w * h {
            if shade[i] >= 0.0 {
                let s = 0.35 + 0.65 * shade[i];
                for c in 0..3 {
                    let src = layer.color[c] as f64 * s;
                    let dst = out.data[3 * i + c] as f64;
                    out.data[3 * i + c] =
                        (layer.alpha * src + (1.0 - layer.alpha) * dst).round().clamp(0.0, 255.0) as u8;
                }
            }
        }
    }
    out
}
