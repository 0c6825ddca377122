//! CLI tests of `laparo stereo match`: a synthetic textured pair with a known signed disparity and a
//! known vertical offset, depth from a focal length and baseline, and bad input.
use laparo_core::image::Image;
use std::path::Path;
mod common;
use common::laparo;

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Smooth random texture (value noise), deterministic.
fn texture(w: usize, h: usize, seed: u64) -> Vec<f64> {
    let mut state = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
    let mut rnd = || {
        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (state >> 33) as f64 / (1u64 << 31) as f64
    };
    let cell = 4usize;
    let (gw, gh) = (w / cell + 2, h / cell + 2);
    let g: Vec<f64> = (0..gw * gh).map(|_| rnd()).collect();
    let mut out = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            let (fx, fy) = (x as f64 / cell as f64, y as f64 / cell as f64);
            let (ix, iy) = (fx as usize, fy as usize);
            let (tx, ty) = (fx - ix as f64, fy - iy as f64);
            let v = |i: usize, j: usize| g[j * gw + i];
            out[y * w + x] = (1.0 - ty) * ((1.0 - tx) * v(ix, iy) + tx * v(ix + 1, iy))
                + ty * ((1.0 - tx) * v(ix, iy + 1) + tx * v(ix + 1, iy + 1));
        }
    }
    out
}

/// Left = texture; right(x, y) = left(x + d, y + dy): the right view sees the scene shifted so that
/// x_L − x_R = d (CATS' convention), and one row lower when dy = 1.
fn pair(dir: &Path, d: i64, dy: i64) -> (std::path::PathBuf, std::path::PathBuf) {
    let (w, h) = (160usize, 96usize);
    let big = texture(w + 40, h + 8, 7);
    let at = |x: i64, y: i64| big[(y + 4) as usize * (w + 40) + (x + 20) as usize];
    let mut l = Image::filled(w, h, 1, 0u8);
    let mut r = Image::filled(w, h, 1, 0u8);
    for y in 0..h as i64 {
        for x in 0..w as i64 {
            l.data[(y as usize) * w + x as usize] = (at(x, y) * 255.0).round() as u8;
            r.data[(y as usize) * w + x as usize] = (at(x + d, y + dy) * 255.0).round() as u8;
        }
    }
    let (lp, rp) = (dir.join(format!("l{d}_{dy}.png")), dir.join(format!("r{d}_{dy}.png")));
    laparo_core::io::write_png(&lp, &l).unwrap();
    laparo_core::io::write_png(&rp, &r).unwrap();
    (lp, rp)
}

fn median_valid(p: &Path) -> (f64, f64) {
    let img = laparo_core::io::read_pfm(p).unwrap();
    let mut v: Vec<f64> = img.data.iter().filter(|x| x.is_finite()).map(|&x| x as f64).collect();
    let frac = v.len() as f64 / img.data.len() as f64;
    v.sort_by(|a, b| a.total_cmp(b));
    (v[v.len() / 2], frac)
}

#[test]
fn a_negative_disparity_is_recovered_with_depth_from_focal_and_baseline() {
    let dir = tempfile::tempdir().unwrap();
    let (l, r) = pair(dir.path(), -6, 0);
    let out = dir.path().join("out");
    let (ok, stdout, err) = laparo(&[
        "stereo",
        "match",
        "--left",
        s(&l),
        "--right",
        s(&r),
        "--range",
        "-16:4",
        "--out",
        s(&out),
        "--focal-px",
        "500",
        "--baseline-mm",
        "5",
        "--cx-offset-px",
        "-10",
    ]);
    assert!(ok, "{err}");
    assert!(stdout.contains("matched 160x96"), "{stdout}");
    let (med, frac) = median_valid(&out.join("disparity.pfm"));
    assert!((med + 6.0).abs() < 0.25, "median disparity {med} (expected −6)");
    assert!(frac > 0.7, "valid fraction {frac}");
    // d = f b / z + (c_x^L − c_x^R): z = f b / (d − offset) = 500 · 5 / (−6 + 10) = 625 mm
    let depth = laparo_core::io::read_float_map(out.join("depth_mm.npy")).unwrap();
    let mut z: Vec<f64> = depth.data.iter().copied().filter(|v| v.is_finite()).collect();
    z.sort_by(|a, b| a.total_cmp(b));
    let zm = z[z.len() / 2];
    assert!((zm - 625.0).abs() < 40.0, "median depth {zm} mm (expected 625)");
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("stats.json")).unwrap()).unwrap();
    assert_eq!(stats["range_px"], serde_json::json!([-16, 4]));
    for f in ["disparity.png", "confidence.pfm", "confidence.png", "depth.png"] {
        assert!(out.join(f).exists(), "{f}");
    }
}

#[test]
fn vertical_tolerance_reports_the_row_offset() {
    let dir = tempfile::tempdir().unwrap();
    let (l, r) = pair(dir.path(), 5, 1);
    let out = dir.path().join("out");
    let (ok, _, err) = laparo(&[
        "stereo",
        "match",
        "--left",
        s(&l),
        "--right",
        s(&r),
        "--range",
        "0:12",
        "--vertical-tol",
        "1",
        "--out",
        s(&out),
    ]);
    assert!(ok, "{err}");
    let (d, _) = median_valid(&out.join("disparity.pfm"));
    assert!((d - 5.0).abs() < 0.25, "median disparity {d}");
    // right(x, y) = left(x + d, y + 1): the match of left row y is right row y − 1
    let (dy, _) = median_valid(&out.join("dy.pfm"));
    assert!((dy.abs() - 1.0).abs() < 1e-6, "median vertical offset {dy}");
}

#[test]
fn bad_input_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let (l, r) = pair(dir.path(), 3, 0);
    let out = dir.path().join("out");
    let (ok, _, err) =
        laparo(&["stereo", "match", "--left", s(&l), "--right", s(&r), "--range", "5:3", "--out", s(&out)]);
    assert!(!ok && err.contains("--range") && err.contains("empty range"), "{err}");
    let missing = dir.path().join("nope.png");
    let (ok, _, err) =
        laparo(&["stereo", "match", "--left", s(&missing), "--right", s(&r), "--range", "0:8", "--out", s(&out)]);
    assert!(!ok && err.contains("nope.png"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
}
