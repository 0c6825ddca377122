//! `laparo cats augment` / `apply`: determinism across thread counts, resumability after an
//! interruption, reproduction of a sample from its sidecar, and clear errors on bad input.
use laparo_core::{io, Image};
use laparo_stereo::{default_camera, Scene};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
mod common;
use common::command;

fn make_dataset(root: &Path, n: usize) {
    let k = default_camera(64, 48);
    for i in 0..n {
        // Different baselines give different samples.
        let s = Scene::default().stereo_sample(&k, 40.0 + 10.0 * i as f64, 1);
        let name = format!("{i:04}");
        io::write_png(root.join("left").join(format!("{name}.png")), &s.left).unwrap();
        io::write_png(root.join("right").join(format!("{name}.png")), &s.right).unwrap();
        io::write_pfm(root.join("disp").join(format!("{name}.pfm")), s.disp_left.as_ref().unwrap()).unwrap();
    }
    let cfg = format!(
        "source = \"test\"\n[camera]\nfx = {f}\nfy = {f}\n\
         [left.euler_deg]\nx = {{ dist = \"normal\", mean = 0.0, std = 0.5 }}\ny = {{ dist = \"normal\", mean = 0.0, std = 1.0 }}\nz = {{ dist = \"normal\", mean = 0.0, std = 1.0 }}\n\
         [right.euler_deg]\nx = {{ dist = \"normal\", mean = 0.0, std = 0.5 }}\ny = {{ dist = \"normal\", mean = 0.0, std = 1.0 }}\nz = {{ dist = \"normal\", mean = 0.0, std = 1.0 }}\n\
         [disparity_offset]\ndx_right_px = {{ dist = \"uniform\", min = -20.0, max = 0.0 }}\n",
        f = k.fx
    );
    std::fs::write(root.join("cats.toml"), cfg).unwrap();
}

fn run(args: &[&str], threads: usize) -> (bool, String) {
    let o = command().args(args).env("RAYON_NUM_THREADS", threads.to_string()).output().unwrap();
    (o.status.success(), String::from_utf8_lossy(&o.stderr).into_owned())
}

fn augment(input: &Path, out: &Path, seed: u64, threads: usize) -> (bool, String) {
    run(
        &[
            "cats",
            "augment",
            "--input",
            input.to_str().unwrap(),
            "--layout",
            "generic",
            "--out",
            out.to_str().unwrap(),
            "--config",
            input.join("cats.toml").to_str().unwrap(),
            "--seed",
            &seed.to_string(),
        ],
        threads,
    )
}

fn tree(root: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    fn walk(d: &Path, root: &Path, m: &mut BTreeMap<PathBuf, Vec<u8>>) {
        for e in std::fs::read_dir(d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                walk(&p, root, m);
            } else {
                m.insert(p.strip_prefix(root).unwrap().to_path_buf(), std::fs::read(&p).unwrap());
            }
        }
    }
    let mut m = BTreeMap::new();
    walk(root, root, &mut m);
    m
}

