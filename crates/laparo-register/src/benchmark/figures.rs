//! Benchmark pictures: TRE colour maps on the organ surface (Fig. 5.7) with a colour bar, the error against
//! the distance to the nearest incision landmark (Fig. 5.8), and a VTK file with per-node error for ParaView.
use super::rods::RODS_MPM_NAME;
use super::table::Cell;
use super::tre::DISTANCE_BIN_EDGES_MM;
use crate::error::{RegisterError, Result};
use laparo_core::colormap::Colormap;
use laparo_core::image::Image;
use nalgebra::Vector3;
use std::path::Path;

/// An orthographic view of a surface.
#[derive(Clone, Copy, Debug)]
pub struct SurfaceView {
    /// Viewing direction, from the camera towards the scene.
    pub direction: Vector3<f64>,
    /// The image's up direction.
    pub up: Vector3<f64>,
    /// Image side (px, square).
    pub size_px: usize,
}

/// Orthographic, z-buffered rendering of the triangles `faces` of `vertices` seen as `view` says, coloured
/// by the per-vertex `values` mapped from [lo, hi] with `cmap`, Lambert-shaded, on a white background.
pub fn render_scalar_surface(
    vertices: &[Vector3<f64>],
    faces: &[[usize; 3]],
    values: &[f64],
    (lo, hi, cmap): (f64, f64, Colormap),
    view: &SurfaceView,
) -> Image<u8> {
    let size = view.size_px;
    let f = view.direction.normalize();
    let r = f.cross(&view.up).normalize();
    let u = r.cross(&f);
    let proj: Vec<Vector3<f64>> = vertices.iter().map(|p| Vector3::new(p.dot(&r), p.dot(&u), p.dot(&f))).collect();
    let mut img = Image::filled(size, size, 3, 255u8);
    if proj.is_empty() || size < 4 {
        return img;
    }
    // frame the drawn faces only (a close-up draws a subset)
    let used = faces.iter().flatten().map(|&i| proj[i]);
    let first = faces.first().map(|f| proj[f[0]]).unwrap_or(proj[0]);
    let lo_xy = used.clone().fold(first, |a, b| a.inf(&b));
    let hi_xy = used.fold(first, |a, b| a.sup(&b));
    let ext = (hi_xy[0] - lo_xy[0]).max(hi_xy[1] - lo_xy[1]).max(1e-12);
    let scale = 0.92 * size as f64 / ext;
    let cx = 0.5 * (lo_xy[0] + hi_xy[0]);
    let cy = 0.5 * (lo_xy[1] + hi_xy[1]);
    let to_px = |p: &Vector3<f64>| {
        Vector3::new((p[0] - cx) * scale + 0.5 * size as f64, 0.5 * size as f64 - (p[1] - cy) * scale, p[2])
    };
    let px: Vec<Vector3<f64>> = proj.iter().map(to_px).collect();
    let mut zbuf = vec![f64::INFINITY; size * size];
    let span = (hi - lo).max(1e-12);
    for tri in faces {
        let [a, b, c] = tri.map(|i| px[i]);
        let n = (vertices[tri[1]] - vertices[tri[0]]).cross(&(vertices[tri[2]] - vertices[tri[0]]));
        let shade = if n.norm() > 0.0 { 0.35 + 0.65 * (n.normalize().dot(&f)).abs() } else { 0.35 };
        let area = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
        if area.abs() < 1e-12 {
            continue;
        }
        let x0 = a[0].min(b[0]).min(c[0]).floor().max(0.0) as usize;
        let x1 = (a[0].max(b[0]).max(c[0]).ceil() as usize).min(size - 1);
        let y0 = a[1].min(b[1]).min(c[1]).floor().max(0.0) as usize;
        let y1 = (a[1].max(b[1]).max(c[1]).ceil() as usize).min(size - 1);
        for y in y0..=y1 {
            for x in x0..=x1 {
                let (qx, qy) = (x as f64 + 0.5, y as f64 + 0.5);
                let w0 = ((b[0] - qx) * (c[1] - qy) - (b[1] - qy) * (c[0] - qx)) / area;
                let w1 = ((c[0] - qx) * (a[1] - qy) - (c[1] - qy) * (a[0] - qx)) / area;
                let w2 = 1.0 - w0 - w1;
                if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                    continue;
                }
                let z = w0 * a[2] + w1 * b[2] + w2 * c[2];
                let k = y * size + x;
                if z >= zbuf[k] {
                    continue;
                }
                zbuf[k] = z;
                let v = w0 * values[tri[0]] + w1 * values[tri[1]] + w2 * values[tri[2]];
                let rgb = cmap.rgb(((v - lo) / span).clamp(0.0, 1.0));
                let p = img.pixel_mut(x, y);
                for ch in 0..3 {
                    p[ch] = (rgb[ch] as f64 * shade).round() as u8;
                }
            }
        }
    }
    img
}

