//! `laparo mpm ...`: differentiable MPM simulation (thesis §5.2.3–5.2.4, §5.3.2).
use anyhow::{bail, Context, Result};
use clap::Subcommand;
use indicatif::{ProgressBar, ProgressStyle};
use laparo_mpm::reference::{rods_scene, TaichiFixture};
use laparo_mpm::render::{ply_bytes, render_particles_2d};
use laparo_mpm::scene_file::{load_scene_file, LoadedScene};
use laparo_mpm::{
    diagnostics, simulate_observed, simulate_with_gradient_in, GradientWorkspace, Loss, ParticleState, Scene,
};
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Subcommand)]
pub enum MpmCmd {
    /// Simulate a scene (TOML) and write particle frames and an energy/momentum log.
    Simulate {
        /// Scene description (TOML; see crates/laparo-mpm/README.md).
        #[arg(long)]
        scene: PathBuf,
        /// Output folder.
        #[arg(long)]
        out: PathBuf,
        /// Write a frame every N steps (default: 20 frames over the horizon).
        #[arg(long)]
        every: Option<usize>,
    },
    /// Forward and forward+backward wall time per iteration on the DiffTaichi RODS box problem.
    Bench {
        /// 2 or 3.
        #[arg(long, default_value_t = 3)]
        dim: usize,
        /// Approximate particle count (default: thesis 6800 in 3D, 6400 in 2D).
        #[arg(long)]
        particles: Option<usize>,
        /// Grid cells per axis.
        #[arg(long, default_value_t = 120)]
        n_grid: usize,
        /// Horizon T.
        #[arg(long, default_value_t = 200)]
        steps: usize,
        /// Timed repetitions (median reported).
        #[arg(long, default_value_t = 5)]
        repeats: usize,
        /// Rayon threads (0 = all cores).
        #[arg(long, default_value_t = 0)]
        threads: usize,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// Compare with a DiffTaichi fixture written by scripts/check_mpm_taichi.sh.
    TaichiCompare {
        /// Fixture JSON.
        #[arg(long)]
        fixture: PathBuf,
    },
}

pub fn run(c: MpmCmd) -> Result<()> {
    match c {
        MpmCmd::Simulate { scene, out, every } => simulate_cmd(&scene, &out, every),
        MpmCmd::Bench { dim, particles, n_grid, steps, repeats, threads, json } => {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build()?;
            pool.install(|| bench(dim, particles, n_grid, steps, repeats, json))
        }
        MpmCmd::TaichiCompare { fixture } => {
            let s = std::fs::read_to_string(&fixture).with_context(|| format!("reading {}", fixture.display()))?;
            let fx: TaichiFixture =
                serde_json::from_str(&s).with_context(|| format!("parsing {}", fixture.display()))?;
            let c = match fx.dim {
                2 => fx.compare::<2>()?,
                3 => fx.compare::<3>()?,
                d => bail!("{}: dim {d} not supported", fixture.display()),
            };
            println!("{}", serde_json::to_string(&c)?);
            let ok = c.max_position_diff_cells < 1e-6 && c.grad_rel_diff < 1e-4;
            println!(
                "{}: {} particles, max |x - x_taichi| = {:.3e} cells, loss rel diff {:.3e}, grad rel diff {:.3e} (max {:.3e}) -> {}",
                fixture.display(),
                c.particles,
                c.max_position_diff_cells,
                c.loss_rel_diff,
                c.grad_rel_diff,
                c.grad_max_rel_diff,
                if ok { "AGREE" } else { "DISAGREE" }
            );
            if !ok {
                bail!("laparo-mpm and DiffTaichi disagree");
            }
            Ok(())
        }
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Peak resident set size (VmHWM) in MiB.
pub fn peak_rss_mb() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines().find(|l| l.starts_with("VmHWM:")).and_then(|l| l.split_whitespace().nth(1)?.parse::<f64>().ok())
        })
        .map(|kb| kb / 1024.0)
        .unwrap_or(f64::NAN)
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
    Ok((median(fwd), median(fb), lossv))
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

fn simulate_cmd(scene_path: &Path, out: &Path, every: Option<usize>) -> Result<()> {
    match load_scene_file(scene_path)? {
        LoadedScene::D2(s) => run_scene(&s, out, every),
        LoadedScene::D3(s) => run_scene(&s, out, every),
    }
}

fn write_frame<const D: usize>(scene: &Scene<D>, st: &ParticleState<D>, out: &Path, step: usize) -> Result<()> {
    let j: Vec<f64> = st.f.iter().map(laparo_mpm::linalg::det).collect();
    if D == 2 {
        let x: Vec<laparo_mpm::Vector<2>> = st.x.iter().map(|p| laparo_mpm::Vector::<2>::new(p[0], p[1])).collect();
        let size = 512;
        let dot = ((scene.grid.dx / 2.0 / scene.grid.extent() * size as f64).ceil() as usize).max(2);
        let img = render_particles_2d(&x, &j, 0.5, 1.5, scene.grid.extent(), size, dot, &[]);
        laparo_core::io::write_png(out.join(format!("frame_{step:05}.png")), &img)?;
    } else {
        let x: Vec<laparo_mpm::Vector<3>> =
            st.x.iter().map(|p| laparo_mpm::Vector::<3>::new(p[0], p[1], p[2])).collect();
        let v: Vec<laparo_mpm::Vector<3>> =
            st.v.iter().map(|p| laparo_mpm::Vector::<3>::new(p[0], p[1], p[2])).collect();
        laparo_core::atomic::write_atomic(&out.join(format!("frame_{step:05}.ply")), &ply_bytes(&x, &v, &j))?;
    }
    Ok(())
}

fn run_scene<const D: usize>(scene: &Scene<D>, out: &Path, every: Option<usize>) -> Result<()> {
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    for w in laparo_mpm::cfl::check(scene) {
        eprintln!("warning: {w}");
    }
    let every = every.unwrap_or((scene.steps / 20).max(1)).max(1);
    eprintln!(
        "{}D scene: {} particles, n_grid {}, dx {:.4e}, dt {:.3e}, {} steps (CFL number {:.3})",
        D,
        scene.n_particles(),
        scene.grid.n_grid,
        scene.grid.dx,
        scene.dt,
        scene.steps,
        laparo_mpm::cfl::cfl_number(scene)
    );
    let pb = ProgressBar::new(scene.steps as u64);
    pb.set_style(ProgressStyle::with_template("{bar:40} {pos}/{len} steps {elapsed_precise} eta {eta}").unwrap());
    let mut log = String::from("step,time,kinetic_energy,elastic_energy,total_energy,px,py,pz,Lx,Ly,Lz,min_J\n");
    let mut frame_err: Option<anyhow::Error> = None;
    let res = simulate_observed(scene, |step, st| {
        let d = diagnostics(scene, st);
        log += &format!(
            "{step},{:.9e},{:.9e},{:.9e},{:.9e},{:.9e},{:.9e},{:.9e},{:.9e},{:.9e},{:.9e},{:.9e}\n",
            step as f64 * scene.dt,
            d.kinetic_energy,
            d.elastic_energy,
            d.kinetic_energy + d.elastic_energy,
            d.linear_momentum[0],
            d.linear_momentum[1],
            d.linear_momentum[2],
            d.angular_momentum[0],
            d.angular_momentum[1],
            d.angular_momentum[2],
            d.min_j
        );
        if step % every == 0 || step == scene.steps {
            if let Err(e) = write_frame(scene, st, out, step) {
                frame_err = Some(e);
                return Err(laparo_mpm::MpmError::InvalidScene("frame output failed".into()));
            }
        }
        pb.set_position(step as u64);
        Ok(())
    });
    pb.finish_and_clear();
    if let Some(e) = frame_err {
        return Err(e);
    }
    // The log is written even when the simulation blew up (it shows the run up to the failing step).
    laparo_core::atomic::write_atomic(&out.join("energy_momentum.csv"), log.as_bytes())?;
    let sim = res.context("simulation failed")?;
    let d = diagnostics(scene, &sim.final_state);
    println!(
        "simulated {} steps; frames every {every} steps and energy_momentum.csv in {}; final kinetic {:.4e}, elastic {:.4e}, min J {:.4}",
        scene.steps,
        out.display(),
        d.kinetic_energy,
        d.elastic_energy,
        d.min_j
    );
    Ok(())
}
