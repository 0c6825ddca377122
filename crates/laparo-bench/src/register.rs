//! `laparo-bench register`: RODS-MPM registration on the thesis 3D configuration (the DiffTaichi RODS box of
//! `../shared/bench/taichi_mpm/mpm3d_rods.py`: 6.8k particles, n_grid 120, T 200), L-BFGS with the `tear` preset
//! (`--preset default` for the default settings) for up to 50 iterations: loss reduction (eq. 5.10) and wall
//! time, optionally against DiffTaichi's plain gradient descent
//! (10 iterations, run as a subprocess in the same session), and the determinism across 1 and 2 threads.
use crate::timing::peak_rss_mb;
use anyhow::{bail, Context, Result};
use clap::Args;
use laparo_mpm::reference::rods_scene;
use laparo_mpm::Vector;
use laparo_register::loss::{GroupTarget, LandmarkGroup, RegistrationLoss};
use laparo_register::optimize::{register, LineSearch, OptimizerConfig, OptimizerKind};
use std::path::PathBuf;
use std::time::Instant;

/// Options of `laparo-bench register`.
#[derive(Args)]
pub struct BenchArgs {
    /// 2 or 3.
    #[arg(long, default_value_t = 3)]
    pub dim: usize,
    /// Iterations.
    #[arg(long, default_value_t = 50)]
    pub iterations: usize,
    /// Optimiser: lbfgs, adam, thesis-gd.
    #[arg(long, default_value = "lbfgs")]
    pub optimizer: String,
    /// Settings of lbfgs/adam: `default` (OptimizerConfig::default) or `tear` (OptimizerConfig::tear, for
    /// targets that pull adjacent particles apart); by default `tear` in 3D (the thesis box), `default` in 2D.
    #[arg(long)]
    pub preset: Option<String>,
    /// Python with taichi: also run DiffTaichi's script (10 iterations of plain GD) in the same session.
    #[arg(long)]
    pub taichi_python: Option<PathBuf>,
    /// Folder of the DiffTaichi scripts.
    #[arg(long, default_value = "../shared/bench/taichi_mpm")]
    pub taichi_dir: PathBuf,
    /// σ of the Gaussian preconditioner (Δx; default: the optimiser's).
    #[arg(long)]
    pub smoothing_dx: Option<f64>,
    /// Largest landmark displacement per step (Δx; default: the optimiser's).
    #[arg(long)]
    pub max_step_dx: Option<f64>,
    /// Also run with 1 thread and compare the results bit for bit.
    #[arg(long)]
    pub check_threads: bool,
    /// L-BFGS line search: backtracking or wolfe (default: the optimiser's).
    #[arg(long)]
    pub line_search: Option<String>,
    /// Distance-smoothing continuation κ (ε = κ × mean landmark distance; 0 = off; default: the optimiser's).
    #[arg(long)]
    pub epsilon_ratio: Option<f64>,
    /// L-BFGS memory (default: the optimiser's).
    #[arg(long)]
    pub lbfgs_memory: Option<usize>,
    /// Strong Wolfe curvature constant c₂ (default: the optimiser's).
    #[arg(long)]
    pub wolfe_c2: Option<f64>,
    /// Print every accepted iteration.
    #[arg(long)]
    pub verbose: bool,
}

fn run_once<const D: usize>(
    counts: [usize; D],
    cfg: &OptimizerConfig,
    verbose: bool,
) -> Result<(Vec<f64>, f64, usize, Vec<Vector<D>>)> {
    let (mut scene, lm) = rods_scene::<D>(counts, 120, 200, 2e-4);
    // DiffTaichi's script starts from v₀ = 0 (`init_v.fill(0)`); rods_scene carries a test field
    scene.velocities.iter_mut().for_each(|v| *v = Vector::<D>::zeros());
    let loss = RegistrationLoss::new(vec![LandmarkGroup {
        name: "lips".into(),
        particles: lm.indices.clone(),
        target: GroupTarget::Paired(lm.targets.clone()),
        weight: 1.0,
    }]);
    let t0 = Instant::now();
    let r = register(&scene, &loss, cfg, None, &mut |h, _| {
        if verbose {
            println!(
                "  it {:3}  loss {:.5e}  objective {:.5e}  eps {:.3e}  step {:.3e}  sims {:3}  {:.1} s",
                h.iteration, h.loss, h.objective, h.epsilon, h.step, h.evaluations, h.seconds
            );
        }
        true
    })?;
    let secs = t0.elapsed().as_secs_f64();
    let losses = r.history.iter().map(|h| h.loss).collect();
    Ok((losses, secs, r.history.last().map_or(0, |h| h.evaluations), r.velocities))
}

