//! Stage profile of one CPC frame on raw scene files (development tool):
//! `cargo run --release -p laparo-cpc --example cpc_profile -- DEPTH.f64 IMG.u8 [STEP] [REPEATS] [LAMBDA]`
//! (640×480 little-endian f64 depth in mm, NaN outside the ROI; 640×480×3 u8 image).
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

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let a: Vec<String> = std::env::args().collect();
    let depth: Vec<f64> =
        std::fs::read(&a[1]).unwrap().chunks_exact(8).map(|c| f64::from_le_bytes(c.try_into().unwrap())).collect();
    let img = std::fs::read(&a[2]).unwrap();
    let step: usize = a.get(3).map_or(4, |s| s.parse().unwrap());
    let reps: usize = a.get(4).map_or(9, |s| s.parse().unwrap());
    let lambda: f64 = a.get(5).map_or(0.9, |s| s.parse().unwrap());
    let depth = DepthMap::new(640, 480, DepthUnit::Mm, depth).unwrap();
    let image = Image { width: 640, height: 480, channels: 3, data: img };
    let roi = depth.valid_mask();
    let k = Intrinsics::new(500.0, 500.0, 320.0, 240.0, 640, 480).unwrap();
    let mp = MeshParams { grid_step_px: step, ..MeshParams::default() };
    let conf = ConformalParams::default();
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
            median(tr), sys.topology().factor_len());
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
            print!("  {n} {:.2}", median(v));
        }
        println!();
    }
}
