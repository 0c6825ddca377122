//! Quick timing of the RODS box problem without the CLI (development aid): `cargo run --release
//! -p laparo-mpm --example mpm_bench_quick -- DIM REPEATS`.
use laparo_mpm::reference::rods_scene;
use laparo_mpm::*;
use std::time::Instant;

fn run<const D: usize>(counts: [usize; D], reps: usize) {
    let (scene, loss) = rods_scene::<D>(counts, 120, 200, 2e-4);
    let mut fwd = Vec::new();
    let mut fb = Vec::new();
    let mut ws = GradientWorkspace::new();
    for _ in 0..reps {
        let t = Instant::now();
        simulate(&scene).unwrap();
        fwd.push(t.elapsed().as_secs_f64());
        let t = Instant::now();
        simulate_with_gradient_in(&mut ws, &scene, &loss).unwrap();
        fb.push(t.elapsed().as_secs_f64());
    }
    fwd.sort_by(f64::total_cmp);
    fb.sort_by(f64::total_cmp);
    println!(
        "{D}D forward min {:.3} med {:.3}  fwd+bwd min {:.3} med {:.3}",
        fwd[0],
        fwd[reps / 2],
        fb[0],
        fb[reps / 2]
    );
}

fn main() {
    let a: Vec<usize> = std::env::args().skip(1).map(|s| s.parse().unwrap()).collect();
    let reps = a.get(1).copied().unwrap_or(3);
    if a.first().copied().unwrap_or(3) == 2 {
        run::<2>([80, 80], reps)
    } else {
        run::<3>([16, 25, 17], reps)
    }
}
