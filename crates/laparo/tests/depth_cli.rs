//! `laparo depth ...` through the binary: eval-pair output, the manifest workflow, an end-to-end
//! evaluation, and bad inputs (clear error naming the file, non-zero exit, no panic, no
//! complete-looking output).
use laparo_core::image::Image;
use laparo_core::io::{write_npy_f64, write_png};
use std::path::{Path, PathBuf};
mod common;
use common::run;
use std::process::Output;

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Fails with a clear message: non-zero exit, no panic, stderr mentions every `needles`.
fn assert_clean_failure(o: &Output, needles: &[&str]) {
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "expected failure, stderr: {err}");
    assert_eq!(o.status.code(), Some(1), "stderr: {err}");
    assert!(!err.contains("panicked"), "panic: {err}");
    for n in needles {
        assert!(err.contains(n), "stderr does not mention '{n}': {err}");
    }
}

const W: usize = 24;
const H: usize = 16;

/// GT depth (m): a slanted plane 5–15 cm with a hole.
fn gt_m() -> Vec<f64> {
    let mut z = Vec::with_capacity(W * H);
    for y in 0..H {
        for x in 0..W {
            let v = 0.05 + 0.1 * (x as f64 / W as f64) + 0.02 * (y as f64 / H as f64);
            z.push(if x < 2 && y < 2 { 0.0 } else { v });
        }
    }
    z
}

fn img(v: Vec<f64>) -> Image<f64> {
    Image::from_vec(W, H, 1, v).unwrap()
}

/// A disparity prediction `k / z` perturbed by a deterministic pattern of amplitude `noise`.
fn disparity(k: f64, noise: f64) -> Vec<f64> {
    gt_m()
        .iter()
        .enumerate()
        .map(|(i, z)| {
            let e = 1.0 + noise * (((i * 7919) % 13) as f64 / 6.0 - 1.0);
            if *z > 0.0 {
                k / z * e
            } else {
                1.0
            }
        })
        .collect()
}

