//! Issue 10, "one reader per kind of input": every command that reads masks, intrinsics or
//! stereo calibrations accepts the same set of files (they all go through
//! `laparo_core::io::{read_mask, read_camera, read_stereo_calibration}`).
//!
//! Before the shared readers, a mask `.npy` worked in `depth eval-pair` and failed in `cpc warp`,
//! and a `{"K": ...}` camera JSON accepted by `depth reproject` was rejected by `cpc warp`.
use laparo_core::calib::StereoCalibration;
use laparo_core::{io, Image, Intrinsics};
use laparo_stereo::{default_camera, Scene};
use nalgebra::{Matrix3, Vector3};
use std::path::{Path, PathBuf};
mod common;
use common::laparo;

fn s(p: &Path) -> String {
    p.to_str().unwrap().to_string()
}

fn run(args: &[String]) -> (bool, String) {
    let a: Vec<&str> = args.iter().map(String::as_str).collect();
    let (ok, _, err) = laparo(&a);
    (ok, err)
}

/// The same mask (inside = all but a 2-px border) in every mask format.
fn masks(dir: &Path, w: usize, h: usize) -> Vec<PathBuf> {
    let inside = |x: usize, y: usize| x >= 2 && y >= 2 && x + 2 < w && y + 2 < h;
    let m: Image<bool> = Image::from_vec(w, h, 1, (0..w * h).map(|i| inside(i % w, i / w)).collect()).unwrap();
    let f = m.map(|b| if b { 1.0 } else { 0.0 });
    let u8m = m.map(|b| if b { 255u8 } else { 0 });
    let mut out = Vec::new();
    let p = dir.join("mask.png");
    io::write_mask_png(&p, &m).unwrap();
    out.push(p);
    let p = dir.join("mask.jpg");
    io::write_jpeg(&p, &u8m, 95).unwrap();
    out.push(p);
    let p = dir.join("mask.npy");
    io::write_npy_f64(&p, &f).unwrap();
    out.push(p);
    let p = dir.join("mask.npz");
    io::write_npz_f64(&p, &[("mask", &f)]).unwrap();
    out.push(p);
    let p = dir.join("mask.pfm");
    io::write_pfm(&p, &f.map(|v| v as f32)).unwrap();
    out.push(p);
    let p = dir.join("mask.tif");
    io::write_tiff_f32(&p, &f.map(|v| v as f32)).unwrap();
    out.push(p);
    let p = dir.join("mask.exr");
    io::write_exr(&p, &f).unwrap();
    out.push(p);
    out
}

