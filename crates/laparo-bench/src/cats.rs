//! `laparo-bench cats`: CATS warp timings (RGB u8 bilinear, f32 nearest; grey u8 bicubic, the
//! self-rectified matcher's warp) on the same input and homography as `../shared/bench/warp_ref.py`,
//! optionally running that OpenCV peer (and `scripts/warp_grey_cubic_opencv.py`) in the same
//! session (formerly `laparo cats bench`).
use crate::timing::time_min_median;
use anyhow::{bail, Context, Result};
use clap::Args;
use laparo_core::{io, Distortion, Image, Intrinsics};
use laparo_stereo::CameraAugmentation;
use nalgebra::Matrix3;
use std::path::PathBuf;

/// Options of `laparo-bench cats` (those of the former `laparo cats bench`).
#[derive(Args)]
pub struct BenchArgs {
    /// Image to warp (resized to WIDTH×HEIGHT).
    #[arg(long)]
    pub image: PathBuf,
    /// Warped image width (px).
    #[arg(long, default_value_t = 960)]
    pub width: usize,
    /// Warped image height (px).
    #[arg(long, default_value_t = 540)]
    pub height: usize,
    /// Timed runs per warp (after one warm-up; minimum and median reported).
    #[arg(long, default_value_t = 20)]
    pub runs: usize,
    /// Threads for laparo (rayon) and OpenCV.
    #[arg(long, default_value_t = 1)]
    pub threads: usize,
    /// Python with numpy + opencv-python-headless: run the peer script in the same session.
    #[arg(long)]
    pub peer_python: Option<PathBuf>,
    /// The peer script.
    #[arg(long, default_value = "../shared/bench/warp_ref.py")]
    pub peer_script: PathBuf,
    /// The grey bicubic peer script (cv2.warpPerspective INTER_CUBIC, same homography).
    #[arg(long, default_value = "scripts/warp_grey_cubic_opencv.py")]
    pub grey_peer_script: PathBuf,
}

fn rows(m: &Matrix3<f64>) -> [[f64; 3]; 3] {
    [[m[(0, 0)], m[(0, 1)], m[(0, 2)]], [m[(1, 0)], m[(1, 1)], m[(1, 2)]], [m[(2, 0)], m[(2, 1)], m[(2, 2)]]]
}

/// Area-average resize (like OpenCV INTER_AREA for downscaling; bilinear when upscaling).
fn resize(img: &Image<u8>, w: usize, h: usize) -> Image<u8> {
    let (sx, sy) = (img.width as f64 / w as f64, img.height as f64 / h as f64);
    let mut out = Image::filled(w, h, img.channels, 0u8);
    for y in 0..h {
        for x in 0..w {
            for c in 0..img.channels {
                let v = if sx >= 1.0 && sy >= 1.0 {
                    let (x0, x1) = ((x as f64 * sx) as usize, (((x + 1) as f64 * sx).ceil() as usize).min(img.width));
                    let (y0, y1) = ((y as f64 * sy) as usize, (((y + 1) as f64 * sy).ceil() as usize).min(img.height));
                    let mut s = 0.0;
                    for yy in y0..y1 {
                        for xx in x0..x1 {
                            s += img.get(xx, yy, c) as f64;
                        }
                    }
                    s / ((x1 - x0) * (y1 - y0)) as f64
                } else {
                    let u = ((x as f64 + 0.5) * sx - 0.5).clamp(0.0, (img.width - 1) as f64);
                    let v = ((y as f64 + 0.5) * sy - 0.5).clamp(0.0, (img.height - 1) as f64);
                    img.sample_bilinear(u, v, c).unwrap_or(0.0)
                };
                out.set(x, y, c, (v + 0.5) as u8);
            }
        }
    }
    out
}