#[test]
fn augment_is_deterministic_across_threads_and_resumable() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in");
    make_dataset(&input, 5);
    let (o1, o2) = (dir.path().join("o1"), dir.path().join("o2"));
    let (ok, err) = augment(&input, &o1, 7, 1);
    assert!(ok, "{err}");
    let (ok, err) = augment(&input, &o2, 7, 2);
    assert!(ok, "{err}");
    let t1 = tree(&o1);
    let t2 = tree(&o2);
    // 5 samples × (left, right, disp, sidecar, 2 masks, vertical residual).
    assert_eq!(t1.len(), 5 * 7, "{:?}", t1.keys().collect::<Vec<_>>());
    assert_eq!(t1, t2, "outputs differ between 1 and 2 threads");
    assert!(t1.contains_key(Path::new("left/0003.cats.json")));
    assert!(t1.contains_key(Path::new("disp/0003.pfm")));

    // Another seed gives other parameters.
    let o3 = dir.path().join("o3");
    assert!(augment(&input, &o3, 8, 2).0);
    assert_ne!(tree(&o3)[Path::new("left/0001.png")], t1[Path::new("left/0001.png")]);

    // Interruption: sample 2 lost its sidecar and has a truncated image, sample 4 only a
    // leftover temporary file. A re-run redoes exactly those and gives the same bytes.
    std::fs::remove_file(o1.join("left/0002.cats.json")).unwrap();
    std::fs::write(o1.join("left/0002.png"), b"trunc").unwrap();
    std::fs::remove_file(o1.join("left/0004.cats.json")).unwrap();
    std::fs::write(o1.join("left/.0004.png.123.tmp"), b"partial").unwrap();
    let before = std::fs::metadata(o1.join("left/0001.cats.json")).unwrap().modified().unwrap();
    let (ok, err) = augment(&input, &o1, 7, 2);
    assert!(ok, "{err}");
    assert!(err.contains("2 to do (3 already finished)"), "{err}");
    let after = std::fs::metadata(o1.join("left/0001.cats.json")).unwrap().modified().unwrap();
    assert_eq!(before, after, "a finished sample was redone");
    std::fs::remove_file(o1.join("left/.0004.png.123.tmp")).unwrap();
    assert_eq!(tree(&o1), t2);

    // Re-applying a sidecar reproduces the sample bit for bit.
    let ap = dir.path().join("apply");
    let (ok, err) = run(
        &[
            "cats",
            "apply",
            "--params",
            o1.join("left/0003.cats.json").to_str().unwrap(),
            "--left",
            input.join("left/0003.png").to_str().unwrap(),
            "--right",
            input.join("right/0003.png").to_str().unwrap(),
            "--disp",
            input.join("disp/0003.pfm").to_str().unwrap(),
            "--out",
            ap.to_str().unwrap(),
            "--gt-rule",
            "exact",
        ],
        1,
    );
    assert!(ok, "{err}");
    assert_eq!(std::fs::read(ap.join("left.png")).unwrap(), t1[Path::new("left/0003.png")]);
    assert_eq!(std::fs::read(ap.join("right.png")).unwrap(), t1[Path::new("right/0003.png")]);
    assert_eq!(std::fs::read(ap.join("disp_left.pfm")).unwrap(), t1[Path::new("disp/0003.pfm")]);
}

#[test]
fn hand_written_params_and_bad_inputs() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in");
    make_dataset(&input, 1);
    let k = default_camera(64, 48);
    // Pure principal-point shift, thesis rule: every valid output disparity is d + Δx.
    let params = dir.path().join("p.json");
    std::fs::write(
        &params,
        format!(
            "{{\"k\": [[{f}, 0, {cx}], [0, {f}, {cy}], [0, 0, 1]], \"left\": {{\"euler_deg\": [0, 0, 0]}}, \"dx_right_px\": -12}}",
            f = k.fx,
            cx = k.cx,
            cy = k.cy
        ),
    )
    .unwrap();
    let out = dir.path().join("a");
    let l = input.join("left/0000.png");
    let r = input.join("right/0000.png");
    let d = input.join("disp/0000.pfm");
    let args = |p: &Path, l: &Path, d: &Path, out: &Path| -> Vec<String> {
        [
            "cats",
            "apply",
            "--params",
            p.to_str().unwrap(),
            "--left",
            l.to_str().unwrap(),
            "--right",
            r.to_str().unwrap(),
            "--disp",
            d.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--gt-rule",
            "thesis",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect()
    };
    let a = args(&params, &l, &d, &out);
    let (ok, err) = run(&a.iter().map(|s| s.as_str()).collect::<Vec<_>>(), 1);
    assert!(ok, "{err}");
    let src = io::read_pfm(&d).unwrap();
    let got = io::read_pfm(out.join("disp_left.pfm")).unwrap();
    for (s, g) in src.data.iter().zip(&got.data) {
        if s.is_finite() {
            assert_eq!(*g, *s - 12.0);
        }
    }
    assert_eq!(io::read_image(out.join("left.png")).unwrap(), io::read_image(&l).unwrap());

    // Images of different sizes: the error names the right image.
    let small = dir.path().join("small.png");
    io::write_png(&small, &Image::filled(32, 48, 3, 9u8)).unwrap();
    let a = args(&params, &small, &d, &out);
    let (ok, err) = run(&a.iter().map(|s| s.as_str()).collect::<Vec<_>>(), 1);
    assert!(!ok && err.contains("0000.png") && err.contains("64x48"), "{err}");
    // A PFM with a wrong header: the error names the file.
    let bad = dir.path().join("bad.pfm");
    std::fs::write(&bad, b"P5\n64 48\n-1.0\n").unwrap();
    let a = args(&params, &l, &bad, &out);
    let (ok, err) = run(&a.iter().map(|s| s.as_str()).collect::<Vec<_>>(), 1);
    assert!(!ok && err.contains("bad.pfm"), "{err}");
    // A non-rotation matrix in the parameters.
    std::fs::write(
        &params,
        r#"{"k": {"fx": 70, "fy": 70, "cx": 32, "cy": 24}, "left": {"rotation": [[2,0,0],[0,1,0],[0,0,1]]}}"#,
    )
    .unwrap();
    let a = args(&params, &l, &d, &out);
    let (ok, err) = run(&a.iter().map(|s| s.as_str()).collect::<Vec<_>>(), 1);
    assert!(!ok && err.contains("p.json") && err.contains("left.rotation"), "{err}");
    // A config with a negative standard deviation.
    std::fs::write(input.join("cats.toml"), "[left.euler_deg]\nx = { dist = \"normal\", mean = 0.0, std = -1.0 }\n")
        .unwrap();
    let (ok, err) = augment(&input, &dir.path().join("o"), 1, 1);
    assert!(!ok && err.contains("cats.toml"), "{err}");
}

