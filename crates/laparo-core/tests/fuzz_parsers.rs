//! Seeded mutation fuzzing of every laparo-core parser, on stable Rust (the `fuzz/` directory
//! holds the equivalent cargo-fuzz targets for nightly). Each target starts from valid files
//! written by laparo's own writers plus hand-written samples, mutates them (bit flips, special
//! bytes, inserted / deleted / duplicated chunks, truncation, deep nesting, huge numbers) and
//! asserts that the parser returns (Ok or Err) without panicking.
//!
//! The default run is short (a few seconds in all). Long campaigns:
//! `LAPARO_FUZZ_SECS=600 cargo test --release -p laparo-core --test fuzz_parsers -- --nocapture --test-threads 1`
//! runs each target for that many seconds and prints iterations and the slowest input per target.
//! `LAPARO_FUZZ_CPU_SECS=600` budgets CPU time of the fuzzing thread instead of wall time (Linux:
//! `/proc/thread-self/schedstat`), so that a campaign run at low priority beside other work still
//! gets its full share.
//! A panicking input is saved to `$TMPDIR/laparo-fuzz-<target>-<iteration>.bin` and reported.
use laparo_core::calib::StereoCalibration;
use laparo_core::io;
use laparo_core::mesh::{self, TetMesh, TriMesh};
use laparo_core::Image;
use nalgebra::{Matrix3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::panic::AssertUnwindSafe;
use std::path::Path;
use std::time::{Duration, Instant};

/// One fuzz target: a file name (the extension selects the format) and a parser call.
struct Target {
    name: &'static str,
    file: &'static str,
    parse: fn(&Path) -> bool,
    seeds: Vec<Vec<u8>>,
}

fn seed_images(dir: &Path) -> (Vec<u8>, Vec<u8>, Vec<u8>, Vec<u8>) {
    let img = Image::from_vec(7, 5, 3, (0..105).map(|i| (i * 37 % 256) as u8).collect()).unwrap();
    io::write_png(dir.join("s.png"), &img).unwrap();
    io::write_jpeg(dir.join("s.jpg"), &img, 80).unwrap();
    let f = Image::from_vec(4, 3, 1, (0..12).map(|i| i as f32 * 0.5 - 1.0).collect()).unwrap();
    io::write_tiff_f32(dir.join("s.tif"), &f).unwrap();
    io::write_png16(dir.join("s16.png"), &Image::from_vec(3, 2, 1, vec![0u16, 1, 300, 65535, 7, 9]).unwrap()).unwrap();
    let r = |n: &str| std::fs::read(dir.join(n)).unwrap();
    (r("s.png"), r("s.jpg"), r("s.tif"), r("s16.png"))
}

fn calib() -> StereoCalibration {
    let k = laparo_core::Intrinsics::new(500.0, 501.0, 320.0, 240.0, 640, 480).unwrap();
    StereoCalibration {
        width: 640,
        height: 480,
        left: k,
        left_dist: laparo_core::Distortion::brown_conrady(-0.1, 0.01, 0.001, 0.0, 0.0),
        right: k,
        right_dist: Default::default(),
        r: Matrix3::identity(),
        t_mm: Vector3::new(-5.0, 0.0, 0.0),
    }
}

fn targets(dir: &Path) -> Vec<Target> {
    let (png, jpg, tif, png16) = seed_images(dir);
    let f = Image::from_vec(3, 2, 1, vec![1.5, -2.0, f64::NAN, 0.0, 1e-3, 7.0]).unwrap();
    io::write_npy_f64(dir.join("s.npy"), &f).unwrap();
    io::write_npz_f64(dir.join("s.npz"), &[("a", &f), ("b", &f)]).unwrap();
    io::write_pfm(dir.join("s.pfm"), &f.map(|v| v as f32)).unwrap();
    io::write_exr(dir.join("s.exr"), &f).unwrap();
    let c = calib();
    c.write_json(dir.join("c.json")).unwrap();
    c.write_opencv_yaml(dir.join("c.yaml")).unwrap();
    let tri = TriMesh::new(
        vec![
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(1.0, 0.0, 0.0),
            Vector3::new(0.0, 1.0, 0.0),
            Vector3::new(0.0, 0.0, 1.0),
        ],
        vec![[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]],
    )
    .unwrap();
    let tet = TetMesh::new(tri.vertices.clone(), vec![[0, 1, 2, 3]]).unwrap();
    mesh::write_obj(dir.join("m.obj"), &tri).unwrap();
    mesh::write_ply(dir.join("m.ply"), &tri).unwrap();
    mesh::write_stl(dir.join("m.stl"), &tri, false).unwrap();
    mesh::write_stl(dir.join("ma.stl"), &tri, true).unwrap();
    mesh::write_msh(dir.join("m.msh"), &tet).unwrap();
    mesh::write_vtk(dir.join("m.vtk"), &tet).unwrap();
    let r = |n: &str| std::fs::read(dir.join(n)).unwrap();
    let b = |s: &str| s.as_bytes().to_vec();
    let endovis = "Width: 1280\nHeight: 1024\nCamera-0-F: 1084.21 1084.05 // f\nCamera-0-C: 580.02 506.79\n\
Camera-0-K: -0.00069 0.00195 0.00018 0.00000 0.00000\nCamera-1-F: 1083.43 1083.22\nCamera-1-C: 680.91 505.81\n\
Camera-1-K: -0.00085 0.00245 0.00004 0.00000 0.00000\nExtrinsic-Omega: -0.0002 -0.0011 -0.0000\nExtrinsic-T: -4.3499 0.0333 -0.0369\n";
    let middlebury = "cam0=[3979.911 0 1244.772; 0 3979.911 1019.507; 0 0 1]\ncam1=[3979.911 0 1369.115; 0 3979.911 1019.507; 0 0 1]\ndoffs=124.343\nbaseline=193.001\nwidth=2964\nheight=2000\nndisp=270\n";
    let ros = "image_width: 640\nimage_height: 480\ncamera_matrix:\n  rows: 3\n  cols: 3\n  data: [500, 0, 320, 0, 500, 240, 0, 0, 1]\n\
distortion_model: plumb_bob\ndistortion_coefficients:\n  rows: 1\n  cols: 5\n  data: [0.1, 0, 0, 0, 0]\n\
rectification_matrix:\n  rows: 3\n  cols: 3\n  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]\nprojection_matrix:\n  rows: 3\n  cols: 4\n  data: [500, 0, 320, -25, 0, 500, 240, 0, 0, 0, 1, 0]\n";
    let p2ilf = r#"{"projection": "frame", "width": "1920", "height": "1080", "fx": "9.52e+02", "fy": "9.52e+02", "cx": "8.84e+02", "cy": "5.53e+02", "skew": "0.0", "k1": "-2.3e-01", "k2": "3.4e-01", "k3": "-2.3e-01", "k4": "0", "p1": "0", "p2": "0"}"#;
    let kjson =
        r#"{"K": [[500, 0, 320], [0, 500, 240], [0, 0, 1]], "width": 640, "height": 480, "dist": [0.1, 0, 0, 0, 0]}"#;
    vec![
        Target { name: "opencv_yaml", file: "f.yaml", parse: |p| StereoCalibration::read(p).is_ok(), seeds: vec![r("c.yaml"), b(ros), b("%YAML:1.0\na: [ 1, [ 2, { b: 3 } ] ]\nm: !!opencv-nd-matrix\n   sizes: [ 2, 1 ]\n   dt: d\n   data: [ 1., 2. ]\n")] },
        Target { name: "filestorage", file: "f.yml", parse: |p| io::opencv_yaml::read_filestorage(p).is_ok(), seeds: vec![r("c.yaml"), b(ros)] },
        Target { name: "calib_json", file: "f.json", parse: |p| StereoCalibration::read(p).is_ok(), seeds: vec![r("c.json")] },
        Target { name: "calib_txt", file: "f.txt", parse: |p| StereoCalibration::read(p).is_ok(), seeds: vec![b(endovis), b(middlebury)] },
        Target { name: "intrinsics_json", file: "k.json", parse: |p| io::read_camera(p).is_ok(), seeds: vec![b(p2ilf), b(kjson)] },
        Target { name: "intrinsics_yaml", file: "k.yaml", parse: |p| io::read_camera(p).is_ok(), seeds: vec![b(ros)] },
        Target { name: "intrinsics_txt", file: "cameras.txt", parse: |p| io::read_camera(p).is_ok(), seeds: vec![b("# c\n1 OPENCV 640 480 500 500 320 240 0.1 0 0 0\n2 PINHOLE 10 10 1 1 5 5\n"), b(endovis)] },
        Target { name: "npy", file: "a.npy", parse: |p| io::read_npy(p).is_ok(), seeds: vec![r("s.npy")] },
        Target { name: "npz", file: "a.npz", parse: |p| io::read_npz(p, None).is_ok(), seeds: vec![r("s.npz")] },
        Target { name: "pfm", file: "a.pfm", parse: |p| io::read_pfm(p).is_ok(), seeds: vec![r("s.pfm")] },
        Target { name: "exr", file: "a.exr", parse: |p| io::read_exr(p).is_ok(), seeds: vec![r("s.exr")] },
        Target { name: "png", file: "a.png", parse: |p| io::read_png16(p).is_ok() | io::read_mask(p).is_ok(), seeds: vec![png.clone(), png16] },
        Target { name: "jpeg", file: "a.jpg", parse: |p| io::read_image(p).is_ok(), seeds: vec![jpg] },
        Target { name: "tiff", file: "a.tif", parse: |p| io::read_tiff_f32(p).is_ok() | io::read_image(p).is_ok(), seeds: vec![tif] },
        Target { name: "obj", file: "m.obj", parse: |p| mesh::read_obj(p).is_ok(), seeds: vec![r("m.obj")] },
        Target { name: "ply", file: "m.ply", parse: |p| mesh::read_ply_with_colors(p).is_ok(), seeds: vec![r("m.ply"), b("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")] },
        Target { name: "stl", file: "m.stl", parse: |p| mesh::read_stl(p).is_ok(), seeds: vec![r("m.stl"), r("ma.stl")] },
        Target { name: "msh", file: "m.msh", parse: |p| mesh::read_msh_mixed(p).is_ok(), seeds: vec![r("m.msh")] },
        Target { name: "vtk", file: "m.vtk", parse: |p| mesh::read_vtk_mixed(p).is_ok(), seeds: vec![r("m.vtk")] },
    ]
}

const SPECIAL: &[&[u8]] = &[
    b"[",
    b"{",
    b"]",
    b"}",
    b"(",
    b")",
    b"\"",
    b"'",
    b",",
    b":",
    b"\n",
    b" ",
    b"-",
    b"0",
    b"9",
    b"\0",
    b"\xff",
    b"nan",
    b"inf",
    b"-1",
    b"1e308",
    b"18446744073709551615",
    b"9223372036854775807",
    b"0x10",
    b"1_000",
    b"4294967296",
    b"100000",
    b"!!opencv-matrix",
    b"True",
    b"L",
];

fn mutate(rng: &mut ChaCha8Rng, input: &[u8]) -> Vec<u8> {
    let mut v = input.to_vec();
    let n = rng.gen_range(1..=4);
    for _ in 0..n {
        let len = v.len();
        match rng.gen_range(0..9) {
            0 if len > 0 => {
                let i = rng.gen_range(0..len);
                v[i] ^= 1 << rng.gen_range(0..8);
            }
            1 if len > 0 => {
                let i = rng.gen_range(0..len);
                v[i] = rng.gen();
            }
            2 => {
                let i = rng.gen_range(0..=len);
                let s = SPECIAL[rng.gen_range(0..SPECIAL.len())];
                v.splice(i..i, s.iter().copied());
            }
            3 if len > 0 => {
                let i = rng.gen_range(0..len);
                let j = (i + rng.gen_range(1..=16)).min(len);
                v.drain(i..j);
            }
            4 if len > 0 => {
                let i = rng.gen_range(0..len);
                let j = (i + rng.gen_range(1..=32)).min(len);
                let chunk: Vec<u8> = v[i..j].to_vec();
                let k = rng.gen_range(0..=v.len());
                v.splice(k..k, chunk);
            }
            5 if len > 0 => {
                v.truncate(rng.gen_range(0..len));
            }
            6 => {
                // Deep nesting or a long run of one special token.
                let i = rng.gen_range(0..=len);
                let s = SPECIAL[rng.gen_range(0..6)];
                let reps = rng.gen_range(10..3000);
                let run: Vec<u8> = s.iter().copied().cycle().take(s.len() * reps).collect();
                v.splice(i..i, run);
            }
            7 if len > 0 => {
                // Replace a digit run by a huge or negative number.
                let i = rng.gen_range(0..len);
                if v[i].is_ascii_digit() {
                    let mut j = i;
                    while j < v.len() && v[j].is_ascii_digit() {
                        j += 1;
                    }
                    let s = SPECIAL[rng.gen_range(18..27)];
                    v.splice(i..j, s.iter().copied());
                }
            }
            _ if len > 3 => {
                // Overwrite a little-endian u16/u32 with an extreme value (binary headers).
                let i = rng.gen_range(0..len - 3);
                let x: u32 = [0u32, 1, 0xffff, 0x7fff_ffff, 0xffff_ffff, 1 << 20][rng.gen_range(0..6)];
                v[i..i + 4].copy_from_slice(&x.to_le_bytes());
            }
            _ => {}
        }
    }
    v
}

struct Outcome {
    iterations: u64,
    ok: u64,
    slowest: Duration,
    panics: Vec<String>,
    wall_secs: f64,
    cpu_secs: f64,
}

fn fuzz_target(t: &Target, dir: &Path, seed: u64, budget: Budget) -> Outcome {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let path = dir.join(t.file);
    let start = Instant::now();
    let cpu0 = thread_cpu_secs().unwrap_or(0.0);
    let mut out =
        Outcome { iterations: 0, ok: 0, slowest: Duration::ZERO, panics: Vec::new(), wall_secs: 0.0, cpu_secs: 0.0 };
    let mut corpus = t.seeds.clone();
    loop {
        match budget {
            Budget::Iterations(n) if out.iterations >= n => break,
            Budget::Seconds(s) if start.elapsed().as_secs_f64() >= s => break,
            Budget::CpuSeconds(s) if thread_cpu_secs().unwrap_or_else(|| start.elapsed().as_secs_f64()) - cpu0 >= s => {
                break
            }
            _ => {}
        }
        let base = &corpus[rng.gen_range(0..corpus.len())];
        let input = if out.iterations < t.seeds.len() as u64 { base.clone() } else { mutate(&mut rng, base) };
        std::fs::write(&path, &input).unwrap();
        let t0 = Instant::now();
        let r = std::panic::catch_unwind(AssertUnwindSafe(|| (t.parse)(&path)));
        let dt = t0.elapsed();
        out.slowest = out.slowest.max(dt);
        match r {
            Ok(true) => {
                out.ok += 1;
                // Inputs that still parse are good bases for deeper mutations.
                if corpus.len() < 64 && input.len() < 1 << 16 {
                    corpus.push(input);
                }
            }
            Ok(false) => {}
            Err(e) => {
                let msg = e
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| e.downcast_ref::<&str>().map(|s| s.to_string()))
                    .unwrap_or_default();
                let keep = std::env::temp_dir().join(format!("laparo-fuzz-{}-{}.bin", t.name, out.iterations));
                let _ = std::fs::write(&keep, &input);
                out.panics.push(format!("{}: panic '{msg}' (input saved to {})", t.name, keep.display()));
            }
        }
        out.iterations += 1;
    }
    out.wall_secs = start.elapsed().as_secs_f64();
    out.cpu_secs = thread_cpu_secs().map_or(f64::NAN, |c| c - cpu0);
    out
}

