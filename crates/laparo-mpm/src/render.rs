//! Particle frames: 2D particle images and orthographic 3D views (PNG via laparo_core), 3D point
//! clouds (binary PLY), and the loss curve of an optimisation.
use crate::linalg::Vector;
use laparo_core::colormap::Colormap;
use laparo_core::image::Image;

/// Render 2D particles over the square [0, extent]² (y up) into a `size`×`size` RGB image, each
/// particle a `dot`-pixel square coloured by `values` mapped from [lo, hi] with Turbo; `marks` are
/// drawn as black crosses (e.g. landmark targets).
#[allow(clippy::too_many_arguments)]
pub fn render_particles_2d(
    x: &[Vector<2>],
    values: &[f64],
    lo: f64,
    hi: f64,
    extent: f64,
    size: usize,
    dot: usize,
    marks: &[Vector<2>],
) -> Image<u8> {
    let mut img = Image::filled(size, size, 3, 255u8);
    let to_px = |p: &Vector<2>| {
        let u = p[0] / extent * size as f64;
        let v = (1.0 - p[1] / extent) * size as f64;
        (u as i64, v as i64)
    };
    let mut put = |u: i64, v: i64, c: [u8; 3]| {
        if u >= 0 && v >= 0 && (u as usize) < size && (v as usize) < size {
            let o = 3 * (v as usize * size + u as usize);
            img.data[o..o + 3].copy_from_slice(&c);
        }
    };
    let h = dot as i64 / 2;
    for (p, val) in x.iter().zip(values) {
        let t = if hi > lo { ((val - lo) / (hi - lo)).clamp(0.0, 1.0) } else { 0.5 };
        let c = Colormap::Turbo.rgb(t);
        let (u, v) = to_px(p);
        for du in -h..=(dot as i64 - 1 - h) {
            for dv in -h..=(dot as i64 - 1 - h) {
                put(u + du, v + dv, c);
            }
        }
    }
    for m in marks {
        let (u, v) = to_px(m);
        for k in -4..=4 {
            put(u + k, v, [0, 0, 0]);
            put(u, v + k, [0, 0, 0]);
        }
    }
    img
}

/// Binary (little-endian) PLY point cloud of particles: per vertex `double x y z vx vy vz J`
/// (positions and velocities in the scene's length and time units, J = det F).
pub fn ply_bytes(x: &[Vector<3>], v: &[Vector<3>], j: &[f64]) -> Vec<u8> {
    let n = x.len().min(v.len()).min(j.len());
    let header = format!(
        "ply\nformat binary_little_endian 1.0\ncomment laparo mpm particle frame\nelement vertex {n}\nproperty double x\nproperty double y\nproperty double z\nproperty double vx\nproperty double vy\nproperty double vz\nproperty double J\nend_header\n"
    );
    let mut out = Vec::with_capacity(header.len() + n * 56);
    out.extend_from_slice(header.as_bytes());
    for ((p, vel), jj) in x.iter().zip(v).zip(j) {
        for c in [p[0], p[1], p[2], vel[0], vel[1], vel[2], *jj] {
            out.extend_from_slice(&c.to_le_bytes());
        }
    }
    out
}

/// An orthographic view of 3D particles: azimuth `azimuth_deg` about +z, elevation
/// `elevation_deg` above the x–y plane, +z up in the image.
#[derive(Clone, Copy, Debug)]
pub struct View3d {
    /// Rotation of the viewing direction about +z (degrees; 0 looks along +y, x to the right).
    pub azimuth_deg: f64,
    /// Elevation of the viewer above the x–y plane (degrees).
    pub elevation_deg: f64,
}

impl Default for View3d {
    fn default() -> Self {
        View3d { azimuth_deg: -35.0, elevation_deg: 25.0 }
    }
}

impl View3d {
    /// Screen right, screen up and towards-the-viewer unit vectors.
    fn axes(&self) -> (Vector<3>, Vector<3>, Vector<3>) {
        let (t, f) = (self.azimuth_deg.to_radians(), self.elevation_deg.to_radians());
        let r = Vector::<3>::new(t.cos(), t.sin(), 0.0);
        let u = Vector::<3>::new(-t.sin() * f.sin(), t.cos() * f.sin(), f.cos());
        (r, u, r.cross(&u))
    }
}