fn augment_args(input: &Path, out: &Path, seed: u64, extra: &[&str]) -> (bool, String) {
    let mut a: Vec<String> = [
        "cats",
        "augment",
        "--input",
        input.to_str().unwrap(),
        "--layout",
        "generic",
        "--out",
        out.to_str().unwrap(),
        "--config",
        input.join("cats.toml").to_str().unwrap(),
        "--seed",
        &seed.to_string(),
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    a.extend(extra.iter().map(|s| s.to_string()));
    run(&a.iter().map(|s| s.as_str()).collect::<Vec<_>>(), 2)
}

/// Issue 10: `--layout generic` with `.npy` disparities printed success and wrote none.
#[test]
fn generic_layout_reads_npy_disparities() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in");
    make_dataset(&input, 2);
    for name in ["0000", "0001"] {
        let pfm = input.join(format!("disp/{name}.pfm"));
        let d = io::read_pfm(&pfm).unwrap();
        io::write_npy_f32(input.join(format!("disp/{name}.npy")), &d).unwrap();
        std::fs::remove_file(&pfm).unwrap();
    }
    let out = dir.path().join("o");
    let (ok, err) = augment_args(&input, &out, 3, &[]);
    assert!(ok, "{err}");
    // Same samples from PFM inputs: identical disparity outputs.
    let (input2, out2) = (dir.path().join("in2"), dir.path().join("o2"));
    make_dataset(&input2, 2);
    assert!(augment_args(&input2, &out2, 3, &[]).0);
    for name in ["0000", "0001"] {
        let p = out.join(format!("disp/{name}.pfm"));
        assert!(p.is_file(), "no disparity written for {name}");
        assert_eq!(std::fs::read(&p).unwrap(), std::fs::read(out2.join(format!("disp/{name}.pfm"))).unwrap());
    }
}

/// Issue 10: a re-run with another seed skipped every sample (resume keyed on file names only);
/// inputs could be overwritten in place; interrupted runs left temporaries forever.
#[test]
fn resume_checks_parameters_and_outputs_never_overwrite_inputs() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in");
    make_dataset(&input, 2);
    let out = dir.path().join("o");
    assert!(augment_args(&input, &out, 7, &[]).0);
    let sidecar = out.join("left/0001.cats.json");
    let seed_of = |p: &Path| -> u64 {
        let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap();
        v["seed"].as_u64().unwrap()
    };
    // Another seed: refused, nothing rewritten.
    let before = std::fs::read(out.join("left/0001.png")).unwrap();
    let (ok, err) = augment_args(&input, &out, 8, &[]);
    assert!(!ok && err.contains("--force") && err.contains("another seed"), "{err}");
    assert!(!err.contains("panicked"));
    assert_eq!(seed_of(&sidecar), 7);
    // The same seed resumes (nothing to do), and removes a stale temporary of ours.
    let tmp = out.join("left/.0001.png.4294967295.0.tmp");
    std::fs::write(&tmp, b"half").unwrap();
    let (ok, err) = augment_args(&input, &out, 7, &[]);
    assert!(ok && err.contains("0 to do"), "{err}");
    assert!(!tmp.exists(), "stale temporary left behind");
    // A changed configuration is a mismatch too.
    let cfg = std::fs::read_to_string(input.join("cats.toml")).unwrap();
    std::fs::write(input.join("cats.toml"), cfg.replace("std = 0.5", "std = 0.7")).unwrap();
    let (ok, err) = augment_args(&input, &out, 7, &[]);
    assert!(!ok && err.contains("--force"), "{err}");
    std::fs::write(input.join("cats.toml"), cfg).unwrap();
    // --force (and the old spelling --overwrite) redoes everything with the new seed.
    let (ok, err) = augment_args(&input, &out, 8, &["--force"]);
    assert!(ok, "{err}");
    assert_eq!(seed_of(&sidecar), 8);
    assert_ne!(std::fs::read(out.join("left/0001.png")).unwrap(), before);
    assert!(augment_args(&input, &out, 9, &["--overwrite"]).0);
    // Output = input, or inside the input: refused before anything is written.
    let left0 = std::fs::read(input.join("left/0000.png")).unwrap();
    let (ok, err) = augment_args(&input, &input, 7, &[]);
    assert!(!ok && err.contains("would overwrite the input"), "{err}");
    let (ok, err) = augment_args(&input, &input.join("aug"), 7, &[]);
    assert!(!ok && err.contains("would overwrite the input"), "{err}");
    assert_eq!(std::fs::read(input.join("left/0000.png")).unwrap(), left0);
    assert!(!input.join("left/0000.cats.json").exists() && !input.join("aug").exists());
}

