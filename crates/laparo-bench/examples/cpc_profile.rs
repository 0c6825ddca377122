//! Stage profile of one CPC frame on raw scene files (development tool):
//! `cargo run --release -p laparo-bench --example cpc_profile -- DEPTH.f64 IMG.u8 [STEP] [REPEATS] [LAMBDA]`
//! (640×480 little-endian f64 depth in mm, NaN outside the ROI; 640×480×3 u8 image), or
//! `... -- scene [STEP] [REPEATS] [LAMBDA]` for the rendered bumpy bowl (`scene::bumpy_bowl_spec`).
//!
//! Environment: `CPC_NOREF` skips the real-system reference, `CPC_NOSPLIT` solves the whole system,
//! `CPC_HASH` prints FNV hashes of every stage's output (mesh, solution, warp, image, maps) to check
//! that an optimisation leaves the results bitwise identical, `CPC_STAGES=N` times the mesh,
//! next-frame assembly, `Warp::new` and `warp_image` alone, N times each (wall and CPU medians;
//! `CPC_ONLY=<stage name>` times one of them only, e.g. for `perf record`).
use laparo_core::camera::Intrinsics;
use laparo_core::depth::{DepthMap, DepthUnit};
use laparo_core::image::Image;
use laparo_cpc::{ConformalParams, CpcMesh, CpcSolver, CpcSystem, MeshParams, Warp};
use std::time::Instant;

fn clock_ns(id: libc::clockid_t) -> f64 {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: `ts` is a valid, writable timespec.
    unsafe { libc::clock_gettime(id, &mut ts) };
    ts.tv_sec as f64 * 1e9 + ts.tv_nsec as f64
}

/// CPU time of the calling thread (ns).
fn cpu_ns() -> f64 {
    clock_ns(libc::CLOCK_THREAD_CPUTIME_ID)
}

/// CPU time of the whole process (ns, all threads).
fn proc_cpu_ns() -> f64 {
    clock_ns(libc::CLOCK_PROCESS_CPUTIME_ID)
}

fn med_of(mut v: Vec<f64>) -> f64 {
    laparo_core::stats::median(&mut v)
}

