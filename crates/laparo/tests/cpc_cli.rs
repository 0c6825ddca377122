//! End-to-end test of `laparo cpc scene | warp | lambda` and of its error handling.
use std::path::Path;
mod common;
use common::laparo;

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn cpc_scene_warp_lambda_end_to_end() {
    let tmp = tempfile::tempdir().unwrap();
    let sc = tmp.path().join("scene");
    let (ok, _, err) = laparo(&[
        "cpc",
        "scene",
        "--surface",
        "bumpy",
        "--texture",
        "procedural",
        "--tilt",
        "50",
        "--width",
        "200",
        "--height",
        "150",
        "--out",
        s(&sc),
    ]);
    assert!(ok, "scene: {err}");
    for f in ["image.png", "depth.npy", "mask.png", "intrinsics.json", "pose.json", "surface_xy.npy"] {
        assert!(sc.join(f).exists(), "{f}");
    }
    let out = tmp.path().join("warp");
    let common = |extra: &[&str], out: &Path| {
        let mut a = vec![
            "cpc",
            "warp",
            "--image",
            s(&sc.join("image.png")).to_string().leak(),
            "--depth",
            s(&sc.join("depth.npy")).to_string().leak(),
            "--depth-unit",
            "mm",
            "--intrinsics",
            s(&sc.join("intrinsics.json")).to_string().leak(),
            "--mask",
            s(&sc.join("mask.png")).to_string().leak(),
            "--out",
            s(out).to_string().leak(),
        ];
        a.extend_from_slice(extra);
        laparo(&a)
    };
    let (ok, stdout, err) = common(&["--lambda", "0.9", "--grid-step", "4"], &out);
    assert!(ok, "warp: {err}");
    assert!(stdout.contains("λ = 0.9000"), "{stdout}");
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("stats.json")).unwrap()).unwrap();
    for key in [
        "lambda",
        "n_vertices",
        "n_triangles",
        "angle_error_deg_before",
        "angle_error_deg_after",
        "delta_area",
        "n_flipped",
        "timings_ms",
    ] {
        assert!(stats.get(key).is_some(), "stats.json lacks {key}");
    }
    assert_eq!(stats["lambda"].as_f64().unwrap(), 0.9);
    assert!(stats["angle_error_deg_after"].as_f64().unwrap() < stats["angle_error_deg_before"].as_f64().unwrap());
    for stage in ["mesh", "assemble", "solve", "warp"] {
        assert!(stats["timings_ms"][stage].as_f64().is_some(), "timing {stage}");
    }
    let warped = laparo_core::io::read_image(out.join("warped.png")).unwrap();
    let mask = laparo_core::io::read_image(out.join("mask.png")).unwrap();
    assert_eq!(
        (warped.width, warped.height),
        (stats["canvas_width"].as_u64().unwrap() as usize, stats["canvas_height"].as_u64().unwrap() as usize)
    );
    assert_eq!((mask.width, mask.height), (warped.width, warped.height));
    let back = laparo_core::io::read_npy(out.join("map_backward.npy")).unwrap();
    let fwd = laparo_core::io::read_npy(out.join("map_forward.npy")).unwrap();
    assert_eq!((back.width, back.height, back.channels), (warped.width, warped.height, 2));
    assert_eq!((fwd.width, fwd.height, fwd.channels), (200, 150, 2));
    // The maps are mutually consistent: forward(backward(q)) ≈ q at valid warped pixels (bilinear on a 1-px grid).
    let mut n = 0;
    for y in (0..back.height).step_by(7) {
        for x in (0..back.width).step_by(7) {
            let (u, v) = (back.get(x, y, 0), back.get(x, y, 1));
            if !u.is_finite() || mask.get(x, y, 0) == 0 {
                continue;
            }
            let (ui, vi) = (u.round() as usize, v.round() as usize);
            let (fx, fy) = (fwd.get(ui, vi, 0), fwd.get(ui, vi, 1));
            if fx.is_finite() {
                assert!(
                    (fx - x as f64).abs() < 3.0 && (fy - y as f64).abs() < 3.0,
                    "({x},{y}) -> ({u},{v}) -> ({fx},{fy})"
                );
                n += 1;
            }
        }
    }
    assert!(n > 50);
    // Automatic λ writes the sweep.
    let out2 = tmp.path().join("auto");
    let (ok, _, err) = common(&["--auto-lambda"], &out2);
    assert!(ok, "auto: {err}");
    assert!(out2.join("lambda_sweep.csv").exists() && out2.join("lambda_sweep.png").exists());
    let out3 = tmp.path().join("lambda");
    let (ok, stdout, err) = laparo(&[
        "cpc",
        "lambda",
        "--depth",
        s(&sc.join("depth.npy")),
        "--intrinsics",
        s(&sc.join("intrinsics.json")),
        "--mask",
        s(&sc.join("mask.png")),
        "--out",
        s(&out3),
    ]);
    assert!(ok, "lambda: {err}");
    assert!(stdout.contains("ℓ ="));
    let csv = std::fs::read_to_string(out3.join("lambda_sweep.csv")).unwrap();
    assert!(csv.starts_with("lambda,delta_area,delta_area_norm,fit,angle_error_deg,n_flipped"));
    assert!(csv.lines().count() > 10);
    // δ_area is normalised by its value at the largest λ of the sweep, so that f(1) = 1 (eq. 4.16).
    let rows: Vec<Vec<f64>> =
        csv.lines().skip(1).map(|l| l.split(',').map(|v| v.parse::<f64>().unwrap()).collect()).collect();
    let last = rows.iter().max_by(|a, b| a[0].total_cmp(&b[0])).unwrap().clone();
    for r in &rows {
        assert!((r[2] - r[1] / last[1]).abs() < 1e-12, "row {r:?}: norm {} vs {}", r[2], r[1] / last[1]);
    }

    // Bad inputs: clear errors, non-zero exit.
    let (ok, _, err) = common(&["--lambda", "1.0"], &tmp.path().join("bad1"));
    assert!(!ok && err.contains("lambda"), "{err}");
    let (ok, _, err) = laparo(&[
        "cpc",
        "warp",
        "--image",
        s(&sc.join("image.png")),
        "--depth",
        s(&tmp.path().join("missing.npy")),
        "--intrinsics",
        s(&sc.join("intrinsics.json")),
        "--out",
        s(&tmp.path().join("bad2")),
    ]);
    assert!(!ok && err.contains("missing.npy"), "{err}");
    let bad_k = tmp.path().join("k.json");
    std::fs::write(&bad_k, r#"{"fx": 0.0, "fy": 100.0, "cx": 100.0, "cy": 75.0, "width": 200, "height": 150}"#)
        .unwrap();
    let (ok, _, err) = laparo(&[
        "cpc",
        "warp",
        "--image",
        s(&sc.join("image.png")),
        "--depth",
        s(&sc.join("depth.npy")),
        "--intrinsics",
        s(&bad_k),
        "--out",
        s(&tmp.path().join("bad3")),
    ]);
    assert!(!ok && err.contains("focal"), "{err}");
    assert!(!tmp.path().join("bad1").join("stats.json").exists());
}

