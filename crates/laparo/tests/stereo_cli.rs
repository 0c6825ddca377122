//! CLI integration tests of `laparo cats stats` and `laparo stereo rectify|eval|disp2depth`:
//! results through the binary, and bad input → non-zero exit with an error naming the file.
use laparo_core::calib::StereoCalibration;
use laparo_core::camera::{Distortion, Intrinsics};
use laparo_core::image::Image;
use laparo_core::se3::rotation_zyx;
use laparo_stereo::stereo_extrinsics_from_rotations;
use nalgebra::{Rotation3, Vector3};
use std::path::{Path, PathBuf};
mod common;
use common::laparo;

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// A synthetic calibration with known rotations from the ideal frame (left: axis ⊥ X).
fn synthetic(i: usize, w: usize, h: usize) -> (StereoCalibration, [f64; 3], [f64; 3], f64) {
    let fi = i as f64;
    let r_left = Rotation3::new(Vector3::new(0.0, (0.2 - 0.1 * fi).to_radians(), (0.35 - 0.2 * fi).to_radians()));
    let (a, b, c) = r_left.euler_angles();
    let right = [0.01 * fi, -0.3 + 0.2 * fi, 0.4 - 0.25 * fi];
    let r_right = rotation_zyx(right[0].to_radians(), right[1].to_radians(), right[2].to_radians());
    let (r, t) = stereo_extrinsics_from_rotations(r_left.matrix(), &r_right, 4.2 + 0.1 * fi);
    let s = w as f64 / 1280.0;
    let kl = Intrinsics::new(1035.0 * s, 1035.0 * s, 597.0 * s + fi, 520.0 * s, w, h).unwrap();
    let kr = Intrinsics::new(1034.0 * s, 1034.5 * s, 688.0 * s - 2.0 * fi, 521.0 * s, w, h).unwrap();
    let calib = StereoCalibration {
        width: w,
        height: h,
        left: kl,
        left_dist: Distortion::brown_conrady(-0.02, 0.01, 0.0005, -0.0003, 0.0),
        right: kr,
        right_dist: Distortion::brown_conrady(-0.015, 0.008, -0.0002, 0.0004, 0.0),
        r,
        t_mm: t,
    };
    (calib, [a.to_degrees(), b.to_degrees(), c.to_degrees()], right, kl.cx - kr.cx)
}

#[test]
fn cats_stats_json_recovers_synthetic_rotations_and_offsets() {
    let dir = tempfile::tempdir().unwrap();
    let mut files = Vec::new();
    let mut truth = Vec::new();
    for i in 0..3 {
        let (c, l, r, off) = synthetic(i, 1280, 1024);
        let p = dir.path().join(if i == 1 { format!("c{i}.json") } else { format!("c{i}.yaml") });
        if i == 1 {
            c.write_json(&p).unwrap();
        } else {
            c.write_opencv_yaml(&p).unwrap();
        }
        files.push(p);
        truth.push((l, r, off, c.t_mm.norm()));
    }
    let toml_path = dir.path().join("fit.toml");
    let mut args = vec!["cats", "stats", "--json", "--config-out", s(&toml_path)];
    args.extend(files.iter().map(|p| s(p)));
    let (ok, out, err) = laparo(&args);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).expect("one JSON object on stdout");
    let got = v["files"].as_array().unwrap();
    assert_eq!(got.len(), 3);
    for (f, (l, r, off, b)) in got.iter().zip(&truth) {
        for k in 0..3 {
            assert!((f["left_euler_deg"][k].as_f64().unwrap() - l[k]).abs() < 1e-6, "{f}");
            assert!((f["right_euler_deg"][k].as_f64().unwrap() - r[k]).abs() < 1e-6, "{f}");
        }
        assert!((f["principal_point_offset_px"].as_f64().unwrap() - off).abs() < 1e-6);
        assert!((f["baseline_mm"].as_f64().unwrap() - b).abs() < 1e-9);
        assert!(f["max_distortion_px"].as_f64().unwrap() > 0.0);
    }
    // Summary: right x angles 0, 0.01, 0.02 → mean 0.01, population σ = sqrt(2/3)·0.01.
    let m = &v["summary"]["right_euler_deg"][0];
    assert!((m["mean"].as_f64().unwrap() - 0.01).abs() < 1e-9);
    assert!((m["std"].as_f64().unwrap() - 0.01 * (2.0f64 / 3.0).sqrt()).abs() < 1e-9);
    // The fitted config is a valid CATS config.
    let cfg = laparo_stereo::CatsConfig::from_toml_str(&std::fs::read_to_string(&toml_path).unwrap()).unwrap();
    assert!((cfg.right.euler_deg.x.mean() - 0.01).abs() < 1e-9);
}