/// The same pinhole camera in every intrinsics format.
fn intrinsics_files(dir: &Path, k: &Intrinsics) -> Vec<PathBuf> {
    let (w, h) = (k.width, k.height);
    let mut out = Vec::new();
    let mut put = |name: &str, text: String| {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        out.push(p);
    };
    put(
        "k_fields.json",
        format!(r#"{{"fx": {}, "fy": {}, "cx": {}, "cy": {}, "width": {w}, "height": {h}}}"#, k.fx, k.fy, k.cx, k.cy),
    );
    put(
        "k_matrix.json",
        format!(
            r#"{{"K": [[{}, 0, {}], [0, {}, {}], [0, 0, 1]], "width": {w}, "height": {h}}}"#,
            k.fx, k.cx, k.fy, k.cy
        ),
    );
    put(
        "k_strings_nosize.json",
        format!(
            r#"{{"fx": "{:e}", "fy": "{:e}", "cx": "{:e}", "cy": "{:e}", "k1": "0.0", "p1": "0"}}"#,
            k.fx, k.fy, k.cx, k.cy
        ),
    );
    put(
        "k_flat9.json",
        format!(r#"{{"K": [{}, 0, {}, 0, {}, {}, 0, 0, 1], "dist": [0, 0, 0, 0, 0]}}"#, k.fx, k.cx, k.fy, k.cy),
    );
    put(
        "camera_info.yaml",
        format!(
            "image_width: {w}\nimage_height: {h}\ncamera_name: cam\ncamera_matrix:\n  rows: 3\n  cols: 3\n  data: [{}, 0, {}, 0, {}, {}, 0, 0, 1]\n\
             distortion_model: plumb_bob\ndistortion_coefficients:\n  rows: 1\n  cols: 5\n  data: [0, 0, 0, 0, 0]\n",
            k.fx, k.cx, k.fy, k.cy
        ),
    );
    put("cameras.txt", format!("# COLMAP\n1 PINHOLE {w} {h} {} {} {} {}\n", k.fx, k.fy, k.cx + 0.5, k.cy + 0.5));
    out
}

/// The same rectified stereo rig (R = I, T = (−b, 0, 0) mm) in every calibration format; each
/// entry is the `--calib` argument (a pair is `LEFT,RIGHT`).
fn calibration_files(dir: &Path, k: &Intrinsics, b_mm: f64) -> Vec<String> {
    let (w, h) = (k.width, k.height);
    let c = StereoCalibration {
        width: w,
        height: h,
        left: *k,
        left_dist: Default::default(),
        right: *k,
        right_dist: Default::default(),
        r: Matrix3::identity(),
        t_mm: Vector3::new(-b_mm, 0.0, 0.0),
    };
    let mut out = Vec::new();
    let p = dir.join("calib.json");
    c.write_json(&p).unwrap();
    out.push(s(&p));
    let p = dir.join("calib.yaml");
    c.write_opencv_yaml(&p).unwrap();
    out.push(s(&p));
    let p = dir.join("camera_calibration.txt");
    let cam = |i: usize| {
        format!(
            "Camera-{i}-F: {} {}\nCamera-{i}-C: {} {}\nCamera-{i}-Alpha: 0\nCamera-{i}-K: 0 0 0 0 0\n",
            k.fx, k.fy, k.cx, k.cy
        )
    };
    std::fs::write(
        &p,
        format!("Width: {w}\nHeight: {h}\n{}{}Extrinsic-Omega: 0 0 0\nExtrinsic-T: {} 0 0\n", cam(0), cam(1), -b_mm),
    )
    .unwrap();
    out.push(s(&p));
    let p = dir.join("calib.txt");
    std::fs::write(
        &p,
        format!(
            "cam0=[{f} 0 {cx}; 0 {f} {cy}; 0 0 1]\ncam1=[{f} 0 {cx}; 0 {f} {cy}; 0 0 1]\ndoffs=0\nbaseline={b_mm}\nwidth={w}\nheight={h}\n",
            f = k.fx,
            cx = k.cx,
            cy = k.cy
        ),
    )
    .unwrap();
    out.push(s(&p));
    let ros = |name: &str, tx: f64| {
        let p = dir.join(name);
        std::fs::write(
            &p,
            format!(
                "image_width: {w}\nimage_height: {h}\ncamera_matrix:\n  rows: 3\n  cols: 3\n  data: [{f}, 0, {cx}, 0, {f}, {cy}, 0, 0, 1]\n\
                 distortion_model: plumb_bob\ndistortion_coefficients:\n  rows: 1\n  cols: 5\n  data: [0, 0, 0, 0, 0]\n\
                 rectification_matrix:\n  rows: 3\n  cols: 3\n  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]\n\
                 projection_matrix:\n  rows: 3\n  cols: 4\n  data: [{f}, 0, {cx}, {tx}, 0, {f}, {cy}, 0, 0, 0, 1, 0]\n",
                f = k.fx,
                cx = k.cx,
                cy = k.cy
            ),
        )
        .unwrap();
        s(&p)
    };
    // ROS: metres, Tx = −f·b.
    out.push(format!("{},{}", ros("left.yaml", 0.0), ros("right.yaml", -k.fx * b_mm / 1000.0)));
    out
}

#[test]
fn every_command_accepts_the_same_masks_intrinsics_and_calibrations() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let (w, h) = (64usize, 48usize);
    let k = default_camera(w, h);
    let b_mm = 5.0;
    let sample = Scene::default().stereo_sample(&k, b_mm, 1);
    io::write_png(d.join("left.png"), &sample.left).unwrap();
    io::write_png(d.join("right.png"), &sample.right).unwrap();
    let disp = sample.disp_left.clone().unwrap().map(|v| if v.is_finite() { v } else { 0.0 });
    io::write_pfm(d.join("disp.pfm"), &disp).unwrap();
    // Depth (mm) of the left view from its disparity: z = f b / d.
    let depth = disp.map(|v| if v > 0.0 { k.fx * b_mm / v as f64 } else { 0.0 });
    io::write_npy_f64(d.join("depth_mm.npy"), &depth).unwrap();
    std::fs::write(d.join("ext.json"), r#"{"R": [[1,0,0],[0,1,0],[0,0,1]], "t": [0, 0, 0], "unit": "mm"}"#).unwrap();

    let masks = masks(d, w, h);
    let cams = intrinsics_files(d, &k);
    let calibs = calibration_files(d, &k, b_mm);
    let mut failures = Vec::new();
    let mut check = |what: String, r: (bool, String)| {
        if !r.0 {
            failures.push(format!("{what}: {}", r.1.trim()));
        }
    };

    for (i, m) in masks.iter().enumerate() {
        check(
            format!("depth eval-pair --mask {}", m.display()),
            run(&[
                "depth".into(),
                "eval-pair".into(),
                "--pred".into(),
                s(&d.join("depth_mm.npy")),
                "--pred-kind".into(),
                "depth".into(),
                "--gt".into(),
                s(&d.join("depth_mm.npy")),
                "--gt-unit".into(),
                "mm".into(),
                "--mask".into(),
                s(m),
            ]),
        );
        check(
            format!("cpc lambda --mask {}", m.display()),
            run(&[
                "cpc".into(),
                "lambda".into(),
                "--depth".into(),
                s(&d.join("depth_mm.npy")),
                "--depth-unit".into(),
                "mm".into(),
                "--intrinsics".into(),
                s(&cams[0]),
                "--mask".into(),
                s(m),
                "--out".into(),
                s(&d.join(format!("lambda_m{i}"))),
            ]),
        );
        check(
            format!("depth reproject --tool-mask {}", m.display()),
            run(&[
                "depth".into(),
                "reproject".into(),
                "--depth".into(),
                s(&d.join("depth_mm.npy")),
                "--sensor-intrinsics".into(),
                s(&cams[0]),
                "--extrinsics".into(),
                s(&d.join("ext.json")),
                "--intrinsics".into(),
                s(&cams[0]),
                "--tool-mask".into(),
                s(m),
                "--min-depth-m".into(),
                "0.001".into(),
                "--max-depth-m".into(),
                "10".into(),
                "--out".into(),
                s(&d.join(format!("rep_m{i}.npy"))),
            ]),
        );
        check(
            format!("stereo eval --mask {}", m.display()),
            run(&[
                "stereo".into(),
                "eval".into(),
                "--pred".into(),
                s(&d.join("disp.pfm")),
                "--gt".into(),
                s(&d.join("disp.pfm")),
                "--calib".into(),
                calibs[0].clone(),
                "--mask".into(),
                s(m),
                "--out".into(),
                s(&d.join(format!("seval_m{i}"))),
            ]),
        );
    }
    for (i, c) in cams.iter().enumerate() {
        check(
            format!("cpc warp --intrinsics {}", c.display()),
            run(&[
                "cpc".into(),
                "warp".into(),
                "--image".into(),
                s(&d.join("left.png")),
                "--depth".into(),
                s(&d.join("depth_mm.npy")),
                "--depth-unit".into(),
                "mm".into(),
                "--intrinsics".into(),
                s(c),
                "--mask".into(),
                s(&masks[2]),
                "--lambda".into(),
                "0.9".into(),
                "--grid-step".into(),
                "4".into(),
                "--out".into(),
                s(&d.join(format!("warp_k{i}"))),
            ]),
        );
        check(
            format!("depth reproject --intrinsics {}", c.display()),
            run(&[
                "depth".into(),
                "reproject".into(),
                "--depth".into(),
                s(&d.join("depth_mm.npy")),
                "--sensor-intrinsics".into(),
                s(c),
                "--extrinsics".into(),
                s(&d.join("ext.json")),
                "--intrinsics".into(),
                s(c),
                "--width".into(),
                w.to_string(),
                "--height".into(),
                h.to_string(),
                "--min-depth-m".into(),
                "0.001".into(),
                "--max-depth-m".into(),
                "10".into(),
                "--out".into(),
                s(&d.join(format!("rep_k{i}.npy"))),
            ]),
        );
    }
    for (i, c) in calibs.iter().enumerate() {
        let out = |n: &str| s(&d.join(format!("{n}_c{i}")));
        check(
            format!("stereo rectify --calib {c}"),
            run(&[
                "stereo".into(),
                "rectify".into(),
                "--calib".into(),
                c.clone(),
                "--left".into(),
                s(&d.join("left.png")),
                "--right".into(),
                s(&d.join("right.png")),
                "--out".into(),
                out("rect"),
            ]),
        );
        check(
            format!("stereo disp2depth --calib {c}"),
            run(&[
                "stereo".into(),
                "disp2depth".into(),
                "--disp".into(),
                s(&d.join("disp.pfm")),
                "--calib".into(),
                c.clone(),
                "--out".into(),
                format!("{}.npy", out("d2d")),
            ]),
        );
        check(format!("cats stats {c}"), run(&["cats".into(), "stats".into(), c.clone()]));
    }
    assert!(failures.is_empty(), "{} failures:\n{}", failures.len(), failures.join("\n"));
}

/// The P2ILF camera file (numeric strings, k1..k3 distortion): `depth reproject` applies its
/// distortion; `cpc warp`, a pinhole computation, undistorts image, depth and mask first (before
/// issue 10's fix it refused the file), and its undistorted image matches the pinhole image the
/// distorted one was made from.
#[test]
fn p2ilf_camera_file_is_read_and_its_distortion_never_ignored() {
    let p2ilf = Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../../shared/data/meshes/p2ilf/acquisition-camera-metadata.json"
    ));
    if !p2ilf.exists() {
        eprintln!("SKIP p2ilf_camera_file_is_read_and_its_distortion_never_ignored: {} absent", p2ilf.display());
        return;
    }
    let cam = io::read_camera(p2ilf).unwrap();
    assert_eq!(cam.size, Some((1920, 1080)));
    assert_eq!(
        (cam.fx, cam.cx, cam.cy),
        (
            "9.5206967601396957e+02".parse().unwrap(),
            "8.8447392341747241e+02".parse().unwrap(),
            "5.5368748726315528e+02".parse().unwrap()
        )
    );
    assert_eq!(
        (cam.distortion.k1, cam.distortion.k2, cam.distortion.k3),
        (-2.3184898303739043e-01, 3.4051349187505525e-01, -2.3860036358921605e-01)
    );
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    // A fronto-parallel plane at 100 mm seen by the P2ILF camera (sensor = laparoscope, T = I).
    let (w, h) = (1920usize, 1080usize);
    io::write_npy_f64(d.join("plane.npy"), &Image::filled(w, h, 1, 100.0)).unwrap();
    io::write_png(d.join("plane.png"), &Image::filled(w, h, 1, 128u8)).unwrap();
    std::fs::write(d.join("ext.json"), r#"{"R": [[1,0,0],[0,1,0],[0,0,1]], "t": [0, 0, 0], "unit": "mm"}"#).unwrap();
    let sensor = d.join("pinhole.json");
    std::fs::write(
        &sensor,
        format!(
            r#"{{"fx": {}, "fy": {}, "cx": {}, "cy": {}, "width": {w}, "height": {h}}}"#,
            cam.fx, cam.fy, cam.cx, cam.cy
        ),
    )
    .unwrap();
    let (ok, err) = run(&[
        "depth".into(),
        "reproject".into(),
        "--depth".into(),
        s(&d.join("plane.npy")),
        "--sensor-intrinsics".into(),
        s(&sensor),
        "--extrinsics".into(),
        s(&d.join("ext.json")),
        "--intrinsics".into(),
        s(p2ilf),
        "--out".into(),
        s(&d.join("out.npy")),
    ]);
    assert!(ok, "depth reproject with the P2ILF camera: {err}");
    let out = io::read_float_map(d.join("out.npy")).unwrap();
    assert_eq!(out.size(), (w, h));
    // Barrel distortion (k1 < 0) pulls the image corners inwards: the distorted corner pixel sees
    // a ray outside the undistorted field of view, so it has no depth, while the centre has 100 mm.
    let c = out.data[(h / 2) * w + w / 2];
    assert!((c - 100.0).abs() < 1e-6, "centre {c}");
    // The distorted image of a pinhole image f(u, v) = a smooth ramp: pixel p of the distorted
    // image shows f at the ideal position undistort(p).
    let k = cam.intrinsics(Some((w, h))).unwrap();
    let f = |u: f64, v: f64| 40.0 + 150.0 * (u / w as f64) + 50.0 * (v / h as f64);
    let distorted: Vec<u8> = (0..w * h)
        .map(|i| {
            // (the iterative undistortion does not converge in the far corners of this lens;
            // those pixels stay black and are outside the checked region)
            match cam.distortion.undistort_pixel(&k, (i % w) as f64, (i / w) as f64) {
                Some((u, v)) => f(u, v).round() as u8,
                None => 0,
            }
        })
        .collect();
    io::write_png(d.join("ramp.png"), &Image::from_vec(w, h, 1, distorted).unwrap()).unwrap();
    let (ok, err) = run(&[
        "cpc".into(),
        "warp".into(),
        "--image".into(),
        s(&d.join("ramp.png")),
        "--depth".into(),
        s(&d.join("plane.npy")),
        "--intrinsics".into(),
        s(p2ilf),
        "--grid-step".into(),
        "16".into(),
        "--out".into(),
        s(&d.join("warp")),
    ]);
    assert!(ok, "cpc warp with the P2ILF camera: {err}");
    let und = io::read_image(d.join("warp/undistorted.png")).unwrap();
    assert_eq!((und.width, und.height), (w, h));
    let mut worst = 0.0f64;
    for y in (h / 8..7 * h / 8).step_by(7) {
        for x in (w / 8..7 * w / 8).step_by(7) {
            worst = worst.max((und.data[(y * w + x) * und.channels] as f64 - f(x as f64, y as f64)).abs());
        }
    }
    // Two roundings to 8 bits and one bilinear interpolation of a ramp: within 1.5 grey levels.
    assert!(worst <= 1.5, "undistorted image differs from the pinhole image by {worst} grey levels");
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("warp/stats.json")).unwrap()).unwrap();
    assert_eq!(stats["undistorted"]["distortion_opencv"][0].as_f64().unwrap(), cam.distortion.k1);
}