/// Issue 10: `cpc warp --out <input folder>` overwrote the input mask; a depth prediction at
/// network resolution was rejected; frames had to be warped one process at a time.
#[test]
fn cpc_warp_guards_inputs_resizes_depth_and_takes_folders() {
    let tmp = tempfile::tempdir().unwrap();
    let sc = tmp.path().join("scene");
    let (ok, _, err) = laparo(&[
        "cpc",
        "scene",
        "--surface",
        "bumpy",
        "--texture",
        "procedural",
        "--width",
        "120",
        "--height",
        "90",
        "--out",
        s(&sc),
    ]);
    assert!(ok, "scene: {err}");
    let mask_before = std::fs::read(sc.join("mask.png")).unwrap();
    let warp = |image: &Path, depth: &Path, out: &Path, extra: &[&str]| {
        let mut a = vec![
            "cpc".to_string(),
            "warp".into(),
            "--image".into(),
            s(image).into(),
            "--depth".into(),
            s(depth).into(),
            "--intrinsics".into(),
            s(&sc.join("intrinsics.json")).into(),
            "--mask".into(),
            s(&sc.join("mask.png")).into(),
            "--lambda".into(),
            "0.9".into(),
            "--out".into(),
            s(out).into(),
        ];
        a.extend(extra.iter().map(|x| x.to_string()));
        laparo(&a.iter().map(|x| x.as_str()).collect::<Vec<_>>())
    };
    // Output into the scene folder would replace the input mask.png: refused, mask intact.
    let (ok, _, err) = warp(&sc.join("image.png"), &sc.join("depth.npy"), &sc, &[]);
    assert!(!ok && err.contains("mask.png") && err.contains("would overwrite the input"), "{err}");
    assert_eq!(std::fs::read(sc.join("mask.png")).unwrap(), mask_before);

    // Depth at half resolution (2x2 block means): rejected with a hint, accepted with --resize-depth.
    let d = laparo_core::io::read_npy(sc.join("depth.npy")).unwrap();
    let (hw, hh) = (d.width / 2, d.height / 2);
    let mut half = Vec::with_capacity(hw * hh);
    for y in 0..hh {
        for x in 0..hw {
            let v = [(0, 0), (1, 0), (0, 1), (1, 1)].iter().map(|(i, j)| d.get(2 * x + i, 2 * y + j, 0)).sum::<f64>();
            half.push(v / 4.0);
        }
    }
    let hp = tmp.path().join("half.npy");
    laparo_core::io::write_npy_f64(&hp, &laparo_core::Image::from_vec(hw, hh, 1, half).unwrap()).unwrap();
    let (ok, _, err) = warp(&sc.join("image.png"), &hp, &tmp.path().join("h0"), &[]);
    assert!(!ok && err.contains("--resize-depth"), "{err}");
    let (ok, stdout, err) = warp(&sc.join("image.png"), &hp, &tmp.path().join("h1"), &["--resize-depth", "bilinear"]);
    assert!(ok, "{err}");
    assert!(stdout.contains("λ = 0.9000"), "{stdout}");
    let (ok, _, err) = warp(&sc.join("image.png"), &hp, &tmp.path().join("h2"), &["--resize-pred", "nearest"]);
    assert!(ok, "{err}");

    // Batch: folders of frames; each frame's output equals a single-frame run.
    let (imgs, depths) = (tmp.path().join("frames"), tmp.path().join("depths"));
    std::fs::create_dir_all(&imgs).unwrap();
    std::fs::create_dir_all(&depths).unwrap();
    for n in ["a", "b"] {
        std::fs::copy(sc.join("image.png"), imgs.join(format!("{n}.png"))).unwrap();
        std::fs::copy(sc.join("depth.npy"), depths.join(format!("{n}.npy"))).unwrap();
    }
    let single = tmp.path().join("single");
    let (ok, _, err) = warp(&sc.join("image.png"), &sc.join("depth.npy"), &single, &[]);
    assert!(ok, "{err}");
    let batch = tmp.path().join("batch");
    let (ok, stdout, err) = warp(&imgs, &depths, &batch, &[]);
    assert!(ok, "{err}");
    assert!(stdout.contains("2 of 2 frames"), "{stdout}");
    for n in ["a", "b"] {
        assert_eq!(
            std::fs::read(batch.join(n).join("warped.png")).unwrap(),
            std::fs::read(single.join("warped.png")).unwrap()
        );
    }
    std::fs::remove_file(depths.join("b.npy")).unwrap();
    let (ok, _, err) = warp(&imgs, &depths, &tmp.path().join("batch2"), &[]);
    assert!(!ok && err.contains("'b.*'"), "{err}");
}