#[test]
fn cats_stats_bad_input_names_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("nope.yaml");
    let (ok, _, err) = laparo(&["cats", "stats", s(&missing)]);
    assert!(!ok && err.contains("nope.yaml"), "{err}");
    // R that is not a rotation.
    let (mut c, ..) = synthetic(0, 1280, 1024);
    c.r[(0, 0)] = 1.5;
    let p = dir.path().join("bad_r.yaml");
    std::fs::write(
        &p,
        format!(
            "%YAML:1.0\n---\nimage_width: 1280\nimage_height: 1024\nM1: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 1000., 0., 640., 0., 1000., 512., 0., 0., 1. ]\n\
             D1: !!opencv-matrix\n   rows: 1\n   cols: 5\n   dt: d\n   data: [ 0., 0., 0., 0., 0. ]\n\
             M2: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 1000., 0., 700., 0., 1000., 512., 0., 0., 1. ]\n\
             D2: !!opencv-matrix\n   rows: 1\n   cols: 5\n   dt: d\n   data: [ 0., 0., 0., 0., 0. ]\n\
             R: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ {}, 0., 0., 0., 1., 0., 0., 0., 1. ]\n\
             T: !!opencv-matrix\n   rows: 3\n   cols: 1\n   dt: d\n   data: [ -4., 0., 0. ]\n",
            c.r[(0, 0)]
        ),
    )
    .unwrap();
    let (ok, _, err) = laparo(&["cats", "stats", s(&p)]);
    assert!(!ok && err.contains("bad_r.yaml") && err.contains("R is not a rotation"), "{err}");
    // A SCARED-like file without image size: the angles need none (issue 10), so it works with a
    // warning naming the file, and with --width/--height too.
    let scared = dir.path().join("noscale.yaml");
    let text = std::fs::read_to_string(&p)
        .unwrap()
        .replace("1.5, 0., 0.", "1., 0., 0.")
        .replace("image_width: 1280\nimage_height: 1024\n", "");
    std::fs::write(&scared, text).unwrap();
    let (ok, out, err) = laparo(&["cats", "stats", s(&scared)]);
    assert!(ok && err.contains("noscale.yaml") && err.contains("--width/--height"), "{err}");
    assert!(out.contains("Table 3.6"), "{out}");
    let (ok, out, err) = laparo(&["cats", "stats", s(&scared), "--width", "1280", "--height", "1024", "--json"]);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert!((v["files"][0]["principal_point_offset_px"].as_f64().unwrap() + 60.0).abs() < 1e-12);
}

