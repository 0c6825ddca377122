//! Z-buffered rasterisation of textured triangles with exact depth (the scenario's stereo
//! laparoscope renderer): pinhole cameras without distortion, pixel centres at integer
//! coordinates (OpenCV's convention, as `laparo_core::Intrinsics::project`), perspective-correct
//! texture coordinates (1/z interpolation), bilinear texture sampling, Lambert shading with the
//! light at the camera (`0.35 + 0.65 |n · view|`), depth = camera z (mm) of the nearest surface.
use laparo_core::image::Image;
use laparo_core::Intrinsics;
use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

/// A camera view: `X_cam = R X_world + t` (mm; x right, y down, z forward) and its intrinsics.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct View {
    /// Intrinsics (px).
    pub k: Intrinsics,
    /// World → camera rotation.
    pub r: Matrix3<f64>,
    /// World → camera translation (mm).
    pub t: Vector3<f64>,
}

impl View {
    /// Camera coordinates (mm) of a world point.
    pub fn to_camera(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.r * p + self.t
    }
    /// Pixel (u, v) and depth z (mm) of a world point; None behind the camera.
    pub fn project(&self, p: &Vector3<f64>) -> Option<(f64, f64, f64)> {
        let c = self.to_camera(p);
        if c[2] <= 1e-6 {
            return None;
        }
        Some((self.k.fx * c[0] / c[2] + self.k.cx, self.k.fy * c[1] / c[2] + self.k.cy, c[2]))
    }
    /// World point of pixel (u, v) at depth z (mm).
    pub fn backproject(&self, u: f64, v: f64, z: f64) -> Vector3<f64> {
        let c = Vector3::new((u - self.k.cx) * z / self.k.fx, (v - self.k.cy) * z / self.k.fy, z);
        self.r.transpose() * (c - self.t)
    }
}

/// A textured triangle mesh to render.
#[derive(Clone, Copy)]
pub struct Textured<'a> {
    /// Vertices (world mm).
    pub vertices: &'a [Vector3<f64>],
    /// Triangles.
    pub faces: &'a [[usize; 3]],
    /// Texture coordinates of every vertex (texture px).
    pub uv: &'a [[f64; 2]],
    /// Colour multiplier per face (RGB, 1 = texture as is).
    pub tint: &'a [[f64; 3]],
    /// Label written for the pixels of this mesh (0 is "nothing").
    pub label: u8,
}

/// A rendered view.
#[derive(Clone, Debug)]
pub struct Rendered {
    /// RGB image.
    pub rgb: Image<u8>,
    /// Depth (camera z, mm), NaN where nothing was drawn.
    pub depth_mm: Image<f64>,
    /// Label of the nearest mesh, 0 where nothing was drawn.
    pub label: Image<u8>,
}

struct Tri {
    p: [(f64, f64, f64); 3],
    uv: [[f64; 2]; 3],
    colour: [f64; 3],
    normal: Vector3<f64>,
    label: u8,
}