/// An error map: the whole surface seen along `view` and, beside it, a close-up of the faces within
/// `focus.1` mm of `focus.0` (the incision), coloured by `values_mm` on [0, `hi_mm`] (Turbo), with a colour
/// bar labelled `label` and `title` drawn above. Written to `path` (PNG, atomically).
#[allow(clippy::too_many_arguments)]
pub fn write_tre_map(
    path: &Path,
    vertices: &[Vector3<f64>],
    faces: &[[usize; 3]],
    values_mm: &[f64],
    hi_mm: f64,
    view: &SurfaceView,
    focus: (Vector3<f64>, f64),
    (title, label): (&str, &str),
) -> Result<()> {
    let size = view.size_px;
    let scale = (0.0, hi_mm, Colormap::Turbo);
    let a = render_scalar_surface(vertices, faces, values_mm, scale, view);
    let near: Vec<[usize; 3]> = faces
        .iter()
        .filter(|f| ((vertices[f[0]] + vertices[f[1]] + vertices[f[2]]) / 3.0 - focus.0).norm() < focus.1)
        .copied()
        .collect();
    let b = render_scalar_surface(vertices, if near.is_empty() { faces } else { &near }, values_mm, scale, view);
    let mut both = Image::filled(2 * size, size + 30, 3, 255u8);
    for y in 0..size {
        for x in 0..size {
            both.pixel_mut(x, y + 30).copy_from_slice(a.pixel(x, y));
            both.pixel_mut(x + size, y + 30).copy_from_slice(b.pixel(x, y));
        }
    }
    let titled = laparo_core::plot::render_rgb(both.width as u32, both.height as u32, |area| {
        use plotters::prelude::*;
        area.draw(
            &plotters::element::BitMapElement::with_owned_buffer(
                (0, 0),
                (both.width as u32, both.height as u32),
                both.data.clone(),
            )
            .ok_or("bitmap")?,
        )
        .map_err(|e| e.to_string())?;
        area.draw(&Text::new(title.to_string(), (10, 6), ("DejaVu Sans", 18).into_font()))
            .map_err(|e| e.to_string())?;
        Ok(())
    })
    .map_err(|e| RegisterError::bad(path.display().to_string(), e))?;
    let out = laparo_core::plot::with_colorbar(&titled, 0.0, hi_mm, Colormap::Turbo, label);
    Ok(laparo_core::io::write_png(path, &out)?)
}