fn main() {
    let mut a: Vec<String> = std::env::args().collect();
    let (depth, image) = if a.get(1).map(String::as_str) == Some("scene") {
        let sc = laparo_cpc::scene::bumpy_bowl_spec().render().unwrap();
        a.insert(1, String::new());
        (sc.depth, sc.image)
    } else {
        let depth: Vec<f64> =
            std::fs::read(&a[1]).unwrap().chunks_exact(8).map(|c| f64::from_le_bytes(c.try_into().unwrap())).collect();
        let img = std::fs::read(&a[2]).unwrap();
        (
            DepthMap::new(640, 480, DepthUnit::Mm, depth).unwrap(),
            Image { width: 640, height: 480, channels: 3, data: img },
        )
    };
    let step: usize = a.get(3).map_or(4, |s| s.parse().unwrap());
    let reps: usize = a.get(4).map_or(9, |s| s.parse().unwrap());
    let lambda: f64 = a.get(5).map_or(0.9, |s| s.parse().unwrap());
    let roi = depth.valid_mask();
    let k = Intrinsics::new(500.0, 500.0, 320.0, 240.0, 640, 480).unwrap();
    let mp = MeshParams { grid_step_px: step, ..MeshParams::default() };
    let conf = ConformalParams::default();
    if std::env::var("CPC_HASH").is_ok() {
        print_hashes(&roi, &depth, &k, &mp, &conf, &image, lambda);
        return;
    }
    if let Ok(n) = std::env::var("CPC_STAGES") {
        stage_times(&roi, &depth, &k, &mp, &conf, &image, lambda, n.parse().unwrap());
        return;
    }
    let mut solver = CpcSolver::new();
    let names = [
        "mesh",
        "asm terms",
        "asm values",
        "asm symbolic",
        "solve",
        "solve CPU",
        "warp new",
        "warp image",
        "total",
        "CPU mesh",
        "CPU asm",
        "CPU warp new",
        "CPU warp image",
        "CPU total",
    ];
    if std::env::var("CPC_NOREF").is_err() {
        // Reference: the real interleaved system (the previous solver), same session.
        let mesh = CpcMesh::build(&roi, &depth, &k, &mp).unwrap();
        let sys = CpcSystem::assemble(&mesh, &conf).unwrap();
        let pz = sys.solve(lambda).unwrap();
        let _ = sys.pattern();
        let mut tr = vec![];
        let mut pr = vec![];
        for _ in 0..reps {
            let t = cpu_ns();
            let (_, _, diag) = sys.pattern();
            let mut vals: Vec<f64> = sys.conformal_values().iter().map(|v| lambda * v).collect();
            let w = sys.displacement_weights();
            for (u, &pos) in diag.iter().enumerate() {
                vals[pos] += (1.0 - lambda) * w[u / 2];
            }
            let mut rhs: Vec<f64> = mesh
                .p_init
                .iter()
                .zip(w)
                .flat_map(|(p, &w)| [(1.0 - lambda) * w * p[0], (1.0 - lambda) * w * p[1]])
                .collect();
            sys.factor_solve(&vals, &mut rhs).unwrap();
            tr.push((cpu_ns() - t) * 1e-6);
            pr = rhs;
        }
        let dmax = pz
            .iter()
            .enumerate()
            .map(|(i, p)| (p[0] - pr[2 * i]).abs().max((p[1] - pr[2 * i + 1]).abs()))
            .fold(0.0, f64::max);
        println!("real interleaved solve (previous solver) {:.2} ms CPU; max |complex − real| = {dmax:.3e} px; complex factor {} entries",
            med_of(tr), sys.topology().factor_len());
    }
    for pass in ["first frame", "same topology"] {
        let mut t: Vec<Vec<f64>> = vec![vec![]; names.len()];
        for _ in 0..reps {
            if pass == "first frame" {
                solver.clear();
            }
            let k0 = proc_cpu_ns();
            let t0 = Instant::now();
            let mesh = CpcMesh::build(&roi, &depth, &k, &mp).unwrap();
            let t1 = Instant::now();
            let k1 = proc_cpu_ns();
            let mut sys: CpcSystem = solver.assemble(&mesh, &conf).unwrap();
            sys.set_domain_split(std::env::var("CPC_NOSPLIT").is_err());
            let t2 = Instant::now();
            let k2 = proc_cpu_ns();
            let c2 = cpu_ns();
            let p = sys.solve(lambda).unwrap();
            let c3 = cpu_ns();
            let t3 = Instant::now();
            let k3 = proc_cpu_ns();
            let w = Warp::new(&mesh, p, 640, 480).unwrap();
            let t4 = Instant::now();
            let k4 = proc_cpu_ns();
            let (wi, _) = w.warp_image(&image).unwrap();
            let t5 = Instant::now();
            let k5 = proc_cpu_ns();
            if std::env::var("CPC_CANVAS").is_ok() {
                let (_, m) = w.warp_image(&image).unwrap();
                eprintln!("canvas {}x{}, {} covered", w.width, w.height, m.data.iter().filter(|&&b| b).count());
            }
            if let Ok(f) = std::env::var("CPC_DUMP") {
                let b: Vec<u8> =
                    w.p_flat.iter().flat_map(|q| [q[0].to_le_bytes(), q[1].to_le_bytes()]).flatten().collect();
                std::fs::write(f, b).unwrap();
            }
            std::hint::black_box(wi);
            let ms = |a: Instant, b: Instant| (b - a).as_secs_f64() * 1e3;
            let v = [
                ms(t0, t1),
                sys.assembly_ms[0],
                sys.assembly_ms[1],
                sys.assembly_ms[2],
                ms(t2, t3),
                (c3 - c2) * 1e-6,
                ms(t3, t4),
                ms(t4, t5),
                ms(t0, t5),
                (k1 - k0) * 1e-6,
                (k2 - k1) * 1e-6,
                (k4 - k3) * 1e-6,
                (k5 - k4) * 1e-6,
                (k5 - k0) * 1e-6,
            ];
            for (i, x) in v.iter().enumerate() {
                t[i].push(*x);
            }
        }
        print!("{pass:>14}:");
        for (n, v) in names.iter().zip(t) {
            print!("  {n} {:.2}", med_of(v));
        }
        println!();
    }
}

/// FNV-1a hash of a byte stream.
fn fnv(bytes: impl IntoIterator<Item = u8>) -> u64 {
    bytes.into_iter().fold(0xcbf29ce484222325u64, |h, b| (h ^ b as u64).wrapping_mul(0x100000001b3))
}

fn fnv_f64<'a>(v: impl IntoIterator<Item = &'a f64>) -> u64 {
    fnv(v.into_iter().flat_map(|x| x.to_bits().to_le_bytes()))
}