#[derive(Clone, Copy)]
enum Budget {
    Iterations(u64),
    Seconds(f64),
    CpuSeconds(f64),
}

/// CPU time of the calling thread (s), from `/proc/thread-self/schedstat` (Linux; `None` elsewhere).
fn thread_cpu_secs() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    s.split_whitespace().next()?.parse::<u64>().ok().map(|ns| ns as f64 * 1e-9)
}

#[test]
fn every_parser_survives_mutated_inputs() {
    let dir = tempfile::tempdir().unwrap();
    let secs = |k: &str| std::env::var(k).ok().and_then(|s| s.parse::<f64>().ok());
    let budget = match (secs("LAPARO_FUZZ_CPU_SECS"), secs("LAPARO_FUZZ_SECS")) {
        (Some(s), _) => Budget::CpuSeconds(s),
        (None, Some(s)) => Budget::Seconds(s),
        (None, None) => {
            Budget::Iterations(std::env::var("LAPARO_FUZZ_ITERS").ok().and_then(|s| s.parse().ok()).unwrap_or(60))
        }
    };
    let only = std::env::var("LAPARO_FUZZ_TARGET").ok();
    let seed: u64 = std::env::var("LAPARO_FUZZ_SEED").ok().and_then(|s| s.parse().ok()).unwrap_or(0x1a9a_0010);
    // Panics are caught and reported; keep the default hook quiet meanwhile.
    let hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let mut panics = Vec::new();
    for (i, t) in targets(dir.path()).iter().enumerate() {
        if only.as_deref().is_some_and(|o| o != t.name) {
            continue;
        }
        let o = fuzz_target(t, dir.path(), seed.wrapping_add(i as u64), budget);
        eprintln!(
            "fuzz {:16} iterations {:>9}  parsed {:>7}  slowest {:>8.1} ms  panics {}  cpu {:.0} s  wall {:.0} s",
            t.name,
            o.iterations,
            o.ok,
            o.slowest.as_secs_f64() * 1e3,
            o.panics.len(),
            o.cpu_secs,
            o.wall_secs
        );
        panics.extend(o.panics.into_iter().take(5));
    }
    std::panic::set_hook(hook);
    assert!(panics.is_empty(), "{}", panics.join("\n"));
}
