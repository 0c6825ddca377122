//! Quick timing of the RODS box problem without the CLI (development aid): `cargo run --release
//! -p laparo-bench --example mpm_bench_quick -- DIM REPEATS [THREADS [STEPS [SEGMENT]]]`. Besides wall times it prints
//! the process CPU time per forward+backward iteration (less sensitive to a loaded machine) and the peak RSS;
//! SEGMENT > 1 sets `Scene::checkpoint_segment` (two-level checkpointing of the adjoint).
use laparo_mpm::reference::rods_scene;
use laparo_mpm::*;
use std::time::Instant;

/// Process CPU time (user + system) in seconds, from /proc/self/stat (10 ms ticks).
fn cpu_s() -> f64 {
    let s = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let rest = s.rsplit_once(')').map(|(_, r)| r).unwrap_or("");
    let f: Vec<&str> = rest.split_whitespace().collect();
    let t = |i: usize| f.get(i).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0);
    (t(11) + t(12)) / 100.0
}

fn run<const D: usize>(counts: [usize; D], reps: usize, steps: usize, segment: usize) {
    let (mut scene, loss) = rods_scene::<D>(counts, 120, steps, 2e-4);
    scene.checkpoint_segment = segment;
    let mut fwd = Vec::new();
    let mut fb = Vec::new();
    let mut ws = GradientWorkspace::new();
    let (mut cpu_f, mut cpu_fb) = (0.0, 0.0);
    let mut g = None;
    for _ in 0..reps {
        let (t, c) = (Instant::now(), cpu_s());
        simulate(&scene).unwrap();
        fwd.push(t.elapsed().as_secs_f64());
        cpu_f += cpu_s() - c;
        let (t, c) = (Instant::now(), cpu_s());
        g = Some(simulate_with_gradient_in(&mut ws, &scene, &loss).unwrap());
        fb.push(t.elapsed().as_secs_f64());
        cpu_fb += cpu_s() - c;
    }
    let (fwd_min, fb_min) =
        (fwd.iter().cloned().fold(f64::INFINITY, f64::min), fb.iter().cloned().fold(f64::INFINITY, f64::min));
    let (fwd_med, fb_med) = (laparo_core::stats::median(&mut fwd), laparo_core::stats::median(&mut fb));
    let g = g.unwrap();
    let checksum: f64 = g.d_velocities.iter().map(|v| v.sum()).sum::<f64>() + g.d_youngs_modulus;
    println!(
        "{D}D segment {segment}: forward min {:.3} med {:.3} cpu {:.3}  fwd+bwd min {:.3} med {:.3} cpu {:.3}  loss {:e} grad checksum {:e}  peak RSS {:.0} MiB",
        fwd_min,
        fwd_med,
        cpu_f / reps as f64,
        fb_min,
        fb_med,
        cpu_fb / reps as f64,
        g.loss,
        checksum,
        laparo_register::pipeline::peak_memory_mib().unwrap_or(f64::NAN)
    );
}

fn main() {
    let a: Vec<usize> = std::env::args().skip(1).map(|s| s.parse().unwrap()).collect();
    let reps = a.get(1).copied().unwrap_or(3);
    let steps = a.get(3).copied().unwrap_or(200);
    let segment = a.get(4).copied().unwrap_or(0);
    // As `laparo-bench mpm`: run inside the pool (THREADS, 0 = all cores).
    let pool = rayon::ThreadPoolBuilder::new().num_threads(a.get(2).copied().unwrap_or(0)).build().unwrap();
    pool.install(|| {
        if a.first().copied().unwrap_or(3) == 2 {
            run::<2>([80, 80], reps, steps, segment)
        } else {
            run::<3>([16, 25, 17], reps, steps, segment)
        }
    })
}
