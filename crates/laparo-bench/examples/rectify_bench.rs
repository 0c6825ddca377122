//! Rectification timing on the real SCARED ds1-3 pair (same work as `laparo-bench stereo`):
//! `cargo run --release -p laparo-bench --example rectify_bench -- THREADS`.
use laparo_core::calib::StereoCalibration;
use laparo_core::remap::{remap, Interp};
use laparo_stereo::{Rectification, RectifyOptions, Side};

fn main() {
    let d = concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data/");
    let threads: usize = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(1);
    let calib =
        StereoCalibration::read_with_size(format!("{d}calib/scared_ds1-3_endoscope_calibration.yaml"), 1280, 1024)
            .unwrap();
    let left = laparo_core::io::read_image(format!("{d}surgical/scared_pair_ds1-3/Left_Image.png")).unwrap();
    let right = laparo_core::io::read_image(format!("{d}surgical/scared_pair_ds1-3/Right_Image.png")).unwrap();
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    pool.install(|| {
        let (mut tm, mut tr) = (Vec::new(), Vec::new());
        for _ in 0..15 {
            let t0 = std::time::Instant::now();
            let rect = Rectification::new(&calib, RectifyOptions::default()).unwrap();
            let (ml, mr) = (rect.remap_table(Side::Left), rect.remap_table(Side::Right));
            let t1 = std::time::Instant::now();
            let out =
                (remap(&left, &ml, Interp::Bilinear, 0).unwrap(), remap(&right, &mr, Interp::Bilinear, 0).unwrap());
            let t2 = std::time::Instant::now();
            std::hint::black_box(out);
            tm.push((t1 - t0).as_secs_f64() * 1e3);
            tr.push((t2 - t1).as_secs_f64() * 1e3);
        }
        println!(
            "laparo {}x{}x{} threads={threads}: rectify + maps x2 {:.2} ms, remap bilinear x2 {:.2} ms (median of 15)",
            left.width,
            left.height,
            left.channels,
            laparo_core::stats::median(&mut tm),
            laparo_core::stats::median(&mut tr)
        );
    });
}
