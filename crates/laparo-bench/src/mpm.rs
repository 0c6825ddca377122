//! `laparo-bench mpm`: forward and forward+backward wall time per iteration of the DiffTaichi
//! RODS box problem (`../shared/bench/taichi_mpm/mpm{2,3}d_rods.py`), with the peak RSS
//! (formerly `laparo mpm bench`).
use crate::timing::{med, peak_rss_mb};
use anyhow::{bail, Result};
use clap::Args;
use laparo_mpm::reference::rods_scene;
use laparo_mpm::{simulate_with_gradient_in, GradientWorkspace, Loss, Scene};
use std::time::Instant;

/// Options of `laparo-bench mpm` (those of the former `laparo mpm bench`).
#[derive(Args)]
pub struct BenchArgs {
    /// 2 or 3.
    #[arg(long, default_value_t = 3)]
    pub dim: usize,
    /// Approximate particle count (default: thesis 6800 in 3D, 6400 in 2D).
    #[arg(long)]
    pub particles: Option<usize>,
    /// Grid cells per axis.
    #[arg(long, default_value_t = 120)]
    pub n_grid: usize,
    /// Horizon T.
    #[arg(long, default_value_t = 200)]
    pub steps: usize,
    /// Timed repetitions (median reported).
    #[arg(long, default_value_t = 5)]
    pub repeats: usize,
    /// Rayon threads (0 = all cores).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

fn time_scene<const D: usize, L: Loss<D>>(scene: &Scene<D>, loss: &L, repeats: usize) -> Result<(f64, f64, f64)> {
    let mut fwd = Vec::new();
    let mut lossv = 0.0;
    for _ in 0..repeats.max(1) {
        let t0 = Instant::now();
        let sim = laparo_mpm::simulate(scene)?;
        let mut g = vec![laparo_mpm::Vector::<D>::zeros(); scene.n_particles()];
        lossv = loss.evaluate(scene.steps, &sim.final_state.x, &mut g);
        fwd.push(t0.elapsed().as_secs_f64());
    }
    let mut fb = Vec::new();
    let mut ws = GradientWorkspace::new();
    for _ in 0..repeats.max(1) {
        let t0 = Instant::now();
        let g = simulate_with_gradient_in(&mut ws, scene, loss)?;
        fb.push(t0.elapsed().as_secs_f64());
        if (g.loss - lossv).abs() > 1e-9 * lossv.abs() {
            bail!("forward and forward+backward losses differ");
        }
    }
    Ok((med(fwd), med(fb), lossv))
}

pub fn run(a: BenchArgs) -> Result<()> {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(a.threads).build()?;
    pool.install(|| bench(a.dim, a.particles, a.n_grid, a.steps, a.repeats, a.json))
}

fn bench(dim: usize, particles: Option<usize>, n_grid: usize, steps: usize, repeats: usize, json: bool) -> Result<()> {
    let dt = 2e-4;
    let (fwd, fb, n, lossv) = match dim {
        2 => {
            let base = [80usize, 80];
            let s = particles.map(|p| (p as f64 / 6400.0).sqrt()).unwrap_or(1.0);
            let counts = base.map(|c| ((c as f64 * s).round() as usize).max(2));
            let (scene, loss) = rods_scene::<2>(counts, n_grid, steps, dt);
            scene.validate()?;
            let (f, b, l) = time_scene(&scene, &loss, repeats)?;
            (f, b, scene.n_particles(), l)
        }
        3 => {
            let base = [16usize, 25, 17];
            let s = particles.map(|p| (p as f64 / 6800.0).cbrt()).unwrap_or(1.0);
            let counts = base.map(|c| ((c as f64 * s).round() as usize).max(2));
            let (scene, loss) = rods_scene::<3>(counts, n_grid, steps, dt);
            scene.validate()?;
            let (f, b, l) = time_scene(&scene, &loss, repeats)?;
            (f, b, scene.n_particles(), l)
        }
        d => bail!("--dim must be 2 or 3 (got {d})"),
    };
    let rss = peak_rss_mb();
    if json {
        println!(
            "{}",
            serde_json::json!({"dim": dim, "particles": n, "n_grid": n_grid, "steps": steps, "forward_s": fwd,
                "forward_backward_s": fb, "peak_rss_mb": rss, "loss": lossv, "threads": rayon::current_num_threads()})
        );
    } else {
        println!(
            "{dim}D, {n} particles, n_grid {n_grid}, T = {steps}, {} threads: forward {fwd:.3} s, forward+backward {fb:.3} s per iteration (median of {repeats}); peak RSS {rss:.0} MiB; loss {lossv:.6e}",
            rayon::current_num_threads()
        );
    }
    Ok(())
}