/// Render 3D particles in an orthographic `view` into a `size`×`size` RGB image (white
/// background), fitted to the bounding box of `x` and `frame` (e.g. the initial positions, so that
/// successive frames share the fit): each particle a disc of `dot_size` length units
/// (at least 2 px), coloured by `values` mapped from [lo, hi] with Turbo, nearer particles drawn
/// over farther ones. `ghost` particles (e.g. the initial state) are drawn first in light grey.
#[allow(clippy::too_many_arguments)]
pub fn render_particles_3d(
    x: &[Vector<3>],
    values: &[f64],
    lo: f64,
    hi: f64,
    ghost: &[Vector<3>],
    view: &View3d,
    size: usize,
    dot_size: f64,
) -> Image<u8> {
    let (r, u, w) = view.axes();
    let (mut umin, mut umax, mut vmin, mut vmax) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
    for p in x.iter().chain(ghost) {
        let (a, b) = (p.dot(&r), p.dot(&u));
        if a.is_finite() && b.is_finite() {
            umin = umin.min(a);
            umax = umax.max(a);
            vmin = vmin.min(b);
            vmax = vmax.max(b);
        }
    }
    let mut img = Image::filled(size, size, 3, 255u8);
    if !(umin <= umax) {
        return img;
    }
    let span = (umax - umin).max(vmax - vmin).max(dot_size) * 1.1;
    let scale = size as f64 / span;
    let (uc, vc) = (0.5 * (umin + umax), 0.5 * (vmin + vmax));
    let rad = (0.5 * dot_size * scale).max(1.0);
    let disc = |img: &mut Image<u8>, p: &Vector<3>, c: [u8; 3]| {
        let px = (p.dot(&r) - uc) * scale + 0.5 * size as f64;
        let py = 0.5 * size as f64 - (p.dot(&u) - vc) * scale;
        if !(px.is_finite() && py.is_finite()) {
            return;
        }
        let (x0, x1) = ((px - rad).floor().max(0.0) as i64, (px + rad).ceil().min(size as f64 - 1.0) as i64);
        let (y0, y1) = ((py - rad).floor().max(0.0) as i64, (py + rad).ceil().min(size as f64 - 1.0) as i64);
        for yy in y0..=y1 {
            for xx in x0..=x1 {
                let (dx, dy) = (xx as f64 + 0.5 - px, yy as f64 + 0.5 - py);
                if dx * dx + dy * dy <= rad * rad {
                    let o = 3 * (yy as usize * size + xx as usize);
                    img.data[o..o + 3].copy_from_slice(&c);
                }
            }
        }
    };
    let mut order: Vec<usize> = (0..ghost.len()).collect();
    order.sort_by(|&a, &b| ghost[a].dot(&w).total_cmp(&ghost[b].dot(&w)));
    for &i in &order {
        disc(&mut img, &ghost[i], [215, 215, 215]);
    }
    let mut order: Vec<usize> = (0..x.len().min(values.len())).collect();
    order.sort_by(|&a, &b| x[a].dot(&w).total_cmp(&x[b].dot(&w)));
    for &i in &order {
        let t = if hi > lo { ((values[i] - lo) / (hi - lo)).clamp(0.0, 1.0) } else { 0.5 };
        disc(&mut img, &x[i], Colormap::Turbo.rgb(t));
    }
    img
}

/// Line chart of an optimisation's loss per iteration (log-scale y), saved as PNG.
pub fn plot_loss_curve(
    path: &std::path::Path,
    losses: &[f64],
    title: &str,
) -> Result<(), laparo_core::error::CoreError> {
    use plotters::prelude::*;
    let lo = losses.iter().cloned().fold(f64::INFINITY, f64::min).max(1e-300);
    let hi = losses.iter().cloned().fold(0.0, f64::max).max(lo * 1.0001);
    let n = losses.len().max(2);
    laparo_core::plot::draw_png(path, 640, 400, |root| {
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 20))
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(70)
            .build_cartesian_2d(0f64..(n - 1) as f64, (lo * 0.9..hi * 1.1).log_scale())?;
        // three significant digits (plotters' own log-axis labels print binary round-off such as
        // 0.30000000000000004), no minor grid lines
        let label = |v: &f64| {
            if *v >= 0.01 && *v < 1e4 {
                let s = format!("{:.3}", v);
                s.trim_end_matches('0').trim_end_matches('.').to_string()
            } else {
                format!("{v:.1e}")
            }
        };
        chart
            .configure_mesh()
            .x_desc("iteration")
            .y_desc("loss")
            .y_labels(8)
            .y_label_formatter(&label)
            .light_line_style(TRANSPARENT)
            .draw()?;
        chart.draw_series(LineSeries::new(losses.iter().enumerate().map(|(i, l)| (i as f64, *l)), &BLUE))?;
        chart.draw_series(losses.iter().enumerate().map(|(i, l)| Circle::new((i as f64, *l), 3, BLUE.filled())))?;
        Ok(())
    })
}