/// Hashes of every stage's output (bitwise identity checks across optimisations).
fn print_hashes(
    roi: &laparo_core::image::Mask,
    depth: &DepthMap,
    k: &Intrinsics,
    mp: &MeshParams,
    conf: &ConformalParams,
    image: &Image<u8>,
    lambda: f64,
) {
    let mesh = CpcMesh::build(roi, depth, k, mp).unwrap();
    println!("mesh p_init  {:016x}", fnv_f64(mesh.p_init.iter().flatten()));
    println!("mesh x3d     {:016x}", fnv_f64(mesh.x3d.iter().flat_map(|x| x.iter())));
    println!("mesh faces   {:016x}", fnv(mesh.faces.iter().flatten().flat_map(|i| i.to_le_bytes())));
    println!("mesh cells   {:016x}", fnv(mesh.cell_faces.iter().flatten().flat_map(|i| i.to_le_bytes())));
    println!("mesh comps   {:016x}", fnv(mesh.face_component.iter().flat_map(|i| i.to_le_bytes())));
    println!("mesh report  {}", serde_json::to_string(&mesh.report).unwrap());
    let mut solver = CpcSolver::new();
    let sys = solver.assemble(&mesh, conf).unwrap();
    let p = sys.solve(lambda).unwrap();
    println!("solution     {:016x}", fnv_f64(p.iter().flatten()));
    let sys2 = solver.assemble(&mesh, conf).unwrap();
    let p2 = sys2.solve(lambda).unwrap();
    println!("solution 2   {:016x} (topology reused: {})", fnv_f64(p2.iter().flatten()), sys2.topology_reused);
    let (ec, ed) = sys.energies(&p);
    println!("energies     {:016x}", fnv_f64(&[ec, ed]));
    let w = Warp::new(&mesh, p, 640, 480).unwrap();
    println!("canvas       {}x{} origin {:?}", w.width, w.height, w.origin);
    let (wi, m) = w.warp_image(image).unwrap();
    println!("warped       {:016x}", fnv(wi.data.iter().copied()));
    println!(
        "mask         {:016x} ({} px)",
        fnv(m.data.iter().map(|&b| b as u8)),
        m.data.iter().filter(|&&b| b).count()
    );
    let grey = Image { width: 640, height: 480, channels: 1, data: image.data.iter().step_by(3).copied().collect() };
    let (wg, _) = w.warp_image(&grey).unwrap();
    println!("warped grey  {:016x}", fnv(wg.data.iter().copied()));
    let maps = w.maps();
    println!("backward     {:016x}", fnv_f64(&maps.backward.data));
    println!("forward      {:016x}", fnv_f64(&maps.forward.data));
    let pts: Vec<f64> = (0..2000)
        .flat_map(|i| {
            let (x, y) = ((i * 37 % 640) as f64 + 0.25, (i * 91 % 480) as f64 + 0.5);
            let a = w.original_to_warped(x, y).unwrap_or([-1.0; 2]);
            let b = w.warped_to_original(x, y).unwrap_or([-1.0; 2]);
            let c = w.original_to_warped_affine(x, y).unwrap_or([-1.0; 2]);
            [a[0], a[1], b[0], b[1], c[0], c[1]]
        })
        .collect();
    println!("points       {:016x}", fnv_f64(&pts));
    println!("angle err    {}", laparo_cpc::metrics::angle_error_deg(&w.p_flat, &mesh.x3d, &mesh.faces));
    println!("delta area   {}", laparo_cpc::metrics::delta_area(&w.p_flat, &mesh.p_init, &mesh.faces));
}

/// Each stage alone, `n` times: median wall and process CPU (ms).
#[allow(clippy::too_many_arguments)]
fn stage_times(
    roi: &laparo_core::image::Mask,
    depth: &DepthMap,
    k: &Intrinsics,
    mp: &MeshParams,
    conf: &ConformalParams,
    image: &Image<u8>,
    lambda: f64,
    n: usize,
) {
    let only = std::env::var("CPC_ONLY").ok();
    let time = |name: &str, f: &mut dyn FnMut()| {
        if only.as_deref().is_some_and(|o| o != name) {
            return;
        }
        let (mut wall, mut cpu) = (vec![], vec![]);
        for _ in 0..n {
            let (t, c) = (Instant::now(), proc_cpu_ns());
            f();
            cpu.push((proc_cpu_ns() - c) * 1e-6);
            wall.push(t.elapsed().as_secs_f64() * 1e3);
        }
        println!("{name:>12}: wall {:.3} ms (min {:.3})  CPU {:.3} ms", med_of(wall.clone()), vmin(&wall), med_of(cpu));
    };
    let mesh = CpcMesh::build(roi, depth, k, mp).unwrap();
    let mut solver = CpcSolver::new();
    let p = solver.assemble(&mesh, conf).unwrap().solve(lambda).unwrap();
    let w = Warp::new(&mesh, p.clone(), 640, 480).unwrap();
    time("mesh", &mut || {
        std::hint::black_box(CpcMesh::build(roi, depth, k, mp).unwrap());
    });
    time("assembly", &mut || {
        std::hint::black_box(solver.assemble(&mesh, conf).unwrap());
    });
    time("warp new", &mut || {
        std::hint::black_box(Warp::new(&mesh, p.clone(), 640, 480).unwrap());
    });
    time("warp image", &mut || {
        std::hint::black_box(w.warp_image(image).unwrap());
    });
}

fn vmin(v: &[f64]) -> f64 {
    v.iter().cloned().fold(f64::INFINITY, f64::min)
}