/// The crack seen face-on, unrolled along its blade ([`blade_coordinates_mm`](super::build::blade_coordinates_mm):
/// mm across the blade, mm below its first mouth sample): side A's crack faces, each filled with the mean of `gap_by_node_mm` (by
/// uncut-mesh node, [`crack_gap_by_node_mm`](super::build::crack_gap_by_node_mm); absent = 0, the crack front)
/// over its three nodes with a colour bar (or plain, at rest, when `None`), the crack-front nodes as black dots
/// and the blade's outline in red. An uncut slot or bridge inside the outline shows as a hole or a chain of dots. Written to `path`
/// (PNG, atomically).
pub fn write_crack_opening(
    path: &Path,
    scn: &laparo_fem::mesh::Scenario,
    gap_by_node_mm: Option<&std::collections::HashMap<usize, f64>>,
    title: &str,
) -> Result<()> {
    use plotters::prelude::*;
    let b = &scn.blade;
    let x = &scn.cut.mesh.vertices;
    let chart = super::build::blade_chart_mm(b);
    let flat = |p: &Vector3<f64>| super::build::blade_coordinates_mm(b, &chart, p);
    let gap = |k: usize| gap_by_node_mm.and_then(|g| g.get(&scn.cut.original_node[k])).copied().unwrap_or(0.0);
    let faces: Vec<([(f64, f64); 3], f64)> = scn.cut.crack_faces[0]
        .iter()
        .map(|f| (f.map(|k| flat(&x[k])), f.iter().map(|&k| gap(k)).sum::<f64>() / 3.0))
        .collect();
    if faces.is_empty() {
        return Err(RegisterError::bad(path.display().to_string(), "the scenario has no crack faces to draw"));
    }
    let outline: Vec<(f64, f64)> = chart
        .iter()
        .copied()
        .chain(chart.iter().zip(&b.depths).rev().map(|(&(s, h), &d)| (s, h + d)))
        .chain(chart.first().copied())
        .collect();
    let front: Vec<(f64, f64)> = scn.cut.front_nodes.iter().map(|&k| flat(&x[k])).collect();
    let pts = || faces.iter().flat_map(|(p, _)| p.iter().copied()).chain(outline.iter().copied());
    let (x0, x1) = pts().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, c), p| (a.min(p.0), c.max(p.0)));
    let (y0, y1) = pts().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, c), p| (a.min(p.1), c.max(p.1)));
    let hi = faces.iter().map(|f| f.1).fold(0.0, f64::max).max(1e-9);
    let cmap = Colormap::Viridis;
    let w = 900u32;
    let h = ((w as f64 - 60.0) * (y1 - y0 + 10.0) / (x1 - x0 + 10.0) + 80.0).clamp(300.0, 1400.0) as u32;
    let img = laparo_core::plot::render_rgb(w, h, |root| {
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 16))
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(50)
            .build_cartesian_2d(x0 - 5.0..x1 + 5.0, y1 + 5.0..y0 - 5.0)?;
        chart.configure_mesh().x_desc("across the blade (mm)").y_desc("below the mouth's first point (mm)").draw()?;
        chart.draw_series(faces.iter().map(|(p, v)| {
            let [r, g, bl] = if gap_by_node_mm.is_some() { cmap.rgb(v / hi) } else { [176, 196, 222] };
            Polygon::new(p.to_vec(), RGBColor(r, g, bl).filled())
        }))?;
        chart.draw_series(
            faces.iter().map(|(p, _)| PathElement::new(vec![p[0], p[1], p[2], p[0]], RGBColor(120, 120, 120))),
        )?;
        chart.draw_series(std::iter::once(PathElement::new(outline.clone(), RED.stroke_width(2))))?;
        chart.draw_series(front.iter().map(|&p| Circle::new(p, 3, BLACK.filled())))?;
        Ok(())
    })
    .map_err(|e| RegisterError::bad(path.display().to_string(), e))?;
    let out = match gap_by_node_mm {
        Some(_) => laparo_core::plot::with_colorbar(&img, 0.0, hi, cmap, "gap between the lips (mm)"),
        None => img,
    };
    Ok(laparo_core::io::write_png(path, &out)?)
}

