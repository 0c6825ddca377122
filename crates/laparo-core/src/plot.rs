//! Figures: a bundled font for plotters, PNG/SVG rendering helpers and the colour-bar panel.
//!
//! The workspace builds plotters without its `bitmap_encoder` (which would pull a second image
//! stack); [`draw_png`] renders into an RGB buffer with `BitMapBackend::with_buffer` and encodes
//! it with [`crate::io::write_png`], atomically. Text uses DejaVu Sans, compiled into the binary
//! (`assets/DejaVuSans.ttf`, Bitstream Vera licence in `assets/DejaVuSans-LICENSE.txt`), so figures
//! look the same on every machine and need no system fonts.
use crate::colormap::{nice_ticks, Colormap};
use crate::error::{CoreError, Result};
use crate::image::Image;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::FontTransform;
use std::path::Path;
use std::sync::Once;

/// DejaVu Sans (Bitstream Vera licence), embedded.
pub static DEJAVU_SANS: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");

/// Result type of drawing closures: plotters errors, `anyhow` errors and `CoreError` all convert
/// into it with `?`.
pub type PlotResult = std::result::Result<(), Box<dyn std::error::Error + Send + Sync>>;

static FONTS: Once = Once::new();

/// Register the bundled DejaVu Sans with plotters under "sans-serif" (and "serif",
/// "monospace", "DejaVu Sans", "Arial", "Helvetica" so any common family name renders).
/// Idempotent and thread-safe; every function of this module calls it.
pub fn ensure_fonts() {
    FONTS.call_once(|| {
        for name in ["sans-serif", "serif", "monospace", "DejaVu Sans", "Arial", "Helvetica"] {
            // The font is valid (checked by tests); a failure would only lose text.
            let _ = plotters::style::register_font(name, FontStyle::Normal, DEJAVU_SANS);
        }
    });
}

/// Save a tightly packed RGB buffer (`width * height * 3` bytes) as PNG, atomically.
pub fn save_rgb_png(path: impl AsRef<Path>, width: usize, height: usize, rgb: &[u8]) -> Result<()> {
    let path = path.as_ref();
    if rgb.len() != width * height * 3 {
        return Err(CoreError::SizeMismatch(format!(
            "{}: RGB buffer has {} bytes, {width}x{height}x3 needs {}",
            path.display(),
            rgb.len(),
            width * height * 3
        )));
    }
    crate::io::write_png(path, &Image { width, height, channels: 3, data: rgb.to_vec() })
}