/// Reproducers of the malformed-input campaign (issue 10) through the CLI: each must exit
/// non-zero with an error naming the file or flag (before: stack overflow abort, 80 GB allocation
/// abort, a minute of header parsing, a 7-minute distortion scan, an i64::MAX panic, exit 0 on a
/// truncated JPEG mask).
#[test]
fn malformed_inputs_fail_cleanly_through_the_cli() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let (w, h) = (32usize, 24usize);
    let k = default_camera(w, h);
    io::write_npy_f64(d.join("depth.npy"), &Image::filled(w, h, 1, 100.0)).unwrap();
    io::write_png(d.join("img.png"), &Image::filled(w, h, 1, 100u8)).unwrap();
    let cams = intrinsics_files(d, &k);
    let scared = "%YAML:1.0\nM1: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 1000., 0., 600., 0., 1000., 500., 0., 0., 1. ]\n\
D1: [ 0., 0., 0., 0., 0. ]\nM2: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 1000., 0., 610., 0., 1000., 500., 0., 0., 1. ]\n\
D2: [ 0., 0., 0., 0., 0. ]\nR: [ 1., 0., 0., 0., 1., 0., 0., 0., 1. ]\nT: [ -5., 0., 0. ]\n";
    std::fs::write(d.join("scared.yaml"), scared).unwrap();
    // cats stats angles need no image size.
    let (ok, _, err) = laparo(&["cats", "stats", &s(&d.join("scared.yaml"))]);
    assert!(ok, "cats stats without a size: {err}");
    assert!(err.contains("nominal"), "{err}");
    let (ok, _, err) =
        laparo(&["cats", "stats", &s(&d.join("scared.yaml")), "--width", "9223372036854775807", "--height", "1"]);
    assert!(!ok && err.contains("out of range"), "{err}");
    let (ok, _, err) =
        laparo(&["cats", "stats", &s(&d.join("scared.yaml")), "--width", "100000", "--height", "100000"]);
    assert!(!ok && err.contains("out of range"), "{err}");
    std::fs::write(d.join("deep.yaml"), format!("%YAML:1.0\nM1: {}1{}\n", "[".repeat(30_000), "]".repeat(30_000)))
        .unwrap();
    let (ok, _, err) = laparo(&["cats", "stats", &s(&d.join("deep.yaml"))]);
    assert!(!ok && err.contains("deep.yaml") && err.contains("nested"), "{err}");
    // depth reproject: bounded --width/--height and JSON sizes.
    std::fs::write(d.join("ext.json"), r#"{"R": [[1,0,0],[0,1,0],[0,0,1]], "t": [0, 0, 0]}"#).unwrap();
    let rep = |intr: &Path, extra: &[&str]| {
        let mut a = vec![
            "depth".to_string(),
            "reproject".into(),
            "--depth".into(),
            s(&d.join("depth.npy")),
            "--sensor-intrinsics".into(),
            s(&cams[0]),
            "--extrinsics".into(),
            s(&d.join("ext.json")),
            "--intrinsics".into(),
            s(intr),
            "--out".into(),
            s(&d.join("o.npy")),
        ];
        a.extend(extra.iter().map(|x| x.to_string()));
        run(&a)
    };
    let (ok, err) = rep(&cams[0], &["--width", "100000", "--height", "100000"]);
    assert!(!ok && err.contains("--width/--height") && err.contains("out of range"), "{err}");
    std::fs::write(
        d.join("huge.json"),
        r#"{"fx": 1, "fy": 1, "cx": 0, "cy": 0, "width": 9223372036854775807, "height": 1}"#,
    )
    .unwrap();
    let (ok, err) = rep(&d.join("huge.json"), &[]);
    assert!(!ok && err.contains("huge.json"), "{err}");
    std::fs::write(d.join("badk.json"), r#"{"K": [[500, 0, 16], [0, 500, 12], [0, 1, 1]]}"#).unwrap();
    let (ok, err) = rep(&d.join("badk.json"), &["--width", "32", "--height", "24"]);
    assert!(!ok && err.contains("badk.json") && err.contains("[0, 0, 1]"), "{err}");
    // A 160-byte .npy announcing 100000 x 100000 float64.
    let mut hdr = "{'descr': '<f8', 'fortran_order': False, 'shape': (0x186a0, 100_000), }".to_string();
    while !(10 + hdr.len() + 1).is_multiple_of(64) {
        hdr.push(' ');
    }
    hdr.push('\n');
    let mut f = b"\x93NUMPY\x01\x00".to_vec();
    f.extend_from_slice(&(hdr.len() as u16).to_le_bytes());
    f.extend_from_slice(hdr.as_bytes());
    f.extend_from_slice(&[0u8; 16]);
    std::fs::write(d.join("evil.npy"), &f).unwrap();
    let (ok, _, err) =
        laparo(&["depth", "eval-pair", "--pred", &s(&d.join("evil.npy")), "--gt", &s(&d.join("depth.npy"))]);
    assert!(!ok && err.contains("evil.npy"), "{err}");
    // A truncated JPEG mask.
    let m = Image::from_vec(w, h, 1, (0..w * h).map(|i| if i % 7 < 4 { 255u8 } else { 0 }).collect()).unwrap();
    io::write_jpeg(d.join("m.jpg"), &m, 90).unwrap();
    let bytes = std::fs::read(d.join("m.jpg")).unwrap();
    std::fs::write(d.join("cut.jpg"), &bytes[..bytes.len() * 2 / 3]).unwrap();
    let (ok, _, err) = laparo(&[
        "cpc",
        "warp",
        "--image",
        &s(&d.join("img.png")),
        "--depth",
        &s(&d.join("depth.npy")),
        "--intrinsics",
        &s(&cams[0]),
        "--mask",
        &s(&d.join("cut.jpg")),
        "--out",
        &s(&d.join("w")),
    ]);
    assert!(!ok && err.contains("cut.jpg") && err.contains("truncated"), "{err}");
}