#[test]
fn eval_pair_prints_the_reference_keys() {
    let d = tempfile::tempdir().unwrap();
    let (p, g) = (d.path().join("pred.npy"), d.path().join("gt.npy"));
    write_npy_f64(&p, &img(disparity(3.0, 0.0))).unwrap();
    // GT in mm.
    write_npy_f64(&g, &img(gt_m().iter().map(|v| v * 1000.0).collect())).unwrap();
    let o = run(&["depth", "eval-pair", "--pred", s(&p), "--gt", s(&g), "--gt-unit", "mm", "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["n_valid"], W * H - 4);
    for a in ["none", "scale", "scale_shift"] {
        for k in [
            "abs_rel",
            "sq_rel",
            "rmse",
            "rmse_log",
            "silog",
            "delta_0.25",
            "delta_0.5",
            "delta_1",
            "delta_2",
            "delta_3",
            "scale",
            "shift",
        ] {
            assert!(v[a][k].is_number(), "{a}.{k} missing: {v}");
        }
    }
    // Exact up to scale 3: s-alignment finds s = 1/3 and zero error.
    assert!((v["scale"]["scale"].as_f64().unwrap() - 1.0 / 3.0).abs() < 1e-12);
    assert!(v["scale"]["abs_rel"].as_f64().unwrap() < 1e-12);
    assert_eq!(v["scale_shift"]["delta_0.25"].as_f64().unwrap(), 1.0);
    // Without alignment, d = 3/z -> z/3 (all in 1.7–5.7 cm): Abs Rel = 2/3 exactly.
    assert!((v["none"]["abs_rel"].as_f64().unwrap() - 2.0 / 3.0).abs() < 1e-12);
}

#[test]
fn eval_pair_bad_inputs_fail_cleanly() {
    let d = tempfile::tempdir().unwrap();
    let dir = d.path();
    let g = dir.join("gt.npy");
    write_npy_f64(&g, &img(gt_m())).unwrap();
    let pair = |pred: &Path, extra: &[&str]| {
        let mut a = vec!["depth", "eval-pair", "--pred", s(pred), "--gt", s(&g), "--json"];
        a.extend_from_slice(extra);
        run(&a)
    };
    // Size mismatch.
    let small = dir.join("small.npy");
    write_npy_f64(&small, &Image::from_vec(5, 4, 1, vec![1.0; 20]).unwrap()).unwrap();
    let o = pair(&small, &[]);
    assert_clean_failure(&o, &["small.npy", "size mismatch"]);
    assert!(o.stdout.is_empty());
    // Missing file.
    assert_clean_failure(&pair(&dir.join("nope.npy"), &[]), &["nope.npy"]);
    // Truncated file.
    let good = dir.join("good.npy");
    write_npy_f64(&good, &img(disparity(1.0, 0.1))).unwrap();
    let bytes = std::fs::read(&good).unwrap();
    let trunc = dir.join("trunc.npy");
    std::fs::write(&trunc, &bytes[..bytes.len() / 2]).unwrap();
    assert_clean_failure(&pair(&trunc, &[]), &["trunc.npy"]);
    // Not a float map at all.
    let junk = dir.join("junk.npy");
    std::fs::write(&junk, b"this is not numpy").unwrap();
    assert_clean_failure(&pair(&junk, &[]), &["junk.npy"]);
    // NaN-only prediction.
    let nan = dir.join("nan.npy");
    write_npy_f64(&nan, &img(vec![f64::NAN; W * H])).unwrap();
    assert_clean_failure(&pair(&nan, &[]), &["nan.npy", "no valid value"]);
    // All-invalid mask.
    let mask = dir.join("mask.png");
    write_png(&mask, &Image::from_vec(W, H, 1, vec![0u8; W * H]).unwrap()).unwrap();
    assert_clean_failure(&pair(&good, &["--mask", s(&mask)]), &["mask.png", "no pixel"]);
    // Mask of the wrong size.
    let mask2 = dir.join("mask_small.png");
    write_png(&mask2, &Image::from_vec(3, 3, 1, vec![255u8; 9]).unwrap()).unwrap();
    assert_clean_failure(&pair(&good, &["--mask", s(&mask2)]), &["mask_small.png", "size mismatch"]);
    // GT without any valid pixel.
    let g0 = dir.join("gt0.npy");
    write_npy_f64(&g0, &img(vec![0.0; W * H])).unwrap();
    let o = run(&["depth", "eval-pair", "--pred", s(&good), "--gt", s(&g0)]);
    assert_clean_failure(&o, &["gt0.npy", "no valid pixel"]);
    // Bad parameter.
    let o = run(&["depth", "eval-pair", "--pred", s(&good), "--gt", s(&g), "--depth-min", "1", "--depth-max", "0.5"]);
    assert_clean_failure(&o, &["depth range"]);
}

/// A dataset in the scaffold layout: 2 scenes x (smoke 0..2, dark 0..1), 2 frames per level,
/// methods "good" (mild noise growing with severity) and "base" (stronger noise), both disparity.
fn dataset(root: &Path) {
    let rgb = Image::from_vec(W, H, 3, vec![128u8; W * H * 3]).unwrap();
    for scene in ["kidney", "liver"] {
        for (pert, levels) in [("smoke", 3u32), ("dark", 2)] {
            for lv in 0..levels {
                let level = format!("s{lv}");
                let base = root.join(scene).join(pert).join(&level);
                for f in 0..2 {
                    let name = format!("{f:04}");
                    write_png(base.join("rgb").join(format!("{name}.png")), &rgb).unwrap();
                    write_npy_f64(base.join("depth").join(format!("{name}.npy")), &img(gt_m())).unwrap();
                    for (m, k) in [("good", 0.02), ("base", 0.06)] {
                        let p = root.join("predictions").join(m).join(scene).join(pert).join(&level);
                        let noise = k * (1.0 + lv as f64) + 0.01 * f as f64;
                        write_npy_f64(p.join(format!("{name}.npy")), &img(disparity(2.0, noise))).unwrap();
                    }
                }
            }
        }
    }
}

fn read_json(p: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
}

#[test]
fn scaffold_validate_and_evaluate() {
    let d = tempfile::tempdir().unwrap();
    let root = d.path().join("data");
    dataset(&root);
    let man = root.join("manifest.toml");
    let o = run(&["depth", "manifest", "scaffold", "--root", s(&root), "--gt-unit", "m"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = run(&["depth", "manifest", "validate", s(&man), "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let rep: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(rep["n_frames"], 2 * (3 + 2) * 2);
    assert_eq!(rep["n_methods"], 2);
    assert_eq!(rep["problems"].as_array().unwrap().len(), 0);

    let out = d.path().join("out");
    let o = run(&[
        "depth",
        "eval",
        "--manifest",
        s(&man),
        "--alignment",
        "all",
        "--baseline",
        "base",
        "--out",
        s(&out),
        "--error-maps",
        "liver/dark/s1/0000",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("s&t-alignment") && stdout.contains("good"), "{stdout}");
    let r = read_json(&out.join("results.json"));
    assert_eq!(r["complete"], true);
    assert_eq!(r["n_images"], 20 * 2);
    let st = r["summary"]["alignments"].as_array().unwrap().iter().find(|a| a["alignment"] == "scale_shift").unwrap();
    let rob = st["robustness"].as_array().unwrap();
    let base = rob.iter().find(|m| m["method"] == "base").unwrap();
    let good = rob.iter().find(|m| m["method"] == "good").unwrap();
    // The baseline against itself: mCE = 1 (eq. 3.3); the better method is below 1.
    assert!((base["mce"]["abs_rel"].as_f64().unwrap() - 1.0).abs() < 1e-12);
    assert!(good["mce"]["abs_rel"].as_f64().unwrap() < 1.0);
    // 2 scenes x 2 perturbations = 4 cells; degradation with severity -> RR < 1.
    assert_eq!(good["cells"].as_array().unwrap().len(), 4);
    assert!(good["mrr"]["abs_rel"].as_f64().unwrap() < 1.0);
    // Per-image CSV: header + 20 frames x 2 methods x 3 alignments.
    let csv = std::fs::read_to_string(out.join("per_image.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 20 * 2 * 3);
    let md = std::fs::read_to_string(out.join("tables.md")).unwrap();
    assert!(md.contains("Table 3.5") && md.contains("Smoke") && md.contains("| s2 |"), "{md}");
    for f in figures(&out) {
        assert!(f.exists(), "missing figure {}", f.display());
    }
    // Same inputs, same outputs (deterministic ordering despite rayon).
    let out2 = d.path().join("out2");
    let o = run(&["depth", "eval", "--manifest", s(&man), "--baseline", "base", "--out", s(&out2), "--no-figures"]);
    assert!(o.status.success());
    assert_eq!(csv, std::fs::read_to_string(out2.join("per_image.csv")).unwrap());
}

fn figures(out: &Path) -> Vec<PathBuf> {
    let mut v = vec![out.join("error_maps").join("grid_scale_shift.png")];
    for m in ["good", "base"] {
        v.push(out.join("radar").join(format!("{m}_scale_shift.png")));
        v.push(out.join("radar").join(format!("{m}_scale_shift.svg")));
        v.push(out.join("error_maps").join(format!("liver_dark_s1_0000_{m}_scale_shift.png")));
    }
    v
}

#[test]
fn missing_frames_are_all_listed_and_no_results_are_left() {
    let d = tempfile::tempdir().unwrap();
    let root = d.path().join("data");
    dataset(&root);
    let man = root.join("manifest.toml");
    assert!(run(&["depth", "manifest", "scaffold", "--root", s(&root), "--gt-unit", "m"]).status.success());
    // Remove two files of different kinds.
    let gone_gt = root.join("kidney/smoke/s2/depth/0001.npy");
    let gone_pred = root.join("predictions/good/liver/dark/s0/0000.npy");
    std::fs::remove_file(&gone_gt).unwrap();
    std::fs::remove_file(&gone_pred).unwrap();
    let o = run(&["depth", "manifest", "validate", s(&man)]);
    assert_clean_failure(&o, &["kidney/smoke/s2/depth/0001.npy", "predictions/good/liver/dark/s0/0000.npy"]);
    // eval: the same list, and a stale results.json from an earlier run is removed.
    let out = d.path().join("out");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("results.json"), "{\"complete\": true}").unwrap();
    let o = run(&["depth", "eval", "--manifest", s(&man), "--baseline", "base", "--out", s(&out)]);
    assert_clean_failure(&o, &["kidney/smoke/s2/depth/0001.npy", "predictions/good/liver/dark/s0/0000.npy"]);
    assert!(!out.join("results.json").exists());
}

#[test]
fn a_bad_prediction_fails_the_run_without_partial_results() {
    let d = tempfile::tempdir().unwrap();
    let root = d.path().join("data");
    dataset(&root);
    let man = root.join("manifest.toml");
    assert!(run(&["depth", "manifest", "scaffold", "--root", s(&root), "--gt-unit", "m"]).status.success());
    let bad = root.join("predictions/good/kidney/dark/s1/0001.npy");
    write_npy_f64(&bad, &img(vec![f64::NAN; W * H])).unwrap();
    let out = d.path().join("out");
    let o = run(&["depth", "eval", "--manifest", s(&man), "--baseline", "base", "--out", s(&out)]);
    assert_clean_failure(&o, &["kidney/dark/s1/0001.npy", "no valid value"]);
    assert!(!out.join("results.json").exists());
    // A truncated GT file.
    write_npy_f64(&bad, &img(disparity(1.0, 0.0))).unwrap();
    let gt = root.join("liver/smoke/s1/depth/0000.npy");
    let bytes = std::fs::read(&gt).unwrap();
    std::fs::write(&gt, &bytes[..100]).unwrap();
    let o = run(&["depth", "eval", "--manifest", s(&man), "--baseline", "base", "--out", s(&out)]);
    assert_clean_failure(&o, &["liver/smoke/s1/depth/0000.npy"]);
    assert!(!out.join("results.json").exists());
    // Unknown baseline.
    let o = run(&["depth", "eval", "--manifest", s(&man), "--baseline", "nobody", "--out", s(&out)]);
    assert_clean_failure(&o, &["nobody"]);
}

/// Issue 10: GT far outside the clamp range (Middlebury, 2–5 m) used to give meaningless
/// metrics with exit 0 and no word; a mm file read as metres was not noticed either.
#[test]
fn eval_pair_warns_about_gt_outside_the_clamp_range_and_implausible_units() {
    let d = tempfile::tempdir().unwrap();
    let (p, g) = (d.path().join("pred.npy"), d.path().join("gt.npy"));
    // GT 2–5 m (a slanted plane), prediction exact up to scale.
    let gt: Vec<f64> = (0..W * H).map(|i| 2.0 + 3.0 * (i % W) as f64 / (W - 1) as f64).collect();
    write_npy_f64(&g, &img(gt.clone())).unwrap();
    write_npy_f64(&p, &img(gt.iter().map(|z| 7.0 / z).collect())).unwrap();
    let eval_pair = |extra: &[&str]| {
        let mut a = vec!["depth", "eval-pair", "--pred", s(&p), "--gt", s(&g), "--json"];
        a.extend_from_slice(extra);
        run(&a)
    };
    let o = eval_pair(&["--gt-unit", "m"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    // All 384 valid pixels lie beyond 0.5 m.
    assert!(err.contains("100.0 % of the valid ground truth lies outside the clamp range [0.01, 0.5] m"), "{err}");
    assert!(err.contains("--depth-min-m/--depth-max-m"), "{err}");
    // With a range that fits: no warning, and s-alignment is exact (scale 1/7).
    let o = eval_pair(&["--gt-unit", "m", "--depth-min-m", "1", "--depth-max-m", "10"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success() && !err.contains("warning"), "{err}");
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(v["scale"]["abs_rel"].as_f64().unwrap() < 1e-12, "{v}");
    assert!((v["scale"]["scale"].as_f64().unwrap() - 1.0 / 7.0).abs() < 1e-12);
    // The same values declared as mm (the default unit) are 2–5 mm: implausible.
    let o = eval_pair(&[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("median ground-truth depth is 3.500 mm, implausible"), "{err}");
    // A mm file (2000–5000) read as metres: a median of 3500 m.
    write_npy_f64(&g, &img(gt.iter().map(|z| z * 1000.0).collect())).unwrap();
    let o = eval_pair(&["--gt-unit", "m"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("median ground-truth depth is 3500.0 m, implausible: millimetres read as metres"), "{err}");
    // --json=FILE writes the file and keeps the table on stdout.
    let jf = d.path().join("r.json");
    let jarg = format!("--json={}", s(&jf));
    let o = run(&[
        "depth",
        "eval-pair",
        "--pred",
        s(&p),
        "--gt",
        s(&g),
        "--gt-unit",
        "mm",
        "--depth-min-m",
        "1",
        "--depth-max-m",
        "10",
        &jarg,
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stdout).contains("alignment"));
    assert!(read_json(&jf)["scale"]["abs_rel"].as_f64().unwrap() < 1e-12);
}

/// Issue 10: a prediction at network resolution was rejected; `--resize-pred` resizes it.
#[test]
fn eval_pair_resizes_predictions_at_network_resolution() {
    let d = tempfile::tempdir().unwrap();
    let (p, g) = (d.path().join("pred.npy"), d.path().join("gt.npy"));
    // GT (mm) constant on 2x2 blocks; the prediction is 3x its disparity at half resolution.
    let (hw, hh) = (W / 2, H / 2);
    let zb = |bx: usize, by: usize| 60.0 + 4.0 * bx as f64 + 7.0 * by as f64;
    let gt: Vec<f64> = (0..W * H).map(|i| zb((i % W) / 2, (i / W) / 2)).collect();
    write_npy_f64(&g, &img(gt)).unwrap();
    let pred: Vec<f64> = (0..hw * hh).map(|i| 3.0 / zb(i % hw, i / hw)).collect();
    write_npy_f64(&p, &Image::from_vec(hw, hh, 1, pred).unwrap()).unwrap();
    let base = ["depth", "eval-pair", "--pred", s(&p), "--gt", s(&g), "--gt-unit", "mm", "--json"];
    let o = run(&base);
    assert_clean_failure(&o, &["pred.npy", "size mismatch"]);
    let mut a = base.to_vec();
    a.extend(["--resize-pred", "nearest"]);
    let o = run(&a);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    // Nearest with centres aligned maps x to floor(x / 2): exact, s = 1/3000 (disparity in 1/m).
    assert_eq!(v["n_valid"], W * H);
    assert!(v["scale"]["abs_rel"].as_f64().unwrap() < 1e-12, "{v}");
    let mut a = base.to_vec();
    a.extend(["--resize-pred", "bilinear"]);
    let o = run(&a);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let e = v["scale_shift"]["abs_rel"].as_f64().unwrap();
    assert!(e > 0.0 && e < 0.05, "bilinear blends neighbouring blocks a little: {e}");
}

/// Issue 10: `depth eval` had no range flags and the scaffolded manifest hid `depth_min_m`.
#[test]
fn eval_range_flags_and_scaffolded_range() {
    let d = tempfile::tempdir().unwrap();
    let root = d.path().join("data");
    dataset(&root);
    let man = root.join("manifest.toml");
    let o = run(&["depth", "manifest", "scaffold", "--root", s(&root), "--gt-unit", "m"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(&man).unwrap();
    assert!(text.contains("depth_min_m = 0.01") && text.contains("depth_max_m = 0.5"), "{text}");
    // GT is 5–17 cm: inside the default range, no warning.
    let out = d.path().join("out");
    let args = |extra: &[&str]| {
        let mut a =
            vec!["depth", "eval", "--manifest", s(&man), "--baseline", "base", "--out", s(&out), "--no-figures"];
        a.extend_from_slice(extra);
        run(&a)
    };
    let o = args(&[]);
    assert!(o.status.success() && !String::from_utf8_lossy(&o.stderr).contains("warning"));
    let csv0 = std::fs::read_to_string(out.join("per_image.csv")).unwrap();
    // A near clamp of 20 cm puts all GT outside the range: warned, and the metrics change.
    let o = args(&["--depth-min-m", "0.2", "--depth-max-m", "5"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("100.0 % of the valid ground truth lies outside the clamp range [0.2, 5] m"), "{err}");
    assert_ne!(csv0, std::fs::read_to_string(out.join("per_image.csv")).unwrap());
    // An invalid range names the flags.
    assert_clean_failure(&args(&["--depth-min-m", "0.3", "--depth-max-m", "0.2"]), &["--depth-min-m", "depth range"]);
}

/// Issue 10 ("silent garbage"): an all-zero disparity has no s-alignment (scale = NaN, JSON
/// `null`); the metrics were printed without a word. The JSON keeps `null` (as the reference).
#[test]
fn eval_pair_warns_when_the_scale_alignment_is_undefined() {
    let d = tempfile::tempdir().unwrap();
    let (p, g) = (d.path().join("zero.npy"), d.path().join("gt.npy"));
    write_npy_f64(&g, &img(gt_m())).unwrap();
    write_npy_f64(&p, &img(vec![0.0; W * H])).unwrap();
    let o = run(&["depth", "eval-pair", "--pred", s(&p), "--gt", s(&g), "--gt-unit", "m", "--json"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("zero.npy: the 'scale' alignment is undefined (scale NaN"), "{err}");
    assert!(!err.contains("'scale_shift' alignment") && !err.contains("'none' alignment"), "{err}");
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(v["scale"]["scale"].is_null(), "{v}");
    // An ordinary prediction: no such warning.
    write_npy_f64(&p, &img(disparity(2.0, 0.0))).unwrap();
    let o = run(&["depth", "eval-pair", "--pred", s(&p), "--gt", s(&g), "--gt-unit", "m", "--json"]);
    assert!(o.status.success() && !String::from_utf8_lossy(&o.stderr).contains("undefined"));
}
