//! `laparo mpm ...`: differentiable MPM simulation (thesis §5.2.3–5.2.4, §5.3.2).
use anyhow::{bail, Context, Result};
use clap::Subcommand;
use indicatif::{ProgressBar, ProgressStyle};
use laparo_core::colormap::{with_colorbar, Colormap};
use laparo_mpm::reference::{rods_scene, TaichiFixture};
use laparo_mpm::render::{ply_bytes, render_particles_2d, render_particles_3d, View3d};
use laparo_mpm::{
    diagnostics, load_scene_file, simulate_observed, simulate_with_gradient_in, GradientWorkspace, LoadedScene, Loss,
    ParticleState, Scene, Vector,
};
use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Subcommand)]
pub enum MpmCmd {
    /// Simulate a scene (TOML) and write particle frames (3D: binary PLY; 2D: PNG), a PNG preview
    /// and an energy/momentum log. Frames of an earlier run in the same folder are removed.
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
        let mut g = vec![Vector::<D>::zeros(); scene.n_particles()];
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
    let (scene, warnings) = load_scene_file(scene_path)?;
    for w in &warnings {
        eprintln!("warning: {w}");
    }
    match scene {
        LoadedScene::D2(s) => run_scene(&s, out, every),
        LoadedScene::D3(s) => run_scene(&s, out, every),
    }
}

/// Whether `name` is one of the files `mpm simulate` writes per run (`frame_NNNNN.ply|png`,
/// `preview.png`) or a temporary of them left by an interrupted run.
fn is_run_output(name: &str) -> bool {
    let name = name.strip_prefix('.').and_then(|n| n.split_once(".tmp").map(|_| n)).unwrap_or(name);
    let frame = |n: &str| {
        n.strip_prefix("frame_").and_then(|r| r.split_once('.')).is_some_and(|(num, ext)| {
            !num.is_empty()
                && num.bytes().all(|b| b.is_ascii_digit())
                && (ext.starts_with("ply") || ext.starts_with("png"))
        })
    };
    frame(name) || name.starts_with("preview.png") || name.starts_with("energy_momentum.csv")
}

/// Remove the frames, preview and log of an earlier run (and their temporaries) from `out`, so that a
/// shorter rerun does not leave older frames beside the new ones. Other files are kept.
fn remove_stale_outputs(out: &Path) -> Result<usize> {
    let mut removed = 0;
    for e in std::fs::read_dir(out).with_context(|| format!("listing {}", out.display()))? {
        let e = e?;
        if e.file_type()?.is_file() && e.file_name().to_str().is_some_and(is_run_output) {
            std::fs::remove_file(e.path()).with_context(|| format!("removing {}", e.path().display()))?;
            removed += 1;
        }
    }
    Ok(removed)
}

fn to3(v: &[impl std::ops::Index<usize, Output = f64>]) -> Vec<Vector<3>> {
    v.iter().map(|p| Vector::<3>::new(p[0], p[1], p[2])).collect()
}

fn write_frame<const D: usize>(scene: &Scene<D>, st: &ParticleState<D>, out: &Path, step: usize) -> Result<()> {
    let j: Vec<f64> = st.f.iter().map(laparo_mpm::det).collect();
    if D == 2 {
        let x: Vec<Vector<2>> = st.x.iter().map(|p| Vector::<2>::new(p[0], p[1])).collect();
        let size = 512;
        let dot = ((scene.grid.dx / 2.0 / scene.grid.extent() * size as f64).ceil() as usize).max(2);
        let img = render_particles_2d(&x, &j, 0.5, 1.5, scene.grid.extent(), size, dot, &[]);
        let img = with_colorbar(&img, 0.5, 1.5, Colormap::Turbo, "J = det F");
        laparo_core::io::write_png(out.join(format!("frame_{step:05}.png")), &img)?;
    } else {
        laparo_core::atomic::write_atomic(
            &out.join(format!("frame_{step:05}.ply")),
            &ply_bytes(&to3(&st.x), &to3(&st.v), &j),
        )?;
    }
    Ok(())
}

/// 3D preview: the final particles in an orthographic view over the initial ones (light grey),
/// coloured by displacement magnitude |x − x₀| (scene length units), with a colour bar.
fn write_preview_3d<const D: usize>(scene: &Scene<D>, st: &ParticleState<D>, out: &Path) -> Result<()> {
    let (x0, x) = (to3(&scene.positions), to3(&st.x));
    let disp: Vec<f64> = x.iter().zip(&x0).map(|(a, b)| (a - b).norm()).collect();
    let hi = disp.iter().copied().filter(|d| d.is_finite()).fold(0.0, f64::max);
    let spacing = scene.volumes.first().map_or(scene.grid.dx / 2.0, |v| v.cbrt());
    let img = render_particles_3d(&x, &disp, 0.0, hi.max(1e-300), &x0, &View3d::default(), 640, 1.2 * spacing);
    let img = with_colorbar(&img, 0.0, hi, Colormap::Turbo, "displacement |x - x0| (scene length units)");
    laparo_core::io::write_png(out.join("preview.png"), &img)?;
    Ok(())
}