pub fn run(a: BenchArgs) -> Result<()> {
    let kind = match a.optimizer.as_str() {
        "lbfgs" => OptimizerKind::Lbfgs,
        "adam" => OptimizerKind::Adam,
        "thesis-gd" => OptimizerKind::ThesisGd,
        o => bail!("--optimizer {o}"),
    };
    let preset = a.preset.clone().unwrap_or_else(|| if a.dim == 3 { "tear".into() } else { "default".into() });
    let base = match (kind, preset.as_str()) {
        (OptimizerKind::ThesisGd, _) => OptimizerConfig::thesis(),
        (_, "default") => OptimizerConfig::default(),
        (_, "tear") => OptimizerConfig::tear(),
        (_, o) => bail!("--preset {o}: expected default or tear"),
    };
    let cfg = OptimizerConfig {
        kind,
        iterations: a.iterations,
        rel_tol: 0.0,
        smoothing_dx: a.smoothing_dx.unwrap_or(base.smoothing_dx),
        max_step_dx: a.max_step_dx.unwrap_or(base.max_step_dx),
        line_search: match a.line_search.as_deref() {
            None => base.line_search,
            Some("backtracking") => LineSearch::Backtracking,
            Some("wolfe") => LineSearch::StrongWolfe,
            Some(o) => bail!("--line-search {o}: expected backtracking or wolfe"),
        },
        epsilon_ratio: a.epsilon_ratio.unwrap_or(base.epsilon_ratio),
        lbfgs_memory: a.lbfgs_memory.unwrap_or(base.lbfgs_memory),
        wolfe_c2: a.wolfe_c2.unwrap_or(base.wolfe_c2),
        ..base
    };
    let threads = rayon::current_num_threads();
    let (losses, secs, sims, v) = match a.dim {
        3 => {
            let (l, s, n, v) = run_once::<3>([16, 25, 17], &cfg, a.verbose)?;
            (l, s, n, v.iter().flat_map(|x| [x[0], x[1], x[2]]).collect::<Vec<f64>>())
        }
        2 => {
            let (l, s, n, v) = run_once::<2>([80, 80], &cfg, a.verbose)?;
            (l, s, n, v.iter().flat_map(|x| [x[0], x[1]]).collect::<Vec<f64>>())
        }
        d => bail!("--dim must be 2 or 3 (got {d})"),
    };
    let (l0, l1) = (losses[0], *losses.last().unwrap_or(&losses[0]));
    println!(
        "laparo register ({:?}, preset {preset}, {}D RODS box, {} threads): loss {:.4e} -> {:.4e} ({:.1} % reduction) in {} iterations, \
         {} simulations, {:.1} s ({:.2} s per simulation), peak RSS {:.0} MiB",
        kind,
        a.dim,
        threads,
        l0,
        l1,
        100.0 * (1.0 - l1 / l0),
        losses.len() - 1,
        sims,
        secs,
        secs / sims.max(1) as f64,
        peak_rss_mb()
    );
    if a.check_threads {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
        let v1 = pool.install(|| -> Result<Vec<f64>> {
            Ok(match a.dim {
                3 => run_once::<3>([16, 25, 17], &cfg, a.verbose)?.3.iter().flat_map(|x| [x[0], x[1], x[2]]).collect(),
                _ => run_once::<2>([80, 80], &cfg, a.verbose)?.3.iter().flat_map(|x| [x[0], x[1]]).collect(),
            })
        })?;
        let same = v1.len() == v.len() && v1.iter().zip(&v).all(|(a, b)| a.to_bits() == b.to_bits());
        println!("1 thread vs {threads} threads: optimised v0 {}", if same { "bit-identical" } else { "DIFFERENT" });
        if !same {
            bail!("results differ between thread counts");
        }
    }
    if let Some(py) = &a.taichi_python {
        let script = a.taichi_dir.join(if a.dim == 3 { "mpm3d_rods.py" } else { "mpm2d_rods.py" });
        let lr = if a.dim == 3 { "4e4" } else { "1e4" };
        let t0 = Instant::now();
        let out = std::process::Command::new(py)
            .arg(&script)
            .args(["--n-grid", "120", "--steps", "200", "--iters", "10", "--fwd-reps", "0", "--lr", lr])
            .output()
            .with_context(|| format!("running {} {}", py.display(), script.display()))?;
        let t = t0.elapsed().as_secs_f64();
        if !out.status.success() {
            bail!("DiffTaichi failed: {}", String::from_utf8_lossy(&out.stderr));
        }
        let text = String::from_utf8_lossy(&out.stdout);
        let last: Vec<&str> = text.lines().rev().take(4).collect();
        println!(
            "DiffTaichi plain GD, 10 iterations (lr {lr}), same session: {t:.1} s wall (incl. compile); laparo {:.1} s for {} iterations = {:.2}× less wall time",
            secs,
            losses.len() - 1,
            t / secs
        );
        for l in last.iter().rev() {
            println!("  taichi: {l}");
        }
    }
    Ok(())
}
