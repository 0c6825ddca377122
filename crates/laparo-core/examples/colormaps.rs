//! Writes one colour-mapped gradient with a colour bar per colour map:
//! `cargo run --release -p laparo-core --example colormaps -- OUT_DIR`
use laparo_core::colormap::{colorize, Colormap};
use laparo_core::plot::with_colorbar;
use laparo_core::{io, Image};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::path::PathBuf::from(std::env::args().nth(1).unwrap_or_else(|| "colormaps".into()));
    let (w, h) = (320usize, 240usize);
    let mut img = Image::filled(w, h, 1, 0.0f64);
    for y in 0..h {
        for x in 0..w {
            // a radial bump in mm, with a NaN hole to show the invalid colour
            let (dx, dy) = (x as f64 - 160.0, y as f64 - 120.0);
            let v = 40.0 + 80.0 * (-(dx * dx + dy * dy) / 8000.0).exp();
            img.set(x, y, 0, if dx.hypot(dy) < 12.0 { f64::NAN } else { v });
        }
    }
    for cm in Colormap::ALL {
        let c = colorize(&img, 40.0, 120.0, cm);
        let fig = with_colorbar(&c, 40.0, 120.0, cm, "depth [mm]");
        io::write_png(out.join(format!("{cm}.png")), &fig)?;
    }
    Ok(())
}