/// Render a textured fronto-parallel plane (rectified frame, z = 50 mm) through both distorted
/// cameras of `c` (exact texture function, inverse mapping).
fn render_pair(c: &StereoCalibration) -> (Image<u8>, Image<u8>) {
    let z0 = 50.0;
    let render = |right: bool| {
        let (k, d) = if right { (&c.right, &c.right_dist) } else { (&c.left, &c.left_dist) };
        let mut img = Image::filled(c.width, c.height, 3, 0u8);
        for y in 0..c.height {
            for x in 0..c.width {
                let (xn, yn) = k.pixel_to_normalized(x as f64, y as f64);
                let (u, v) = d.undistort_normalized(xn, yn).unwrap();
                let (o, dir) = if right {
                    (-(c.r.transpose() * c.t_mm), c.r.transpose() * Vector3::new(u, v, 1.0))
                } else {
                    (Vector3::zeros(), Vector3::new(u, v, 1.0))
                };
                let p = o + dir * ((z0 - o.z) / dir.z);
                let g = (127.5 + 60.0 * (p.x * 2.0).sin() + 60.0 * (p.y * 1.5).cos()).round() as u8;
                img.set(x, y, 0, g);
                img.set(x, y, 1, 255 - g);
                img.set(x, y, 2, 128);
            }
        }
        img
    };
    (render(false), render(true))
}

#[test]
fn stereo_rectify_writes_rectified_pair_and_calibration() {
    let dir = tempfile::tempdir().unwrap();
    let (c, ..) = synthetic(1, 320, 256);
    let calib = dir.path().join("calib.yaml");
    c.write_opencv_yaml(&calib).unwrap();
    let (l, r) = render_pair(&c);
    let (lp, rp) = (dir.path().join("l.png"), dir.path().join("r.png"));
    laparo_core::io::write_png(&lp, &l).unwrap();
    laparo_core::io::write_png(&rp, &r).unwrap();
    let out = dir.path().join("out");
    let (ok, stdout, err) =
        laparo(&["stereo", "rectify", "--calib", s(&calib), "--left", s(&lp), "--right", s(&rp), "--out", s(&out)]);
    assert!(ok, "{err}");
    assert!(stdout.contains("doffs"), "{stdout}");
    let rc = StereoCalibration::read(out.join("calib_rectified.json")).unwrap();
    assert_eq!(rc.r, nalgebra::Matrix3::identity());
    assert!((rc.t_mm.norm() - c.t_mm.norm()).abs() < 1e-12);
    assert_eq!(rc.left.cx, rc.right.cx);
    let info: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("rectification.json")).unwrap()).unwrap();
    assert_eq!(info["doffs_px"].as_f64().unwrap(), 0.0);
    let lr = laparo_core::io::read_image(out.join("left_rectified.png")).unwrap();
    let rr = laparo_core::io::read_image(out.join("right_rectified.png")).unwrap();
    assert_eq!((lr.width, lr.height, lr.channels), (320, 256, 3));
    // The plane is at 50 mm in the left camera; rectified rows must agree: compare the left image
    // with the right one shifted by the best integer-or-not disparity found along the row only.
    let f = rc.left.fx;
    let d = f * c.t_mm.norm() / 50.0; // approximate (the plane is fronto-parallel to the left camera)
    let mut best = f64::INFINITY;
    for k in -40..=40 {
        let dd = d + k as f64 * 0.1;
        let mut e = 0.0;
        let mut n = 0;
        for y in 40..216 {
            for x in 120..300 {
                let xr = x as f64 - dd;
                let x0 = xr.floor() as usize;
                let a = xr - x0 as f64;
                let v = (1.0 - a) * rr.get(x0, y, 0) as f64 + a * rr.get(x0 + 1, y, 0) as f64;
                e += (lr.get(x, y, 0) as f64 - v).abs();
                n += 1;
            }
        }
        best = best.min(e / n as f64);
    }
    assert!(best < 2.0, "rectified pair does not match along rows: {best} grey levels");
    // A SCARED-style file without an image size takes the images' size; an explicit size that
    // disagrees with the images is an error naming the image.
    let text = std::fs::read_to_string(&calib).unwrap();
    let sizeless: String = text.lines().filter(|l| !l.starts_with("image_")).map(|l| format!("{l}\n")).collect();
    let scared = dir.path().join("scared.yaml");
    std::fs::write(&scared, sizeless).unwrap();
    let out2 = dir.path().join("out2");
    let (ok, _, err) =
        laparo(&["stereo", "rectify", "--calib", s(&scared), "--left", s(&lp), "--right", s(&rp), "--out", s(&out2)]);
    assert!(ok, "{err}");
    assert_eq!(
        std::fs::read(out2.join("left_rectified.png")).unwrap(),
        std::fs::read(out.join("left_rectified.png")).unwrap()
    );
    let (ok, _, err) = laparo(&[
        "stereo",
        "rectify",
        "--calib",
        s(&scared),
        "--width",
        "640",
        "--height",
        "512",
        "--left",
        s(&lp),
        "--right",
        s(&rp),
        "--out",
        s(&out2),
    ]);
    assert!(!ok && err.contains("l.png") && err.contains("640x512"), "{err}");
    // Bad input: right image of another size names the file.
    let small = dir.path().join("small.png");
    laparo_core::io::write_png(&small, &Image::filled(100, 80, 3, 0u8)).unwrap();
    let (ok, _, err) =
        laparo(&["stereo", "rectify", "--calib", s(&calib), "--left", s(&lp), "--right", s(&small), "--out", s(&out)]);
    assert!(!ok && err.contains("small.png") && err.contains("100x80"), "{err}");
    let (ok, _, err) = laparo(&[
        "stereo",
        "rectify",
        "--calib",
        s(&dir.path().join("missing.yaml")),
        "--left",
        s(&lp),
        "--right",
        s(&rp),
        "--out",
        s(&out),
    ]);
    assert!(!ok && err.contains("missing.yaml"), "{err}");
}

