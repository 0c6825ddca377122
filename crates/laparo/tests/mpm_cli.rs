//! `laparo mpm` end to end: simulate writes frames and a log; bad input fails clearly; bench --json.
use std::process::Command;

fn laparo() -> Command {
    Command::new(env!("CARGO_BIN_EXE_laparo"))
}

const SCENE_2D: &str = r#"
dim = 2
[grid]
n_grid = 32
dx = 0.03125
[material]
model = "neo_hookean"
youngs_modulus = 5.0
poisson_ratio = 0.3
density = 1.0
[time]
steps = 40
[[body]]
shape = "box"
lo = [0.4, 0.4]
hi = [0.6, 0.55]
stretch_rate = [4.0, 0.0]
"#;

#[test]
fn simulate_2d_writes_frames_and_log() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("s.toml");
    std::fs::write(&scene, SCENE_2D).unwrap();
    let out = dir.path().join("out");
    let o = laparo()
        .args(["mpm", "simulate", "--scene"])
        .arg(&scene)
        .arg("--out")
        .arg(&out)
        .args(["--every", "10"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for s in [0, 10, 20, 30, 40] {
        assert!(out.join(format!("frame_{s:05}.png")).exists(), "frame {s}");
    }
    let log = std::fs::read_to_string(out.join("energy_momentum.csv")).unwrap();
    assert_eq!(log.lines().count(), 42, "header + 41 rows");
    // sticky walls are far away and there is no gravity: linear momentum stays 0 (symmetric pull)
    let last: Vec<f64> = log.lines().last().unwrap().split(',').map(|v| v.parse().unwrap()).collect();
    assert!(last[5].abs() < 1e-12 && last[6].abs() < 1e-12, "momentum {:?}", &last[5..7]);
}

#[test]
fn simulate_3d_mesh_and_bad_inputs() {
    let dir = tempfile::tempdir().unwrap();
    // closed tetrahedron surface, voxelised
    let obj = "v 0.4 0.4 0.4\nv 0.6 0.4 0.4\nv 0.4 0.6 0.4\nv 0.4 0.4 0.6\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
    std::fs::write(dir.path().join("tet.obj"), obj).unwrap();
    let scene3 = "dim = 3\n[grid]\nn_grid = 32\ndx = 0.03125\n[material]\nmodel = \"neo_hookean\"\nyoungs_modulus = 50.0\npoisson_ratio = 0.3\ndensity = 1.0\n[time]\nsteps = 10\n[[body]]\nshape = \"mesh\"\npath = \"tet.obj\"\nspacing = 0.01\n";
    std::fs::write(dir.path().join("s3.toml"), scene3).unwrap();
    let out = dir.path().join("o3");
    let o = laparo()
        .args(["mpm", "simulate", "--scene"])
        .arg(dir.path().join("s3.toml"))
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.join("frame_00010.ply").exists());
    // open mesh
    std::fs::write(dir.path().join("open.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    std::fs::write(dir.path().join("s_open.toml"), scene3.replace("tet.obj", "open.obj")).unwrap();
    let o = laparo()
        .args(["mpm", "simulate", "--scene"])
        .arg(dir.path().join("s_open.toml"))
        .arg("--out")
        .arg(dir.path().join("x"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("not closed") && err.contains("open.obj"), "{err}");
    // nu >= 0.5, E <= 0, particles outside the domain
    for (from, to, what) in [
        ("poisson_ratio = 0.3", "poisson_ratio = 0.5", "poisson_ratio"),
        ("youngs_modulus = 50.0", "youngs_modulus = 0.0", "youngs_modulus"),
        ("spacing = 0.01", "spacing = 0.01\noffset = [0.8, 0.0, 0.0]", "outside the grid"),
    ] {
        std::fs::write(dir.path().join("s_bad.toml"), scene3.replace(from, to)).unwrap();
        let o = laparo()
            .args(["mpm", "simulate", "--scene"])
            .arg(dir.path().join("s_bad.toml"))
            .arg("--out")
            .arg(dir.path().join("y"))
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && err.contains(what), "{what}: {err}");
    }
}

#[test]
fn bench_json_small() {
    let o = laparo()
        .args([
            "mpm",
            "bench",
            "--dim",
            "2",
            "--particles",
            "400",
            "--n-grid",
            "64",
            "--steps",
            "20",
            "--repeats",
            "1",
            "--json",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    for k in ["dim", "particles", "n_grid", "steps", "forward_s", "forward_backward_s", "peak_rss_mb"] {
        assert!(v.get(k).is_some(), "missing {k}");
    }
    assert_eq!(v["dim"], 2);
    assert_eq!(v["particles"], 400);
    assert!(v["forward_backward_s"].as_f64().unwrap() > 0.0);
}