/// Progress of the run: a bar on a terminal, otherwise a line every 10 % on stderr (indicatif
/// hides itself when stderr is not a terminal, e.g. in a batch job or under `tee`).
enum Progress {
    Bar(ProgressBar),
    Lines { total: usize, next_pct: usize, start: Instant },
}

impl Progress {
    fn new(total: usize) -> Self {
        if std::io::stderr().is_terminal() {
            let pb = ProgressBar::new(total as u64);
            pb.set_style(
                ProgressStyle::with_template("{bar:40} {pos}/{len} steps {elapsed_precise} eta {eta}").unwrap(),
            );
            Progress::Bar(pb)
        } else {
            Progress::Lines { total, next_pct: 10, start: Instant::now() }
        }
    }
    fn set(&mut self, step: usize) {
        match self {
            Progress::Bar(pb) => pb.set_position(step as u64),
            Progress::Lines { total, next_pct, start } => {
                if *total == 0 {
                    return;
                }
                let pct = step * 100 / *total;
                if pct >= *next_pct {
                    let el = start.elapsed().as_secs_f64();
                    let eta = el * (*total - step) as f64 / step.max(1) as f64;
                    eprintln!("step {step}/{total} ({pct} %), {el:.1} s elapsed, eta {eta:.1} s");
                    let _ = std::io::stderr().flush();
                    *next_pct = (pct / 10 + 1) * 10;
                }
            }
        }
    }
    fn finish(&self) {
        if let Progress::Bar(pb) = self {
            pb.finish_and_clear();
        }
    }
}

fn run_scene<const D: usize>(scene: &Scene<D>, out: &Path, every: Option<usize>) -> Result<()> {
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let removed = remove_stale_outputs(out)?;
    if removed > 0 {
        eprintln!("removed {removed} frame/preview/log files of an earlier run from {}", out.display());
    }
    for w in laparo_mpm::cfl_warnings(scene) {
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
        laparo_mpm::cfl_number(scene)
    );
    let mut progress = Progress::new(scene.steps);
    // The log is streamed to a temporary file (a long run does not hold it in memory) and renamed
    // at the end, also when the simulation blew up (it shows the run up to the failing step).
    let log_path = out.join("energy_momentum.csv");
    let log_tmp = laparo_core::atomic::temp_path(&log_path);
    let mut log = std::io::BufWriter::new(
        std::fs::File::create(&log_tmp).with_context(|| format!("creating {}", log_tmp.display()))?,
    );
    let mut out_err: Option<anyhow::Error> = None;
    let res = (|| -> std::io::Result<_> {
        writeln!(log, "step,time,kinetic_energy,elastic_energy,total_energy,px,py,pz,Lx,Ly,Lz,min_J")?;
        Ok(simulate_observed(scene, |step, st| {
            let d = diagnostics(scene, st);
            let row = writeln!(
                log,
                "{step},{:.9e},{:.9e},{:.9e},{:.9e},{:.9e},{:.9e},{:.9e},{:.9e},{:.9e},{:.9e},{:.9e}",
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
            )
            .with_context(|| format!("writing {}", log_tmp.display()));
            let frame =
                if step % every == 0 || step == scene.steps { write_frame(scene, st, out, step) } else { Ok(()) };
            if let Err(e) = row.and(frame) {
                out_err = Some(e);
                return Err(laparo_mpm::MpmError::InvalidScene("output failed".into()));
            }
            progress.set(step);
            Ok(())
        }))
    })();
    progress.finish();
    let finished = res
        .map_err(anyhow::Error::from)
        .and_then(|r| Ok((r, log.into_inner().map_err(|e| e.into_error())?)))
        .and_then(|(r, f)| {
            f.sync_all()?;
            std::fs::rename(&log_tmp, &log_path).with_context(|| format!("writing {}", log_path.display()))?;
            Ok(r)
        });
    let res = match finished {
        Ok(r) => r,
        Err(e) => {
            let _ = std::fs::remove_file(&log_tmp);
            return Err(e);
        }
    };
    if let Some(e) = out_err {
        return Err(e);
    }
    let sim = res.context("simulation failed")?;
    if D == 3 {
        write_preview_3d(scene, &sim.final_state, out)?;
    }
    let d = diagnostics(scene, &sim.final_state);
    println!(
        "simulated {} steps; frames every {every} steps{} and energy_momentum.csv in {}; final kinetic {:.4e}, elastic {:.4e}, min J {:.4}",
        scene.steps,
        if D == 3 { ", preview.png" } else { "" },
        out.display(),
        d.kinetic_energy,
        d.elastic_energy,
        d.min_j
    );
    Ok(())
}
