//! Particle frames: 2D particle images (PNG via laparo_core) and 3D point clouds (PLY).
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

/// ASCII PLY point cloud with per-vertex velocity and J.
pub fn ply_bytes(x: &[Vector<3>], v: &[Vector<3>], j: &[f64]) -> Vec<u8> {
    let mut s = format!(
        "ply\nformat ascii 1.0\ncomment laparo mpm particle frame\nelement vertex {}\nproperty double x\nproperty double y\nproperty double z\nproperty double vx\nproperty double vy\nproperty double vz\nproperty double J\nend_header\n",
        x.len()
    );
    for ((p, vel), jj) in x.iter().zip(v).zip(j) {
        s += &format!("{} {} {} {} {} {} {}\n", p[0], p[1], p[2], vel[0], vel[1], vel[2], jj);
    }
    s.into_bytes()
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
        chart.configure_mesh().x_desc("iteration").y_desc("loss").draw()?;
        chart.draw_series(LineSeries::new(losses.iter().enumerate().map(|(i, l)| (i as f64, *l)), &BLUE))?;
        chart.draw_series(losses.iter().enumerate().map(|(i, l)| Circle::new((i as f64, *l), 3, BLUE.filled())))?;
        Ok(())
    })
}