/// Render with plotters into a `width × height` RGB image (white background).
pub fn render_rgb<F>(width: u32, height: u32, draw: F) -> std::result::Result<Image<u8>, String>
where
    F: FnOnce(DrawingArea<BitMapBackend<'_>, Shift>) -> PlotResult,
{
    ensure_fonts();
    if width == 0 || height == 0 {
        return Err(format!("empty figure size {width}x{height}"));
    }
    let mut buf = vec![255u8; width as usize * height as usize * 3];
    {
        let backend = BitMapBackend::with_buffer(&mut buf, (width, height));
        draw(backend.into_drawing_area()).map_err(|e| format!("drawing failed: {e}"))?;
    }
    Ok(Image { width: width as usize, height: height as usize, channels: 3, data: buf })
}

/// Render a figure with plotters and save it as PNG, atomically. The closure receives the root
/// drawing area (already white):
/// ```no_run
/// use plotters::prelude::*;
/// laparo_core::plot::draw_png("fig.png", 400, 300, |root| {
///     let mut chart = ChartBuilder::on(&root).caption("y = x²", ("sans-serif", 20))
///         .x_label_area_size(30).y_label_area_size(40).build_cartesian_2d(0f64..1f64, 0f64..1f64)?;
///     chart.configure_mesh().draw()?;
///     chart.draw_series(LineSeries::new((0..=100).map(|i| (i as f64 / 100.0, (i as f64 / 100.0).powi(2))), &RED))?;
///     Ok(())
/// }).unwrap();
/// ```
pub fn draw_png<F>(path: impl AsRef<Path>, width: u32, height: u32, draw: F) -> Result<()>
where
    F: FnOnce(DrawingArea<BitMapBackend<'_>, Shift>) -> PlotResult,
{
    let path = path.as_ref();
    let img = render_rgb(width, height, draw).map_err(|m| CoreError::format(path, m))?;
    crate::io::write_png(path, &img)
}

/// Render a figure with plotters' SVG backend and save it, atomically (same closure shape as
/// [`draw_png`], with `SVGBackend`).
pub fn draw_svg<F>(path: impl AsRef<Path>, width: u32, height: u32, draw: F) -> Result<()>
where
    F: FnOnce(DrawingArea<SVGBackend<'_>, Shift>) -> PlotResult,
{
    ensure_fonts();
    let path = path.as_ref();
    if width == 0 || height == 0 {
        return Err(CoreError::format(path, format!("empty figure size {width}x{height}")));
    }
    let mut s = String::new();
    {
        let backend = SVGBackend::with_string(&mut s, (width, height));
        let root = backend.into_drawing_area();
        root.fill(&WHITE).map_err(|e| CoreError::format(path, format!("drawing failed: {e}")))?;
        draw(root).map_err(|e| CoreError::format(path, format!("drawing failed: {e}")))?;
    }
    crate::atomic::write_atomic(path, s.as_bytes())
}

/// Layout of the colour-bar panel (all in px), exposed for tests.
#[derive(Clone, Copy, Debug)]
pub(crate) struct BarLayout {
    pub bar_left: usize,
    pub bar_right: usize,
    pub bar_top: usize,
    pub bar_bottom: usize,
    pub label_left: usize,
    pub width: usize,
}

fn text_width(font: &FontDesc<'_>, s: &str) -> usize {
    font.box_size(s).map(|(w, _)| w as usize).unwrap_or(s.len() * 8)
}

pub(crate) fn bar_layout(img_w: usize, h: usize, labels: &[String], label: &str, font_px: f64) -> BarLayout {
    let font = ("sans-serif", font_px).into_font();
    let max_label_w = labels.iter().map(|s| text_width(&font, s)).max().unwrap_or(0);
    let margin = (font_px * 0.6).round() as usize;
    let bar_w = (font_px * 1.2).round() as usize;
    let tick = (font_px * 0.4).round() as usize;
    let x0 = img_w;
    let bar_left = x0 + margin;
    let bar_right = bar_left + bar_w;
    let label_left = bar_right + tick + 3;
    let mut width = label_left + max_label_w + margin;
    if !label.is_empty() {
        width += font_px.ceil() as usize + margin;
    }
    let pad = margin + (font_px / 2.0).ceil() as usize;
    let (bar_top, bar_bottom) = if h > 2 * pad + 4 { (pad, h - 1 - pad) } else { (0, h.saturating_sub(1)) };
    BarLayout { bar_left, bar_right, bar_top, bar_bottom, label_left, width }
}

/// Append a vertical colour bar for [lo, hi] to the right of `img` (gray, RGB or RGBA), with
/// tick labels and `label` (e.g. "depth [mm]") written along it. Returns an RGB image of the same
/// height and larger width. Uses the bundled DejaVu Sans (see [`ensure_fonts`]).
pub fn with_colorbar(img: &Image<u8>, lo: f64, hi: f64, cmap: Colormap, label: &str) -> Image<u8> {
    ensure_fonts();
    let (w, h) = (img.width, img.height);
    let font_px = (h as f64 / 28.0).clamp(11.0, 26.0);
    let target = ((h as f64 / (3.0 * font_px)) as usize).clamp(2, 6);
    let (ticks, dec) = nice_ticks(lo, hi, target);
    let labels: Vec<String> = ticks.iter().map(|t| format!("{t:.dec$}")).collect();
    let l = bar_layout(w, h, &labels, label, font_px);
    let total_w = l.width;
    let mut out = Image::filled(total_w, h, 3, 255u8);
    // The picture itself.
    for y in 0..h {
        for x in 0..w {
            let p = img.pixel(x, y);
            let rgb = match img.channels {
                1 | 2 => [p[0], p[0], p[0]],
                _ => [p[0], p[1], p[2]],
            };
            out.pixel_mut(x, y).copy_from_slice(&rgb);
        }
    }
    if h == 0 {
        return out;
    }
    // The bar: top = hi, bottom = lo, as colorize maps them.
    let span = (l.bar_bottom - l.bar_top).max(1) as f64;
    for y in l.bar_top..=l.bar_bottom {
        let t = 1.0 - (y - l.bar_top) as f64 / span;
        let c = cmap.rgb(t);
        for x in l.bar_left..l.bar_right {
            out.pixel_mut(x, y).copy_from_slice(&c);
        }
    }
    // Outline, ticks and text with plotters (errors only lose text, never the picture).
    let y_of = |v: f64| -> Option<i32> {
        let t = (v - lo) / (hi - lo);
        t.is_finite().then(|| (l.bar_bottom as f64 - t * span).round() as i32)
    };
    let _ = (|| -> PlotResult {
        let backend = BitMapBackend::with_buffer(&mut out.data, (total_w as u32, h as u32));
        let root = backend.into_drawing_area();
        let black = BLACK.stroke_width(1);
        root.draw(&Rectangle::new(
            [(l.bar_left as i32 - 1, l.bar_top as i32 - 1), (l.bar_right as i32, l.bar_bottom as i32 + 1)],
            black,
        ))?;
        let style = TextStyle::from(("sans-serif", font_px).into_font()).color(&BLACK);
        for (v, s) in ticks.iter().zip(&labels) {
            if let Some(y) = y_of(*v) {
                let x1 = l.bar_right as i32;
                root.draw(&PathElement::new(vec![(x1, y), (l.label_left as i32 - 3, y)], black))?;
                root.draw(&Text::new(
                    s.clone(),
                    (l.label_left as i32, y),
                    style.pos(Pos::new(HPos::Left, VPos::Center)),
                ))?;
            }
        }
        if !label.is_empty() {
            let x = (l.width - (font_px * 0.6).round() as usize) as i32 - (font_px / 2.0).round() as i32;
            let y = ((l.bar_top + l.bar_bottom) / 2) as i32;
            let st = style.transform(FontTransform::Rotate270).pos(Pos::new(HPos::Center, VPos::Center));
            root.draw(&Text::new(label.to_string(), (x, y), st))?;
        }
        root.present()?;
        Ok(())
    })();
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::colormap::colorize;

    fn is_dark(p: &[u8]) -> bool {
        p.iter().all(|&v| v < 110)
    }

    #[test]
    fn bundled_font_renders_text() {
        ensure_fonts();
        ensure_fonts(); // idempotent
        let img = render_rgb(120, 40, |root| {
            root.draw(&Text::new("Hg 42", (5, 5), ("sans-serif", 24).into_font().color(&BLACK)))?;
            Ok(())
        })
        .unwrap();
        let dark = img.data.chunks(3).filter(|p| is_dark(p)).count();
        assert!(dark > 40, "text must produce dark pixels, got {dark}");
        // Nothing drawn below the text line.
        assert!((0..120).all(|x| img.pixel(x, 39) == [255, 255, 255]));
    }

    #[test]
    fn colorbar_has_bar_colours_and_labels() {
        let mut v = Image::filled(200, 300, 1, 0.0f64);
        for y in 0..300 {
            for x in 0..200 {
                v.set(x, y, 0, x as f64 / 199.0 * 50.0);
            }
        }
        let c = colorize(&v, 0.0, 50.0, Colormap::Viridis);
        let out = with_colorbar(&c, 0.0, 50.0, Colormap::Viridis, "depth [mm]");
        assert_eq!(out.height, 300);
        assert!(out.width > 200 + 40);
        // the picture is unchanged
        assert_eq!(out.pixel(10, 10), c.pixel(10, 10));
        // bar colours: top = hi, bottom = lo
        let labels: Vec<String> = nice_ticks(0.0, 50.0, 3).0.iter().map(|t| format!("{t:.0}")).collect();
        let font_px = (300f64 / 28.0).clamp(11.0, 26.0);
        let l = bar_layout(200, 300, &labels, "depth [mm]", font_px);
        let mid = (l.bar_left + l.bar_right) / 2;
        assert_eq!(out.pixel(mid, l.bar_top), &Colormap::Viridis.rgb(1.0));
        assert_eq!(out.pixel(mid, l.bar_bottom), &Colormap::Viridis.rgb(0.0));
        // tick labels: dark pixels right of the bar near each tick's height
        let (ticks, _) = nice_ticks(0.0, 50.0, ((300.0 / (3.0 * font_px)) as usize).clamp(2, 6));
        assert!(ticks.len() >= 3);
        for t in ticks {
            let y = (l.bar_bottom as f64 - t / 50.0 * (l.bar_bottom - l.bar_top) as f64).round() as i64;
            let mut dark = 0;
            for yy in (y - 6).max(0)..(y + 6).min(299) {
                for x in l.label_left..l.label_left + 3 * font_px as usize {
                    dark += is_dark(out.pixel(x, yy as usize)) as usize;
                }
            }
            assert!(dark >= 5, "no label text at tick {t} (y = {y})");
        }
        // the rotated axis label: dark pixels in the last columns around the middle
        let mut dark = 0;
        for y in 100..200 {
            for x in out.width - 2 * font_px as usize..out.width {
                dark += is_dark(out.pixel(x, y)) as usize;
            }
        }
        assert!(dark >= 20, "axis label not drawn");
        // background between labels stays white: top-right corner
        assert_eq!(out.pixel(out.width - 1, 0), &[255, 255, 255]);
    }

    #[test]
    fn colorbar_degenerate_inputs_do_not_panic() {
        for (w, h) in [(1, 1), (5, 3), (0, 0), (40, 30)] {
            let img = Image::filled(w, h, 3, 9u8);
            for (lo, hi) in [(0.0, 1.0), (2.0, 2.0), (f64::NAN, 1.0), (5.0, -5.0), (0.0, f64::INFINITY)] {
                let out = with_colorbar(&img, lo, hi, Colormap::Turbo, "x");
                assert_eq!(out.height, h);
                assert!(out.width > w);
                assert_eq!(out.data.len(), out.width * out.height * 3);
            }
        }
        let gray = Image::filled(8, 40, 1, 200u8);
        assert_eq!(with_colorbar(&gray, 0.0, 1.0, Colormap::Gray, "").pixel(3, 3), &[200, 200, 200]);
    }

    #[test]
    fn draw_png_and_svg_write_files() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("chart.png");
        draw_png(&p, 320, 200, |root| {
            let mut chart = ChartBuilder::on(&root)
                .caption("test", ("sans-serif", 16))
                .x_label_area_size(25)
                .y_label_area_size(30)
                .build_cartesian_2d(0f64..1f64, 0f64..1f64)?;
            chart.configure_mesh().draw()?;
            chart.draw_series(LineSeries::new((0..=10).map(|i| (i as f64 / 10.0, i as f64 / 10.0)), &RED))?;
            Ok(())
        })
        .unwrap();
        let img = crate::io::read_image(&p).unwrap();
        assert_eq!((img.width, img.height, img.channels), (320, 200, 3));
        assert!(img.data.chunks(3).any(|px| px[0] > 200 && px[1] < 60 && px[2] < 60), "red line");
        let s = dir.path().join("chart.svg");
        draw_svg(&s, 320, 200, |root| {
            root.draw(&Circle::new((50, 50), 10, BLUE.filled()))?;
            root.draw(&Text::new("label", (10, 10), ("sans-serif", 12)))?;
            Ok(())
        })
        .unwrap();
        let text = std::fs::read_to_string(&s).unwrap();
        assert!(text.starts_with("<svg") && text.contains("circle") && text.contains("label"));
        // a failing closure leaves no file
        let bad = dir.path().join("bad.png");
        let e = draw_png(&bad, 10, 10, |_root| Err("boom".into())).unwrap_err().to_string();
        assert!(e.contains("bad.png") && e.contains("boom"), "{e}");
        assert!(!bad.exists());
        assert!(save_rgb_png(dir.path().join("x.png"), 2, 2, &[0u8; 5]).is_err());
        save_rgb_png(dir.path().join("x.png"), 1, 1, &[1, 2, 3]).unwrap();
    }
}