/// Issue 10: a tiny focal length panicked ("validated K is invertible").
#[test]
fn apply_rejects_a_singular_camera_without_panicking() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in");
    make_dataset(&input, 1);
    let params = dir.path().join("tiny.json");
    std::fs::write(
        &params,
        r#"{"k": {"fx": 1e-200, "fy": 1e-200, "cx": 32, "cy": 24}, "left": {"euler_deg": [1, 2, 3]}}"#,
    )
    .unwrap();
    let out = dir.path().join("a");
    let (ok, err) = run(
        &[
            "cats",
            "apply",
            "--params",
            params.to_str().unwrap(),
            "--left",
            input.join("left/0000.png").to_str().unwrap(),
            "--right",
            input.join("right/0000.png").to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
        1,
    );
    assert!(!ok && !err.contains("panicked"), "{err}");
    assert!(err.contains("tiny.json") && err.contains("not numerically invertible"), "{err}");
    assert!(!out.exists());
    // --out over the inputs' folder would replace left.png: refused.
    let inp = dir.path().join("pair");
    std::fs::create_dir_all(&inp).unwrap();
    std::fs::copy(input.join("left/0000.png"), inp.join("left.png")).unwrap();
    std::fs::copy(input.join("right/0000.png"), inp.join("r.png")).unwrap();
    let k = default_camera(64, 48);
    std::fs::write(&params, format!(r#"{{"k": {{"fx": {f}, "fy": {f}, "cx": 32, "cy": 24}}}}"#, f = k.fx)).unwrap();
    let (ok, err) = run(
        &[
            "cats",
            "apply",
            "--params",
            params.to_str().unwrap(),
            "--left",
            inp.join("left.png").to_str().unwrap(),
            "--right",
            inp.join("r.png").to_str().unwrap(),
            "--out",
            inp.to_str().unwrap(),
        ],
        1,
    );
    assert!(!ok && err.contains("would overwrite the input"), "{err}");
}

/// Issue 10: a camera turned away from the source (80° about y) gave an all-invalid view with exit
/// 0 and no word; it must still succeed (a valid parameter set) but warn, naming the view and the
/// parameters file, and write an all-zero validity mask.
#[test]
fn apply_warns_when_a_view_has_no_valid_pixel() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in");
    make_dataset(&input, 1);
    let k = default_camera(64, 48);
    let params = dir.path().join("away.json");
    std::fs::write(
        &params,
        format!(
            r#"{{"k": {{"fx": {f}, "fy": {f}, "cx": {cx}, "cy": {cy}}}, "left": {{"euler_deg": [0, 80, 0]}}}}"#,
            f = k.fx,
            cx = k.cx,
            cy = k.cy
        ),
    )
    .unwrap();
    let out = dir.path().join("a");
    let (ok, err) = run(
        &[
            "cats",
            "apply",
            "--params",
            params.to_str().unwrap(),
            "--left",
            input.join("left/0000.png").to_str().unwrap(),
            "--right",
            input.join("right/0000.png").to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
        1,
    );
    assert!(ok, "{err}");
    assert!(err.contains("left view has no valid pixel") && err.contains("away.json"), "{err}");
    assert!(!err.contains("right view has no valid pixel"), "{err}");
    let valid = io::read_image(out.join("valid_left.png")).unwrap();
    assert!(valid.data.iter().all(|&v| v == 0));
    let valid_r = io::read_image(out.join("valid_right.png")).unwrap();
    assert!(valid_r.data.contains(&255));
}