/// Fig. 5.8: mean TRE per distance bin, one line per method, for the cells of one scenario and column.
pub fn write_distance_plot(path: &Path, cells: &[&Cell], title: &str) -> Result<()> {
    use plotters::prelude::*;
    let nb = DISTANCE_BIN_EDGES_MM.len() - 1;
    let labels: Vec<String> = (0..nb)
        .map(|k| {
            let (a, b) = (DISTANCE_BIN_EDGES_MM[k], DISTANCE_BIN_EDGES_MM[k + 1]);
            if b.is_finite() {
                format!("{a:.0}–{b:.0}")
            } else {
                format!("> {a:.0}")
            }
        })
        .collect();
    // v2 cells are drawn by distance to the lip polylines at the common points, else by node bins
    let v2 = cells.iter().any(|c| c.points.is_some());
    let means = |c: &Cell| -> Vec<f64> {
        match &c.points {
            Some(p) => p.lip_bin_means_mm.clone(),
            None => c.bin_means_mm.clone(),
        }
    };
    let ymax = cells.iter().flat_map(|c| means(c)).filter(|v| v.is_finite()).fold(0.0f64, f64::max).max(1e-3) * 1.15;
    let colors = [
        RGBColor(31, 119, 180),
        RGBColor(255, 127, 14),
        RGBColor(44, 160, 44),
        RGBColor(148, 103, 189),
        RGBColor(214, 39, 40),
        RGBColor(90, 90, 90),
    ];
    // the legend gets its own strip right of the axes, so it never hides a line or a point
    // (≈ 8 px a character at 14 px DejaVu Sans, so a long oracle name widens the strip, not the overlap)
    let longest = cells.iter().map(|c| c.method.chars().count()).max().unwrap_or(0) as u32;
    let legend_px = (40 + 8 * longest).max(170);
    laparo_core::plot::draw_png(path, 760 + legend_px, 460, |area| {
        let (plot, side) = area.split_horizontally(760);
        let mut chart = ChartBuilder::on(&plot)
            .caption(title, ("DejaVu Sans", 18))
            .margin(12)
            .x_label_area_size(44)
            .y_label_area_size(56)
            .build_cartesian_2d(-0.5f64..(nb as f64 - 0.5), 0.0..ymax)
            .map_err(|e| e.to_string())?;
        let lab = labels.clone();
        chart
            .configure_mesh()
            .x_labels(nb)
            .x_label_formatter(&move |x| {
                let k = x.round();
                if (x - k).abs() < 1e-6 && k >= 0.0 && (k as usize) < lab.len() {
                    lab[k as usize].clone()
                } else {
                    String::new()
                }
            })
            .x_desc(if v2 {
                "distance to the source lip polylines [mm] (common points; dashed: floors and ROI variants)"
            } else {
                "distance to the nearest incision landmark [mm]"
            })
            .y_desc("mean TRE [mm]")
            .draw()
            .map_err(|e| e.to_string())?;
        // one colour per method whatever the figure holds (the six Table 5.1 rows in order), others cycle;
        // a baseline with RODS-MPM's region of interest ("… (ROI)") takes its base's colour, dashed
        let known = ["none (rest)", "ARAP", "DRBC", "François et al.", "LDDMM", RODS_MPM_NAME];
        for (i, c) in cells.iter().enumerate() {
            // a floor row takes the colour of the method it bounds (the mesh methods' P1 floor: grey), dashed
            let floor_of =
                c.method.strip_prefix("floor: ").map(|f| if f.starts_with("RODS") { RODS_MPM_NAME } else { "" });
            let base = c.method.strip_suffix(" (ROI)").or(floor_of);
            let k = known.iter().position(|n| base.unwrap_or(&c.method) == *n);
            let col =
                if floor_of == Some("") { RGBColor(150, 150, 150) } else { colors[k.unwrap_or(i) % colors.len()] };
            let pts: Vec<(f64, f64)> =
                means(c).iter().enumerate().filter(|(_, v)| v.is_finite()).map(|(k, &v)| (k as f64, v)).collect();
            let y = 56 + 22 * i as i32;
            // solid line and filled markers, or dashed line and hollow markers for a "(ROI)" variant
            let marker = if base.is_some() { col.stroke_width(2) } else { col.filled() };
            if base.is_some() {
                chart
                    .draw_series(DashedLineSeries::new(pts.clone(), 7, 4, col.stroke_width(2)))
                    .map_err(|e| e.to_string())?;
                side.draw(&plotters::element::DashedPathElement::new(vec![(4, y), (26, y)], 5, 3, col.stroke_width(2)))
                    .map_err(|e| e.to_string())?;
            } else {
                chart.draw_series(LineSeries::new(pts.clone(), col.stroke_width(2))).map_err(|e| e.to_string())?;
                side.draw(&PathElement::new(vec![(4, y), (26, y)], col.stroke_width(3))).map_err(|e| e.to_string())?;
            }
            chart.draw_series(pts.iter().map(|&p| Circle::new(p, 4, marker))).map_err(|e| e.to_string())?;
            side.draw(&Circle::new((15, y), 4, marker)).map_err(|e| e.to_string())?;
            side.draw(&Text::new(c.method.clone(), (32, y - 8), ("DejaVu Sans", 14).into_font()))
                .map_err(|e| e.to_string())?;
        }
        Ok(())
    })
    .map_err(|e| RegisterError::bad(path.display().to_string(), e.to_string()))
}

