//! `laparo mpm` end to end: simulate writes frames and a log; bad input fails clearly (the bench is in laparo-bench).
use std::path::Path;
mod common;
use common::command;
use std::process::{Command, Output};
use std::time::Instant;

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
    let o = command()
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
    // progress lines when stderr is not a terminal (indicatif would hide itself): every 10 %
    let err = String::from_utf8_lossy(&o.stderr);
    for pct in [10, 50, 100] {
        assert!(err.contains(&format!("({pct} %)")), "no {pct} % progress line: {err}");
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
    let o = command()
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
    let o = command()
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
        let o = command()
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

/// `laparo mpm simulate --scene S --out O` under a 1 GB address-space limit (ulimit -v) and a 20 s
/// hang guard; returns the output and the wall time in seconds.
fn simulate_limited(scene: &Path, out: &Path) -> (Output, f64) {
    let t = Instant::now();
    let o = Command::new("sh")
        .arg("-c")
        .arg("ulimit -v 1048576; exec timeout 20 \"$0\" mpm simulate --scene \"$1\" --out \"$2\"")
        .arg(common::BIN)
        .arg(scene)
        .arg(out)
        .output()
        .unwrap();
    (o, t.elapsed().as_secs_f64())
}

const SCENE_3D: &str = "dim = 3\n[grid]\nn_grid = 32\ndx = 0.03125\n[material]\nmodel = \"neo_hookean\"\nyoungs_modulus = 50.0\npoisson_ratio = 0.3\ndensity = 1.0\n[time]\nsteps = 10\n[[body]]\nshape = \"box\"\nlo = [0.4, 0.4, 0.4]\nhi = [0.6, 0.6, 0.6]\n";

/// Gmsh v2 file of one tetrahedron.
fn msh_one_tet(v: [[f64; 3]; 4]) -> String {
    let mut s = String::from("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n");
    for (i, p) in v.iter().enumerate() {
        s += &format!("{} {} {} {}\n", i + 1, p[0], p[1], p[2]);
    }
    s + "$EndNodes\n$Elements\n1\n1 4 2 0 1 1 2 3 4\n$EndElements\n"
}

#[test]
fn malformed_scenes_fail_cleanly_within_limits() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(
        d.join("poly.vtk"),
        "# vtk DataFile Version 2.0\nt\nASCII\nDATASET POLYDATA\nPOINTS 4 double\n0.4 0.4 0.4 0.6 0.4 0.4 0.4 0.6 0.4 0.4 0.4 0.6\nPOLYGONS 4 16\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n",
    )
    .unwrap();
    std::fs::write(
        d.join("far.msh"),
        msh_one_tet([[0.4, 0.4, 0.4], [0.6, 0.4, 0.4], [0.4, 0.6, 0.4], [-1e300, 0.4, 0.6]]),
    )
    .unwrap();
    let tet = |p: &str| format!("shape = \"tet_mesh\"\npath = \"{p}\"");
    let cases: Vec<(&str, String, String, &[&str])> = vec![
        ("huge_n_grid", "n_grid = 32".into(), "n_grid = 100000000".into(), &["n_grid", "too large"]),
        ("huge_n_grid_u64", "n_grid = 32".into(), "n_grid = 9223372036854775807".into(), &["n_grid"]),
        ("tiny_dx", "dx = 0.03125".into(), "dx = 1e-300".into(), &["outside the grid domain"]),
        ("subnormal_dx", "dx = 0.03125".into(), "dx = 1e-320".into(), &["grid.dx"]),
        ("zero_dx", "dx = 0.03125".into(), "dx = 0.0".into(), &["grid.dx"]),
        (
            "tiny_spacing",
            "hi = [0.6, 0.6, 0.6]".into(),
            "hi = [0.6, 0.6, 0.6]\nspacing = 1e-7".into(),
            &["spacing", "too fine"],
        ),
        ("nan_spacing", "hi = [0.6, 0.6, 0.6]".into(), "hi = [0.6, 0.6, 0.6]\nspacing = nan".into(), &["spacing"]),
        ("inf_corner", "hi = [0.6, 0.6, 0.6]".into(), "hi = [inf, 0.6, 0.6]".into(), &["hi", "finite"]),
        (
            "nan_force",
            "hi = [0.6, 0.6, 0.6]".into(),
            "hi = [0.6, 0.6, 0.6]\nforce_density = [nan, 0.0, 0.0]".into(),
            &["force_density", "finite"],
        ),
        ("inf_gravity", "dim = 3".into(), "dim = 3\ngravity = [0.0, 0.0, -inf]".into(), &["gravity"]),
        ("nan_dt", "steps = 10".into(), "steps = 10\ndt = nan".into(), &["time.dt"]),
        ("thick_walls", "youngs_modulus".into(), "youngs_modulus".into(), &[]),
        ("far_vertex", "shape = \"box\"".into(), tet("far.msh"), &["outside the grid domain", "body 0"]),
        ("polydata_vtk", "shape = \"box\"".into(), tet("poly.vtk"), &["poly.vtk", "no tetrahedra"]),
    ];
    for (name, from, to, want) in cases {
        let mut text = SCENE_3D.replace(&from, &to);
        if name == "thick_walls" {
            text += "[boundary]\nwalls = \"sticky\"\nthickness = 1000\n";
        }
        let scene = d.join(format!("{name}.toml"));
        std::fs::write(&scene, &text).unwrap();
        let (o, secs) = simulate_limited(&scene, &d.join(format!("out_{name}")));
        let err = String::from_utf8_lossy(&o.stderr);
        let want: Vec<&str> = if name == "thick_walls" { vec!["thickness"] } else { want.to_vec() };
        assert_eq!(o.status.code(), Some(1), "{name}: exit {:?} after {secs:.1} s: {err}", o.status);
        assert!(!err.contains("panicked") && err.contains("error:"), "{name}: {err}");
        for w in want {
            assert!(err.contains(w), "{name}: '{w}' not in: {err}");
        }
        eprintln!("{name}: exit 1 after {secs:.2} s: {}", err.trim());
    }
    // the limits themselves leave a valid scene alone
    std::fs::write(d.join("ok.toml"), SCENE_3D).unwrap();
    let (o, _) = simulate_limited(&d.join("ok.toml"), &d.join("out_ok"));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// Particle count from the "3D scene: N particles" line.
fn particles_of(stderr: &str) -> usize {
    let l = stderr.lines().find(|l| l.contains(" particles, n_grid")).unwrap_or_else(|| panic!("{stderr}"));
    l.split_whitespace().nth(2).unwrap().parse().unwrap()
}

#[test]
fn tet_mesh_is_sampled_at_spacing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // Corner tetrahedron of edge 0.5 at (0.25, 0.25, 0.25), spacing 0.01: lattice points
    // (i+½, j+½, k+½)·0.01 with i+j+k ≤ 48.5: C(51, 3) = 20825 (V/s³ = 20833). Before the fix: 1.
    std::fs::write(d.join("t.msh"), msh_one_tet([[0.0, 0.0, 0.0], [0.5, 0.0, 0.0], [0.0, 0.5, 0.0], [0.0, 0.0, 0.5]]))
        .unwrap();
    let scene = SCENE_3D
        .replace(
            "shape = \"box\"",
            "shape = \"tet_mesh\"\npath = \"t.msh\"\noffset = [0.25, 0.25, 0.25]\nspacing = 0.01",
        )
        .replace("steps = 10", "steps = 2");
    std::fs::write(d.join("t.toml"), &scene).unwrap();
    let (o, _) = simulate_limited(&d.join("t.toml"), &d.join("out"));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert_eq!(particles_of(&err), 20825, "{err}");
    assert!(!err.contains("particles per grid cell"), "{err}");
    // spacing = dx: 1 particle per cell draws the warning
    std::fs::write(d.join("t1.toml"), scene.replace("spacing = 0.01", "spacing = 0.03125")).unwrap();
    let (o, _) = simulate_limited(&d.join("t1.toml"), &d.join("out1"));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success() && err.contains("warning: body 0: 1.00 particles per grid cell"), "{err}");
}