fn write_npy(p: &Path, w: usize, h: usize, v: &[f64]) {
    laparo_core::io::write_npy_f64(p, &Image::from_vec(w, h, 1, v.to_vec()).unwrap()).unwrap();
}

#[test]
fn stereo_eval_json_markdown_and_maps() {
    let dir = tempfile::tempdir().unwrap();
    let nan = f64::NAN;
    let (gt, pred) = (dir.path().join("gt.npy"), dir.path().join("pred.npy"));
    write_npy(&gt, 4, 2, &[10.0, 20.0, nan, 5.0, -3.0, 8.0, -12.0, 0.0]);
    write_npy(&pred, 4, 2, &[11.0, 17.0, 4.0, 5.5, nan, 8.0, -12.0, 0.2]);
    // Middlebury-style calib.txt: f = 100, b = 2 mm, c_x^R − c_x^L = 10 → z = 200 / (d + 10).
    let calib = dir.path().join("calib.txt");
    std::fs::write(
        &calib,
        "cam0=[100 0 50; 0 100 1; 0 0 1]\ncam1=[100 0 60; 0 100 1; 0 0 1]\ndoffs=10\nbaseline=2\nwidth=4\nheight=2\n",
    )
    .unwrap();
    let out = dir.path().join("eval");
    let (ok, stdout, err) = laparo(&[
        "stereo",
        "eval",
        "--pred",
        s(&pred),
        "--gt",
        s(&gt),
        "--calib",
        s(&calib),
        "--depth-min-mm",
        "1",
        "--depth-max-mm",
        "100",
        "--out",
        s(&out),
        "--json",
    ]);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    let m = &v["metrics"];
    assert!((m["epe_px"].as_f64().unwrap() - 4.7 / 6.0).abs() < 1e-12);
    assert!((m["bad"][2]["percent"].as_f64().unwrap() - 100.0 / 7.0).abs() < 1e-9);
    assert!((m["depth"]["delta_0_25"].as_f64().unwrap() - 4.0 / 6.0).abs() < 1e-12);
    for f in [
        "metrics.json",
        "metrics.md",
        "disparity_pred.png",
        "disparity_gt.png",
        "disparity_error.png",
        "depth_error.png",
    ] {
        assert!(out.join(f).exists(), "{f} missing");
    }
    let map = laparo_core::io::read_image(out.join("disparity_error.png")).unwrap();
    assert!(map.width > 4, "colour bar appended");
    // Size mismatch: error names both files.
    let small = dir.path().join("small.npy");
    write_npy(&small, 3, 2, &[1.0; 6]);
    let (ok, _, err) = laparo(&["stereo", "eval", "--pred", s(&small), "--gt", s(&gt), "--out", s(&out)]);
    assert!(!ok && err.contains("small.npy") && err.contains("gt.npy"), "{err}");
    let (ok, _, err) =
        laparo(&["stereo", "eval", "--pred", s(&dir.path().join("none.npy")), "--gt", s(&gt), "--out", s(&out)]);
    assert!(!ok && err.contains("none.npy"), "{err}");
}