/// One setting of a Fig. 5.9 sweep: the value and the TRE it gave (mm).
#[derive(Clone, Debug, PartialEq)]
pub struct SweepPoint {
    /// The setting's value (in the panel's unit).
    pub value: f64,
    /// Mean TRE over all volume nodes (mm).
    pub mean_mm: f64,
    /// Mean TRE within 5 mm of the nearest incision landmark (the first Fig. 5.8 bin, mm).
    pub near_mm: f64,
}

/// One panel of Fig. 5.9: RODS-MPM's TRE as one setting varies, the others at their defaults.
#[derive(Clone, Debug, PartialEq)]
pub struct SweepPanel {
    /// Axis label with its unit (e.g. `particle spacing [mm]`).
    pub parameter: String,
    /// The default value (marked on the axis).
    pub default_value: f64,
    /// Plot the values on a log axis (the E × 0.25…10 sweep).
    pub log_x: bool,
    /// The settings, the default among them.
    pub points: Vec<SweepPoint>,
}

/// Fig. 5.9: one panel per swept setting, RODS-MPM's all-node and near-incision (0–5 mm) mean TRE against the
/// setting, the default circled, and `reference` (a baseline's name, all-node and near TRE) as dashed lines.
pub fn write_sweep_plot(
    path: &Path,
    panels: &[SweepPanel],
    reference: Option<(&str, f64, f64)>,
    title: &str,
) -> Result<()> {
    use plotters::prelude::*;
    let bad = |m: String| RegisterError::bad(path.display().to_string(), m);
    if panels.is_empty() || panels.iter().any(|p| p.points.is_empty()) {
        return Err(bad("no sweep results to plot".into()));
    }
    if panels.iter().any(|p| p.log_x && p.points.iter().any(|q| q.value <= 0.0)) {
        return Err(bad("a log-axis sweep holds a value ≤ 0".into()));
    }
    let finite = |v: f64| v.is_finite();
    let ymax = panels
        .iter()
        .flat_map(|p| p.points.iter().flat_map(|q| [q.mean_mm, q.near_mm]))
        .chain(reference.iter().flat_map(|r| [r.1, r.2]))
        .filter(|v| finite(*v))
        .fold(0.0f64, f64::max)
        .max(1e-3)
        * 1.15;
    let (mean_col, near_col) = (RGBColor(31, 119, 180), RGBColor(214, 39, 40));
    let cols = panels.len().min(3);
    let rows = panels.len().div_ceil(cols);
    // the legend: (colour, dashed, label); it goes in the grid's free cell, or in a band below the panels
    let mut legend: Vec<(RGBColor, bool, String)> =
        vec![(mean_col, false, "RODS-MPM, all nodes".into()), (near_col, false, "RODS-MPM, 0–5 mm".into())];
    if let Some((name, mean, near)) = reference {
        for (col, v, what) in [(mean_col, mean, "all nodes"), (near_col, near, "0–5 mm")] {
            if finite(v) {
                legend.push((col, true, format!("{name}, {what}")));
            }
        }
    }
    let free_cell = rows * cols > panels.len();
    let band = if free_cell { 0 } else { 24 * legend.len() as u32 + 16 };
    laparo_core::plot::draw_png(path, 420 * cols as u32, 330 * rows as u32 + 40 + band, |root| {
        let root = root.titled(title, ("DejaVu Sans", 20)).map_err(|e| e.to_string())?;
        let (grid, below) = root.split_vertically(330 * rows as u32);
        let areas = grid.split_evenly((rows, cols));
        let key = if free_cell { &areas[areas.len() - 1] } else { &below };
        for (i, (col, dashed, label)) in legend.iter().enumerate() {
            let (x, y) = (if free_cell { 60 } else { 20 }, if free_cell { 60 } else { 8 } + 24 * i as i32);
            let style = col.stroke_width(if *dashed { 1 } else { 2 });
            if *dashed {
                key.draw(&plotters::element::DashedPathElement::new(vec![(x, y), (x + 28, y)], 6, 4, style))
                    .map_err(|e| e.to_string())?;
            } else {
                key.draw(&PathElement::new(vec![(x, y), (x + 28, y)], style)).map_err(|e| e.to_string())?;
            }
            key.draw(&Text::new(label.clone(), (x + 36, y - 7), ("DejaVu Sans", 13).into_font()))
                .map_err(|e| e.to_string())?;
        }
        for (p, area) in panels.iter().zip(areas.iter()) {
            let tx = |v: f64| if p.log_x { v.log10() } else { v };
            let xs: Vec<f64> = p.points.iter().map(|q| tx(q.value)).chain([tx(p.default_value)]).collect();
            let (lo, hi) = xs.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| (a.min(x), b.max(x)));
            let pad = ((hi - lo) * 0.08).max(1e-3);
            let mut chart = ChartBuilder::on(area)
                .margin(10)
                .x_label_area_size(40)
                .y_label_area_size(50)
                .build_cartesian_2d((lo - pad)..(hi + pad), 0.0..ymax)
                .map_err(|e| e.to_string())?;
            let log_x = p.log_x;
            chart
                .configure_mesh()
                .x_labels(6)
                .x_label_formatter(&move |x| if log_x { format!("{:.2}", 10f64.powf(*x)) } else { format!("{x:.2}") })
                .x_desc(p.parameter.clone())
                .y_desc("mean TRE [mm]")
                .draw()
                .map_err(|e| e.to_string())?;
            let mut pts: Vec<&SweepPoint> = p.points.iter().collect();
            pts.sort_by(|a, b| a.value.total_cmp(&b.value));
            for (col, pick) in [
                (mean_col, (|q: &SweepPoint| q.mean_mm) as fn(&SweepPoint) -> f64),
                (near_col, |q: &SweepPoint| q.near_mm),
            ] {
                let line: Vec<(f64, f64)> =
                    pts.iter().filter(|q| finite(pick(q))).map(|q| (tx(q.value), pick(q))).collect();
                chart.draw_series(LineSeries::new(line.clone(), col.stroke_width(2))).map_err(|e| e.to_string())?;
                chart.draw_series(line.iter().map(|&q| Circle::new(q, 3, col.filled()))).map_err(|e| e.to_string())?;
                let d: Vec<(f64, f64)> =
                    line.iter().copied().filter(|q| (q.0 - tx(p.default_value)).abs() < 1e-9).collect();
                chart
                    .draw_series(d.iter().map(|&q| Circle::new(q, 7, BLACK.stroke_width(2))))
                    .map_err(|e| e.to_string())?;
            }
            if let Some((_, mean, near)) = reference {
                for (col, v) in [(mean_col, mean), (near_col, near)] {
                    if finite(v) {
                        chart
                            .draw_series(DashedLineSeries::new(
                                vec![(lo - pad, v), (hi + pad, v)],
                                6,
                                4,
                                col.stroke_width(1),
                            ))
                            .map_err(|e| e.to_string())?;
                    }
                }
            }
        }
        Ok(())
    })
    .map_err(|e| RegisterError::bad(path.display().to_string(), e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn view(z: f64) -> SurfaceView {
        SurfaceView { direction: Vector3::new(0.0, 0.0, z), up: Vector3::y(), size_px: 64 }
    }

    #[test]
    fn rendering_colours_by_value_and_hides_the_back() {
        // two parallel squares facing the viewer; the nearer one (value 1) must hide the farther (value 0)
        let v = vec![
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(1.0, 0.0, 0.0),
            Vector3::new(1.0, 1.0, 0.0),
            Vector3::new(0.0, 1.0, 0.0),
            Vector3::new(0.0, 0.0, -1.0),
            Vector3::new(1.0, 0.0, -1.0),
            Vector3::new(1.0, 1.0, -1.0),
            Vector3::new(0.0, 1.0, -1.0),
        ];
        let f = vec![[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]];
        let vals = [1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0];
        // camera looks along -z from +z: the square at z = 0 is nearer
        let img = render_scalar_surface(&v, &f, &vals, (0.0, 1.0, Colormap::Gray), &view(-1.0));
        let c = img.pixel(32, 32);
        assert_eq!(c[0], 255, "the near face (value 1 = white in Gray, facing the view: shade 1)");
        // from the other side the far square (value 0) is in front
        let img = render_scalar_surface(&v, &f, &vals, (0.0, 1.0, Colormap::Gray), &view(1.0));
        assert_eq!(img.pixel(32, 32)[0], 0);
    }

    /// Whether any pixel in columns x0..x1, rows y0..y1 of `img` has exactly the colour `rgb`.
    fn has_colour(img: &Image<u8>, (x0, x1): (usize, usize), (y0, y1): (usize, usize), rgb: [u8; 3]) -> bool {
        (y0..y1.min(img.height)).any(|y| (x0..x1.min(img.width)).any(|x| img.pixel(x, y)[..3] == rgb))
    }

    #[test]
    fn distance_plot_keeps_its_legend_off_the_axes() {
        use super::super::protocol::Column;
        let cell = |method: &str, bins: [f64; 6]| Cell {
            scenario: "anatomical".into(),
            method: method.into(),
            column: Column { landmarks: 50, noise_sigma_mm: 0.0 },
            mean_mm: bins[0],
            std_mm: 0.0,
            seed_std_mm: 0.0,
            surface_mean_mm: bins[0],
            bin_means_mm: bins.to_vec(),
            seeds: 1,
            seconds: 1.0,
            points: None,
        };
        // the second method's last point lies where an in-chart legend (upper right) used to be drawn
        let a = cell("none (rest)", [5.0, 2.7, 1.7, 0.8, 0.5, 0.1]);
        let b = cell("RODS-MPM oracle (ballistic v0, kerf 18 mm)", [6.4, 6.4, 9.6, 16.5, 17.5, 8.1]);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("fig58.png");
        write_distance_plot(&path, &[&a, &b], "t").unwrap();
        let img = laparo_core::io::read_image(&path).unwrap();
        // the strip right of the 760 px axes is wide enough for the longest name (42 characters)
        assert_eq!((img.width, img.height), (760 + 40 + 8 * 42, 460));
        let (blue, orange) = ([31, 119, 180], [255, 127, 14]);
        for c in [blue, orange] {
            assert!(has_colour(&img, (760, img.width), (0, 460), c), "legend entry {c:?} in the strip");
            assert!(has_colour(&img, (0, 760), (0, 460), c), "line {c:?} in the axes");
        }
        // the > 80 mm point of the second method (8.1 mm, x at the last bin) is drawn, not covered
        assert!(has_colour(&img, (640, 760), (0, 460), orange));
    }

    #[test]
    fn sweep_plot_has_one_panel_per_setting_and_refuses_bad_sweeps() {
        let pt = |value: f64, mean_mm: f64, near_mm: f64| SweepPoint { value, mean_mm, near_mm };
        let panel = |parameter: &str, log_x: bool, values: &[f64]| SweepPanel {
            parameter: parameter.into(),
            default_value: values[0],
            log_x,
            points: values.iter().map(|&v| pt(v, 0.2 + 0.01 * v, 2.0 + 0.1 * v)).collect(),
        };
        let panels = vec![
            panel("E factor", true, &[1.0, 0.25, 10.0]),
            panel("ν", false, &[0.49, 0.3]),
            panel("spacing [mm]", false, &[3.0, 4.5]),
            panel("Δx [mm]", false, &[6.0, 9.0]),
        ];
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("fig59.png");
        write_sweep_plot(&path, &panels, Some(("François et al.", 0.28, 2.16)), "sweep").unwrap();
        let img = laparo_core::io::read_image(&path).unwrap();
        // four panels: three columns, two rows, 40 px for the title
        assert_eq!((img.width, img.height), (3 * 420, 2 * 330 + 40));
        // the legend (solid and dashed RODS-MPM / reference lines) sits in the free cells, not over a panel
        let (red, blue) = ([214, 39, 40], [31, 119, 180]);
        assert!(has_colour(&img, (420, 1260), (370, 700), red) && has_colour(&img, (420, 1260), (370, 700), blue));
        // three panels fill the grid: the legend gets a band of its own below them
        write_sweep_plot(&path, &panels[..3], Some(("François et al.", 0.28, 2.16)), "sweep").unwrap();
        let img = laparo_core::io::read_image(&path).unwrap();
        assert_eq!((img.width, img.height), (3 * 420, 330 + 40 + 24 * 4 + 16));
        assert!(has_colour(&img, (0, 1260), (372, img.height), red));
        let err = write_sweep_plot(&path, &[], None, "x").unwrap_err().to_string();
        assert!(err.contains("no sweep results"), "{err}");
        let neg = vec![panel("E factor", true, &[1.0, -1.0])];
        let err = write_sweep_plot(&path, &neg, None, "x").unwrap_err().to_string();
        assert!(err.contains("log-axis"), "{err}");
    }
}
