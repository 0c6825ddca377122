//! `laparo mpm ...`: differentiable MPM simulation (thesis §5.2.3–5.2.4, §5.3.2).
use anyhow::{bail, Context, Result};
use clap::Subcommand;
use indicatif::{ProgressBar, ProgressStyle};
use laparo_mpm::reference::TaichiFixture;
use laparo_mpm::render::{ply_bytes, render_particles_2d};
use laparo_mpm::scene_file::{load_scene_file, LoadedScene};
use laparo_mpm::{diagnostics, simulate_observed, ParticleState, Scene};
use std::path::{Path, PathBuf};

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