#[test]
fn disp2depth_on_middlebury_motorcycle() {
    let data = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data/middlebury-motorcycle"));
    let disp = data.join("motorcycle_disp.pfm");
    if !disp.exists() {
        eprintln!("SKIP: {} not found", disp.display());
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let calib = dir.path().join("calib.txt");
    // README values scaled to 741x500.
    std::fs::write(
        &calib,
        "cam0=[994.97775 0 311.193; 0 994.97775 254.87675; 0 0 1]\ncam1=[994.97775 0 342.27875; 0 994.97775 254.87675; 0 0 1]\n\
         doffs=31.08575\nbaseline=193.001\nwidth=741\nheight=500\n",
    )
    .unwrap();
    let (depth, ply) = (dir.path().join("z.npy"), dir.path().join("cloud.ply"));
    let (ok, stdout, err) = laparo(&[
        "stereo",
        "disp2depth",
        "--disp",
        s(&disp),
        "--calib",
        s(&calib),
        "--out",
        s(&depth),
        "--ply",
        s(&ply),
        "--image",
        s(&data.join("motorcycle_left.png")),
    ]);
    assert!(ok, "{err}");
    assert!(stdout.contains("343274 of 370500"), "{stdout}");
    let z = laparo_core::io::read_npy(&depth).unwrap();
    let d = laparo_core::io::read_pfm(&disp).unwrap();
    let dv = d.get(400, 300, 0) as f64;
    assert!((z.get(400, 300, 0) - 193.001 * 994.97775 / (dv + 31.08575)).abs() < 1e-6);
    let head = std::fs::read(&ply).unwrap();
    let text = String::from_utf8_lossy(&head[..200]);
    assert!(text.contains("element vertex 343274") && text.contains("property uchar red"), "{text}");
    assert_eq!(head.len(), head.windows(11).position(|w| w == b"end_header\n").unwrap() + 11 + 343_274 * 15);
}

/// Issue 10: a calibration made for another image size (no size in the file, principal point
/// outside the image) was accepted silently; folders of frames had to be rectified one by one.
#[test]
fn stereo_rectify_rejects_a_calibration_of_another_size_and_takes_folders() {
    let dir = tempfile::tempdir().unwrap();
    let (c, ..) = synthetic(1, 320, 256);
    let (l, r) = render_pair(&c);
    let (lp, rp) = (dir.path().join("l.png"), dir.path().join("r.png"));
    laparo_core::io::write_png(&lp, &l).unwrap();
    laparo_core::io::write_png(&rp, &r).unwrap();
    // The same rig calibrated at 1280x1024, written without its image size (SCARED style).
    let (big, ..) = synthetic(1, 1280, 1024);
    let yaml = dir.path().join("big.yaml");
    big.write_opencv_yaml(&yaml).unwrap();
    let text = std::fs::read_to_string(&yaml).unwrap();
    let sizeless: String = text.lines().filter(|l| !l.starts_with("image_")).map(|l| format!("{l}\n")).collect();
    std::fs::write(&yaml, sizeless).unwrap();
    let out = dir.path().join("out");
    let (ok, _, err) =
        laparo(&["stereo", "rectify", "--calib", s(&yaml), "--left", s(&lp), "--right", s(&rp), "--out", s(&out)]);
    assert!(!ok && !err.contains("panicked"), "{err}");
    assert!(err.contains("big.yaml") && err.contains("outside the 320x256 image"), "{err}");
    assert!(!out.exists());

    // Batch: two frames in folders; the maps are built once; each frame equals a single run.
    let calib = dir.path().join("calib.yaml");
    c.write_opencv_yaml(&calib).unwrap();
    let (ld, rd) = (dir.path().join("L"), dir.path().join("R"));
    for name in ["f0.png", "f1.png"] {
        laparo_core::io::write_png(ld.join(name), &l).unwrap();
        laparo_core::io::write_png(rd.join(name), &r).unwrap();
    }
    let single = dir.path().join("single");
    let (ok, _, err) =
        laparo(&["stereo", "rectify", "--calib", s(&calib), "--left", s(&lp), "--right", s(&rp), "--out", s(&single)]);
    assert!(ok, "{err}");
    let (ok, stdout, err) =
        laparo(&["stereo", "rectify", "--calib", s(&calib), "--left", s(&ld), "--right", s(&rd), "--out", s(&out)]);
    assert!(ok, "{err}");
    assert!(stdout.contains("rectified 2 pair(s)"), "{stdout}");
    for name in ["f0.png", "f1.png"] {
        assert_eq!(
            std::fs::read(out.join("left").join(name)).unwrap(),
            std::fs::read(single.join("left_rectified.png")).unwrap()
        );
        assert_eq!(
            std::fs::read(out.join("right").join(name)).unwrap(),
            std::fs::read(single.join("right_rectified.png")).unwrap()
        );
    }
    assert!(out.join("left_valid.png").is_file() && out.join("calib_rectified.json").is_file());
    // A right folder without one of the frames names it; output into the input folder is refused.
    std::fs::remove_file(rd.join("f1.png")).unwrap();
    let (ok, _, err) =
        laparo(&["stereo", "rectify", "--calib", s(&calib), "--left", s(&ld), "--right", s(&rd), "--out", s(&out)]);
    assert!(!ok && err.contains("f1.png"), "{err}");
    laparo_core::io::write_png(rd.join("f1.png"), &r).unwrap();
    let (ok, _, err) =
        laparo(&["stereo", "rectify", "--calib", s(&calib), "--left", s(&ld), "--right", s(&rd), "--out", s(&ld)]);
    assert!(!ok && err.contains("would overwrite the input"), "{err}");
}

/// Issue 10: `cats stats --config-out` on one of its own inputs overwrote the calibration.
#[test]
fn cats_stats_refuses_to_overwrite_its_input() {
    let dir = tempfile::tempdir().unwrap();
    let (c, ..) = synthetic(0, 1280, 1024);
    let calib = dir.path().join("calib.yaml");
    c.write_opencv_yaml(&calib).unwrap();
    let before = std::fs::read(&calib).unwrap();
    let (ok, _, err) = laparo(&["cats", "stats", s(&calib), "--config-out", s(&calib)]);
    assert!(!ok && err.contains("calib.yaml") && err.contains("would overwrite the input"), "{err}");
    assert_eq!(std::fs::read(&calib).unwrap(), before);
    // --json=FILE writes the JSON there; a bare --json before a positional takes no value.
    let j = dir.path().join("stats.json");
    let (ok, stdout, err) = laparo(&["cats", "stats", &format!("--json={}", s(&j)), s(&calib)]);
    assert!(ok, "{err}");
    assert!(stdout.contains("Table 3.6"), "{stdout}");
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&j).unwrap()).unwrap();
    assert_eq!(v["files"].as_array().unwrap().len(), 1);
    let (ok, stdout, err) = laparo(&["cats", "stats", "--json", s(&calib)]);
    assert!(ok, "{err}");
    assert!(serde_json::from_str::<serde_json::Value>(&stdout).is_ok());
    assert_eq!(std::fs::read(&calib).unwrap(), before);
}