/// Render `meshes` seen by `view` with `texture`.
pub fn render(view: &View, meshes: &[Textured], texture: &Image<u8>) -> Rendered {
    let (w, h) = (view.k.width, view.k.height);
    let mut tris = Vec::new();
    for m in meshes {
        let proj: Vec<Option<(f64, f64, f64)>> = m.vertices.iter().map(|p| view.project(p)).collect();
        for (fi, f) in m.faces.iter().enumerate() {
            let (Some(a), Some(b), Some(c)) = (proj[f[0]], proj[f[1]], proj[f[2]]) else { continue };
            let ca = view.to_camera(&m.vertices[f[0]]);
            let n = (view.to_camera(&m.vertices[f[1]]) - ca).cross(&(view.to_camera(&m.vertices[f[2]]) - ca));
            let n = if n.norm() > 0.0 { n.normalize() } else { n };
            tris.push(Tri {
                p: [a, b, c],
                uv: [m.uv[f[0]], m.uv[f[1]], m.uv[f[2]]],
                colour: m.tint[fi],
                normal: n,
                label: m.label,
            });
        }
    }
    let mut rgb = Image::filled(w, h, 3, 0u8);
    let mut depth = Image::filled(w, h, 1, f64::NAN);
    let mut label = Image::filled(w, h, 1, 0u8);
    const BAND: usize = 32;
    rgb.data
        .par_chunks_mut(3 * w * BAND)
        .zip(depth.data.par_chunks_mut(w * BAND))
        .zip(label.data.par_chunks_mut(w * BAND))
        .enumerate()
        .for_each(|(band, ((rgb, dep), lab))| {
            let y_lo = band * BAND;
            let y_hi = (y_lo + BAND).min(h);
            for t in &tris {
                let [a, b, c] = t.p;
                let ymin = a.1.min(b.1).min(c.1).ceil().max(y_lo as f64) as i64;
                let ymax = a.1.max(b.1).max(c.1).floor().min(y_hi as f64 - 1.0) as i64;
                if ymin > ymax {
                    continue;
                }
                let xmin = a.0.min(b.0).min(c.0).ceil().max(0.0) as i64;
                let xmax = a.0.max(b.0).max(c.0).floor().min(w as f64 - 1.0) as i64;
                if xmin > xmax {
                    continue;
                }
                let area = (b.0 - a.0) * (c.1 - a.1) - (c.0 - a.0) * (b.1 - a.1);
                if area.abs() < 1e-12 {
                    continue;
                }
                for y in ymin..=ymax {
                    for x in xmin..=xmax {
                        let (px, py) = (x as f64, y as f64);
                        let l0 = ((b.0 - px) * (c.1 - py) - (c.0 - px) * (b.1 - py)) / area;
                        let l1 = ((c.0 - px) * (a.1 - py) - (a.0 - px) * (c.1 - py)) / area;
                        let l2 = 1.0 - l0 - l1;
                        if l0 < 0.0 || l1 < 0.0 || l2 < 0.0 {
                            continue;
                        }
                        let iz = l0 / a.2 + l1 / b.2 + l2 / c.2;
                        let z = 1.0 / iz;
                        let i = (y as usize - y_lo) * w + x as usize;
                        let cur = dep[i];
                        if !(cur.is_nan() || z < cur) {
                            continue;
                        }
                        dep[i] = z;
                        lab[i] = t.label;
                        let u = (l0 * t.uv[0][0] / a.2 + l1 * t.uv[1][0] / b.2 + l2 * t.uv[2][0] / c.2) * z;
                        let v = (l0 * t.uv[0][1] / a.2 + l1 * t.uv[1][1] / b.2 + l2 * t.uv[2][1] / c.2) * z;
                        let u = u.clamp(0.0, texture.width as f64 - 1.0);
                        let v = v.clamp(0.0, texture.height as f64 - 1.0);
                        let ray = Vector3::new((px - view.k.cx) / view.k.fx, (py - view.k.cy) / view.k.fy, 1.0);
                        let shade = 0.35 + 0.65 * t.normal.dot(&ray.normalize()).abs();
                        for ch in 0..3 {
                            let s = shade * texture.sample_bilinear(u, v, ch.min(texture.channels - 1)).unwrap_or(0.0);
                            rgb[3 * i + ch] = (s * t.colour[ch]).round().clamp(0.0, 255.0) as u8;
                        }
                    }
                }
            }
        });
    Rendered { rgb, depth_mm: depth, label }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_fronto_parallel_square_has_exact_depth_and_texture() {
        // square at z = 100 mm covering the image; texture = a horizontal ramp mapped 1:1 in u
        let k = Intrinsics::new(100.0, 100.0, 31.5, 23.5, 64, 48).unwrap();
        let view = View { k, r: Matrix3::identity(), t: Vector3::zeros() };
        let z = 100.0;
        let corners = [(-10.0, -10.0), (80.0, -10.0), (80.0, 60.0), (-10.0, 60.0)];
        let verts: Vec<Vector3<f64>> = corners.iter().map(|&(u, v)| view.backproject(u, v, z)).collect();
        let uv: Vec<[f64; 2]> = corners.iter().map(|&(u, v)| [u + 10.0, v + 10.0]).collect();
        let faces = [[0, 1, 2], [0, 2, 3]];
        let tint = [[1.0; 3]; 2];
        let tex_data: Vec<u8> = (0..100 * 80).flat_map(|i| [(i % 100) as u8 * 2, 0, 0]).collect();
        let tex = Image::from_vec(100, 80, 3, tex_data).unwrap();
        let r = render(&view, &[Textured { vertices: &verts, faces: &faces, uv: &uv, tint: &tint, label: 1 }], &tex);
        for y in 0..48 {
            for x in 0..64 {
                assert!((r.depth_mm.get(x, y, 0) - z).abs() < 1e-9);
                assert_eq!(r.label.get(x, y, 0), 1);
                // fronto-parallel, light at the camera: shading = 0.35 + 0.65 cos(angle to the ray)
                let ray = Vector3::new((x as f64 - 31.5) / 100.0, (y as f64 - 23.5) / 100.0, 1.0).normalize();
                let expect = 2.0 * (x as f64 + 10.0) * (0.35 + 0.65 * ray[2]);
                assert!((r.rgb.get(x, y, 0) as f64 - expect).abs() <= 0.51, "{x},{y}");
            }
        }
    }
}