#[test]
fn sofa_liver_tet_mesh_count_matches_its_volume() {
    let liver = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data/meshes/sofa_liver/liver.msh"));
    if !liver.is_file() {
        eprintln!("SKIP: {} is absent", liver.display());
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::copy(liver, d.join("liver.msh")).unwrap();
    // Liver (~6.5 × 5 × 4.4 mesh units) scaled to metres ×0.01 inside a 0.16 m box, dx = 2.5 mm,
    // spacing dx/2: count ≈ V·0.01³ / spacing³, V from the closed boundary surface of the tets
    // (divergence theorem, independent of the sampler).
    let scene = "dim = 3\ngravity = [0.0, 0.0, -9.81]\n[grid]\nn_grid = 64\ndx = 0.0025\n[material]\nmodel = \"neo_hookean\"\nyoungs_modulus = 4100.0\npoisson_ratio = 0.45\ndensity = 1000.0\n[time]\nsteps = 2\n[[body]]\nshape = \"tet_mesh\"\npath = \"liver.msh\"\nscale = 0.01\noffset = [0.07, 0.02, 0.05]\n";
    std::fs::write(d.join("liver.toml"), scene).unwrap();
    let (o, _) = simulate_limited(&d.join("liver.toml"), &d.join("out"));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    let m = laparo_core::mesh::read_msh(liver).unwrap();
    let v = m.boundary().signed_volume().abs() * 1e-6;
    let expect = v / 0.00125f64.powi(3);
    let n = particles_of(&err) as f64;
    assert!((n - expect).abs() < 0.03 * expect, "{n} particles vs V/s^3 = {expect:.0}");
    assert!(n > 10000.0, "{n}: the old sampler gave one particle per tetrahedron (596)");
}

#[test]
fn simulate_3d_binary_ply_preview_and_no_stale_frames() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("s.toml"), SCENE_3D).unwrap();
    let out = d.join("out");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("notes.txt"), "mine").unwrap();
    let run = |every: &str, steps: &str| {
        std::fs::write(d.join("s.toml"), SCENE_3D.replace("steps = 10", steps)).unwrap();
        let o = command()
            .args(["mpm", "simulate", "--scene"])
            .arg(d.join("s.toml"))
            .arg("--out")
            .arg(&out)
            .args(["--every", every])
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    };
    run("2", "steps = 10");
    let frames = |ext: &str| {
        let mut v: Vec<String> = std::fs::read_dir(&out)
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .filter(|n| n.starts_with("frame_") && n.ends_with(ext))
            .collect();
        v.sort();
        v
    };
    assert_eq!(frames(".ply").len(), 6);
    // binary little-endian PLY: header, then 1728 vertices × 7 doubles; first vertex = first box
    // lattice point (0.4 + spacing/2 on every axis, spacing dx/2), velocity 0, J = 1
    let bytes = std::fs::read(out.join("frame_00000.ply")).unwrap();
    let end = bytes.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
    let header = std::str::from_utf8(&bytes[..end]).unwrap();
    assert!(header.contains("format binary_little_endian 1.0") && header.contains("element vertex 1728"), "{header}");
    assert_eq!(bytes.len() - end, 1728 * 7 * 8);
    let f = |i: usize| f64::from_le_bytes(bytes[end + 8 * i..end + 8 * i + 8].try_into().unwrap());
    let x0 = 0.4 + 0.03125 / 4.0;
    assert!((f(0) - x0).abs() < 1e-12 && (f(2) - x0).abs() < 1e-12, "{} {}", f(0), f(2));
    assert_eq!((f(3), f(6)), (0.0, 1.0));
    // PNG preview with a colour bar (wider than the 640 px view)
    let png = std::fs::read(out.join("preview.png")).unwrap();
    assert_eq!(&png[1..4], b"PNG");
    let w = u32::from_be_bytes(png[16..20].try_into().unwrap());
    let h = u32::from_be_bytes(png[20..24].try_into().unwrap());
    assert!(w > 640 && h == 640, "{w}x{h}");
    // a shorter rerun leaves only its own frames; other files are kept
    run("2", "steps = 4");
    assert_eq!(frames(".ply"), ["frame_00000.ply", "frame_00002.ply", "frame_00004.ply"]);
    assert!(out.join("notes.txt").exists() && out.join("preview.png").exists());
    let log = std::fs::read_to_string(out.join("energy_momentum.csv")).unwrap();
    assert_eq!(log.lines().count(), 6, "header + 5 rows");
}