pub fn run(a: BenchArgs) -> Result<()> {
    let img = resize(&io::read_rgb8(&a.image)?.to_rgb(), a.width, a.height);
    // The same camera and homography as warp_ref.py: f = 0.9 w, c = (w/2, h/2), Euler Z-Y-X
    // (0.3, 0.2, 0.02) deg → R = Rz(0.3) Ry(0.2) Rx(0.02), K_rel shift −60 px.
    let (w, h) = (a.width as f64, a.height as f64);
    let k = Intrinsics::new(0.9 * w, 0.9 * w, w / 2.0, h / 2.0, a.width, a.height)?;
    let aug = CameraAugmentation::from_euler_deg(
        k,
        Distortion::default(),
        [0.02, 0.2, 0.3],
        Matrix3::new(1.0, 0.0, -60.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0),
        Distortion::default(),
    );
    let map = aug.map()?;
    // A uniform(0, 100) float map (xorshift; content does not matter for timing).
    let mut st = 0x2545F4914F6CDD1Du64;
    let fmap = Image::from_vec(
        a.width,
        a.height,
        1,
        (0..a.width * a.height)
            .map(|_| {
                st ^= st << 13;
                st ^= st >> 7;
                st ^= st << 17;
                (st >> 40) as f32 / (1u64 << 24) as f32 * 100.0
            })
            .collect(),
    )?;
    let pool = rayon::ThreadPoolBuilder::new().num_threads(a.threads).build()?;
    let grey = Image::from_vec(a.width, a.height, 1, laparo_stereo::to_gray_u8(&img))?;
    let h_inv = rows(&map.h.try_inverse().context("the CATS homography is singular")?);
    let (rgb, f32n, gc) = pool.install(|| -> Result<_> {
        let rgb = time_min_median(a.runs, || {
            std::hint::black_box(map.warp_bilinear_u8(&img).expect("sizes match"));
        });
        let f32n = time_min_median(a.runs, || {
            std::hint::black_box(map.warp_nearest_f32(&fmap, f32::INFINITY).expect("sizes match"));
        });
        let gc = time_min_median(a.runs, || {
            std::hint::black_box(
                laparo_core::remap::warp_homography(
                    &grey,
                    &h_inv,
                    a.width,
                    a.height,
                    laparo_core::remap::Interp::Bicubic,
                    0u8,
                )
                .expect("sizes match"),
            );
        });
        Ok((rgb, f32n, gc))
    })?;
    let mut out = serde_json::json!({
        "laparo": env!("CARGO_PKG_VERSION"), "threads": a.threads, "size": [a.width, a.height],
        "H": rows(&map.h),
        "rgb_u8_bilinear": {"min_ms": rgb.0, "median_ms": rgb.1},
        "f32_nearest": {"min_ms": f32n.0, "median_ms": f32n.1},
        "grey_u8_bicubic": {"min_ms": gc.0, "median_ms": gc.1},
    });
    if let Some(py) = &a.peer_python {
        // both peer scripts take the image, size, runs and threads and print JSON
        let run_peer = |script: &PathBuf| -> Result<serde_json::Value> {
            let o = std::process::Command::new(py)
                .arg(script)
                .arg(&a.image)
                .args(["--width", &a.width.to_string(), "--height", &a.height.to_string()])
                .args(["--runs", &a.runs.to_string(), "--threads", &a.threads.to_string()])
                .output()
                .with_context(|| format!("running {} {}", py.display(), script.display()))?;
            if !o.status.success() {
                bail!("peer script {} failed: {}", script.display(), String::from_utf8_lossy(&o.stderr));
            }
            serde_json::from_slice(&o.stdout).with_context(|| format!("parsing the JSON of {}", script.display()))
        };
        let peer = run_peer(&a.peer_script)?;
        let peer2 = run_peer(&a.grey_peer_script)?;
        let ratio = |p: &serde_json::Value, key: &str, ours: f64| p[key]["min_ms"].as_f64().map(|p| p / ours);
        out["opencv"] = peer.clone();
        out["opencv_grey_bicubic"] = peer2.clone();
        out["speedup_vs_opencv_min"] = serde_json::json!({
            "rgb_u8_bilinear": ratio(&peer, "rgb_u8_bilinear", rgb.0),
            "f32_nearest": ratio(&peer, "f32_nearest", f32n.0),
            "grey_u8_bicubic": ratio(&peer2, "grey_u8_bicubic", gc.0),
        });
        // Same homography on both sides (the peer prints its H).
        if let Some(ph) = peer["H"].as_array() {
            let ph: Vec<f64> =
                ph.iter().flat_map(|r| r.as_array().into_iter().flatten().filter_map(|v| v.as_f64())).collect();
            let ours: Vec<f64> = rows(&map.h).concat();
            let diff = ph.iter().zip(&ours).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
            out["max_abs_H_difference"] = serde_json::json!(diff);
        }
    }
    println!("{}", serde_json::to_string_pretty(&out)?);
    Ok(())
}
