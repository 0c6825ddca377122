//! `laparo register ...`: RODS-MPM deformable registration (thesis Ch. 5) and rigid alignment (App. A).
use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use laparo_mpm::Vector;
use laparo_register::io::{read_landmarks, read_p2ilf_contours, read_targets, SourceGroup};
use laparo_register::optimize::{OptimizerConfig, OptimizerKind};
use laparo_register::organ::{OrganConfig, Roi};
use laparo_register::pipeline::{run_job, Job};
use laparo_register::rigid::{
    bbox_diagonal, icp, icp_estimate_overlap, rmse, rotation_angle_deg, umeyama, IcpConfig, IcpMode, Similarity,
    FRMSD_LAMBDA, OVERLAP_CANDIDATES,
};
use std::path::PathBuf;

/// `laparo register`: deformable registration, or a subcommand.
#[derive(Args)]
#[command(args_conflicts_with_subcommands = true)]
pub struct RegisterArgs {
    #[command(subcommand)]
    pub sub: Option<RegisterSub>,
    #[command(flatten)]
    pub run: RunArgs,
}

/// Subcommands of `laparo register`.
#[derive(Subcommand)]
pub enum RegisterSub {
    /// Rigid alignment: landmark Procrustes (Umeyama) then ICP (point-to-point or point-to-plane).
    Rigid(RigidArgs),
    /// Write landmarks + targets from P2ILF 3D contours displaced by a smooth field (benchmarks).
    SynthTargets(SynthArgs),
    /// The in-silico incision benchmark (§5.4.2, Table 5.1, Figs. 5.7–5.9): FEM ground truth on a real liver,
    /// ARAP, DRBC, François et al., LDDMM and RODS-MPM scored by TRE at every node.
    Benchmark(Box<crate::cmd::register_benchmark::BenchmarkArgs>),
    /// Mesh convergence of the benchmark's FEM ground truth: one scenario on two tetrahedron sizes, compared
    /// at the coarse mesh's evaluation points (issue 46).
    Convergence(Box<crate::cmd::register_convergence::ConvergenceArgs>),
    /// Beyond incisions: a Gaussian bump pushed into the organ's broadest face, seen through landmarks along
    /// one surface curve; RODS-MPM with each unknown, scored on the whole surface against the analytic field
    /// (OUT/bump.json, bump.md, registered surfaces as OBJ).
    Bump(Box<BumpArgs>),
    /// Fig. 5.5 in 2D: the four cases (stretch, curve, rupture, rupture + stretch) as PNGs + metrics.
    Fig55 {
        /// Output folder.
        #[arg(long)]
        out: PathBuf,
        /// Iterations per case.
        #[arg(long, default_value_t = 50)]
        iterations: usize,
        /// Optimiser: lbfgs, tear, adam, thesis-gd (as `laparo register --optimizer`).
        #[arg(long, default_value = "lbfgs")]
        optimizer: String,
    },
}

/// `laparo register bump`.
#[derive(Args)]
pub struct BumpArgs {
    /// Output folder (bump.json, bump.md, bump_truth.obj, bump_<unknown>.obj).
    #[arg(long)]
    pub out: PathBuf,
    /// Closed organ surface (OBJ/PLY/STL, mm); default the P2ILF liver under ../shared/data.
    #[arg(long)]
    pub organ: Option<PathBuf>,
    /// Peak displacement of the bump (mm).
    #[arg(long, default_value_t = 9.0)]
    pub amplitude_mm: f64,
    /// Gaussian width σ of the bump (mm).
    #[arg(long, default_value_t = 45.0)]
    pub sigma_mm: f64,
    /// Landmarks along the curve.
    #[arg(long, default_value_t = 30)]
    pub landmarks: usize,
    /// Unknowns to compare, comma separated (velocity: the thesis' v₀; loads: rung L3).
    #[arg(long, default_value = "velocity,loads")]
    pub unknowns: String,
    /// Particle spacing (mm).
    #[arg(long, default_value_t = 4.0)]
    pub spacing_mm: f64,
    /// Horizon T (steps).
    #[arg(long, default_value_t = 200)]
    pub steps: usize,
    /// Optimiser iterations.
    #[arg(long, default_value_t = 16)]
    pub iterations: usize,
}

fn bump(a: BumpArgs) -> Result<()> {
    use laparo_register::bump::{run_bump, BumpCase, BumpConfig};
    let organ = match a.organ {
        Some(p) => p,
        None => crate::demo::shared_data("meshes/p2ilf/patient2_1_3d-liver-model.obj").context(
            "--organ not given and ../shared/data/meshes/p2ilf/patient2_1_3d-liver-model.obj not found (set LAPARO_SHARED_DATA)",
        )?,
    };
    let unknowns: Vec<laparo_register::optimize::Unknown> = a
        .unknowns
        .split(',')
        .map(|u| {
            laparo_register::optimize::Unknown::from_name(
                u.trim(),
                laparo_register::optimize::DEFAULT_DAMPING_PER_HORIZON,
            )
        })
        .collect::<std::result::Result<_, _>>()
        .context("--unknowns")?;
    let names: Vec<String> = unknowns.iter().map(|u| format!("bump_{}.obj", u.name())).collect();
    let mut outs: Vec<&str> = vec!["bump.json", "bump.md", "bump_truth.obj"];
    outs.extend(names.iter().map(String::as_str));
    laparo_core::atomic::refuse_overwrite_in(&a.out, &outs, &[organ.as_path()]).context("--out")?;
    let surface = laparo_core::mesh::read_mesh(&organ).with_context(|| format!("--organ {}", organ.display()))?;
    let cfg = BumpConfig { amplitude_mm: a.amplitude_mm, sigma_mm: a.sigma_mm, landmarks: a.landmarks };
    let case = BumpCase::new(&surface, &cfg).with_context(|| format!("--organ {}", organ.display()))?;
    std::fs::create_dir_all(&a.out).with_context(|| format!("--out {}", a.out.display()))?;
    let truth = laparo_core::mesh::TriMesh {
        vertices: surface.vertices.iter().map(|x| x + case.displacement(x)).collect(),
        faces: surface.faces.clone(),
    };
    laparo_core::mesh::write_obj(a.out.join("bump_truth.obj"), &truth)?;
    let organ_cfg = OrganConfig { spacing_mm: a.spacing_mm, steps: a.steps, ..Default::default() };
    let mut runs = Vec::new();
    for (u, name) in unknowns.iter().zip(&names) {
        eprintln!("bump: registering with unknown `{}` ({} iterations)…", u.name(), a.iterations);
        let opt = OptimizerConfig { iterations: a.iterations, unknown: *u, ..Default::default() };
        let (run, registered) = run_bump(&organ, &surface, &case, &organ_cfg, &opt)?;
        laparo_core::mesh::write_obj(a.out.join(name), &registered)?;
        runs.push(run);
    }
    let mut t = laparo_core::table::Table::new([
        "unknown",
        "surface error mean / max (mm)",
        "vs none",
        "beyond 2σ: motion mean / max (mm)",
        "beyond 2σ: error mean (mm)",
        "landmarks to curve, mesh / particles (mm)",
        "eq. 5.10 (mm)",
        "s",
    ]);
    for r in &runs {
        t.push_row(vec![
            r.unknown.clone(),
            format!("{:.2} / {:.2}", r.surface_error_mm.mean, r.surface_error_mm.max),
            format!("{:.2} ×", r.surface_error_mm.mean / r.surface_error_none_mm.mean),
            format!("{:.2} / {:.2}", r.far_motion_mm.mean, r.far_motion_mm.max),
            format!("{:.2}", r.far_error_mm.mean),
            format!("{:.2} / {:.2}", r.landmark_to_curve_mesh_mm.mean, r.landmark_to_curve_particles_mm.mean),
            format!("{:.2} → {:.2}", r.loss_mm[0], r.loss_mm[1]),
            format!("{:.0}", r.seconds),
        ]);
    }
    let none = runs.first().map(|r| r.surface_error_none_mm).unwrap_or_default();
    let md = format!(
        "# Beyond incisions: a {:.0} mm Gaussian bump (σ {:.0} mm), {} landmarks on one curve\n\nNo registration: surface error mean {:.2} / max {:.2} mm over {} vertices.\n\n{}",
        a.amplitude_mm,
        a.sigma_mm,
        case.landmarks.len(),
        none.mean,
        none.max,
        none.n,
        t.to_markdown()
    );
    laparo_core::atomic::write_atomic(&a.out.join("bump.md"), md.as_bytes())?;
    let json = serde_json::json!({"organ": organ.display().to_string(), "config": cfg, "case": case, "spacing_mm": a.spacing_mm, "steps": a.steps, "runs": runs});
    laparo_core::atomic::write_atomic(&a.out.join("bump.json"), serde_json::to_string_pretty(&json)?.as_bytes())?;
    println!("{md}");
    Ok(())
}

/// The preset an `--optimizer` name starts from.
pub(crate) fn optimizer_base(s: &str) -> Result<OptimizerConfig> {
    OptimizerConfig::preset(s).with_context(|| {
        format!("--optimizer {s}: expected one of {}", laparo_register::optimize::PRESET_NAMES.join(", "))
    })
}

/// Run the four Fig. 5.5 cases, writing `<case>_before.png`, `<case>_after.png`, `<case>_loss.png` and
/// `fig55.json` into `out`; returns the metrics.
pub fn fig55_figures(out: &std::path::Path, cfg: &OptimizerConfig) -> Result<Vec<laparo_register::fig55::CaseMetrics>> {
    use laparo_register::fig55::*;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let mut all = Vec::new();
    for case in Case::ALL {
        // (a), (b): the DiffTaichi material; (c), (d): the rupture material, kerf and kinematic warm start
        let setup = CaseSetup::for_case(case);
        let scene = square_scene_with(setup.material);
        let marks = case_marks(&scene, case, &setup)?;
        let ones = vec![1.0; scene.n_particles()];
        laparo_core::io::write_png(
            out.join(format!("{}_before.png", case.label())),
            &render_case(&scene.positions, &ones, &marks, 420),
        )?;
        let (m, x, j) = run_case(case, cfg)?;
        laparo_core::io::write_png(out.join(format!("{}_after.png", case.label())), &render_case(&x, &j, &marks, 420))?;
        let lp = out.join(format!("{}_loss.png", case.label()));
        laparo_core::atomic::write_atomic_with(&lp, |tmp| {
            let t = tmp.with_extension("png");
            laparo_mpm::render::plot_loss_curve(
                &t,
                &m.curve_dx,
                &format!("{}: mean landmark distance (Δx)", case.label()),
            )?;
            std::fs::rename(&t, tmp).map_err(|e| laparo_core::CoreError::io(tmp, e))
        })?;
        all.push(m);
    }
    laparo_core::atomic::write_atomic(&out.join("fig55.json"), serde_json::to_string_pretty(&all)?.as_bytes())?;
    Ok(all)
}

/// Deformable registration arguments.
#[derive(Args)]
pub struct RunArgs {
    /// Organ: closed surface (OBJ/PLY/STL) or tetrahedral mesh (.msh/.vtk), mm.
    #[arg(long)]
    pub organ: Option<PathBuf>,
    /// Source landmarks (JSON groups or CSV group,x,y,z; mm).
    #[arg(long)]
    pub landmarks: Option<PathBuf>,
    /// Targets: JSON groups (points/polyline/cloud) or a PLY/OBJ surface or point cloud.
    #[arg(long)]
    pub target: Option<PathBuf>,
    /// Output folder.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Particle spacing (mm); grid cell = 2 × spacing unless --dx-mm.
    #[arg(long, default_value_t = 3.0)]
    pub spacing_mm: f64,
    /// Grid cell (mm).
    #[arg(long)]
    pub dx_mm: Option<f64>,
    /// Optimiser: lbfgs (default, preconditioned), tear (L-BFGS preset for targets that tear neighbouring
    /// particles apart: unsmoothed, strong Wolfe line search, distance-smoothing continuation), adam,
    /// thesis-gd.
    #[arg(long, default_value = "lbfgs")]
    pub optimizer: String,
    /// Maximum iterations (thesis-gd: 500 by default).
    #[arg(long)]
    pub iterations: Option<usize>,
    /// Region of interest: ball:x,y,z,r or box:x0,y0,z0,x1,y1,z1 (mm); its boundary particles are fixed.
    #[arg(long)]
    pub roi: Option<String>,
    /// Tumour (or any internal structure) mesh to deform (mm).
    #[arg(long)]
    pub tumour: Option<PathBuf>,
    /// Image for the overlay (with --camera).
    #[arg(long)]
    pub image: Option<PathBuf>,
    /// Camera intrinsics file (JSON/YAML; pinhole + distortion).
    #[arg(long)]
    pub camera: Option<PathBuf>,
    /// Young's modulus (kPa).
    #[arg(long, default_value_t = 4.1)]
    pub youngs_modulus_kpa: f64,
    /// Poisson's ratio.
    #[arg(long, default_value_t = 0.49)]
    pub poisson_ratio: f64,
    /// Density (kg/m³).
    #[arg(long, default_value_t = 1000.0)]
    pub density_kg_m3: f64,
    /// Horizon T (steps).
    #[arg(long, default_value_t = 200)]
    pub steps: usize,
    /// Time step (s); default from the CFL condition.
    #[arg(long)]
    pub dt_s: Option<f64>,
    /// Weight of the one-sided target→source term for surface / point-cloud targets.
    #[arg(long, default_value_t = 0.0)]
    pub region_weight: f64,
    /// Also identify E (poorly identifiable from one snapshot; see the crate README).
    #[arg(long)]
    pub joint_e: bool,
    /// Gaussian preconditioner σ (grid cells; default: the optimiser's, 2 for lbfgs, 0 for tear).
    #[arg(long)]
    pub smoothing_dx: Option<f64>,
    /// Largest landmark displacement per step (grid cells; default: the optimiser's, 0.5 for lbfgs, 16 for
    /// tear).
    #[arg(long)]
    pub max_step_dx: Option<f64>,
    /// Stop when the mean landmark distance is at most this (mm).
    #[arg(long, default_value_t = 0.0)]
    pub target_mean_mm: f64,
    /// Resume from OUT/checkpoint_v0.json.
    #[arg(long)]
    pub resume: bool,
    /// Checkpoint v₀ every N iterations.
    #[arg(long, default_value_t = 5)]
    pub checkpoint_every: usize,
    /// Memory available for the adjoint checkpoints (GB); default: MemAvailable. Beyond it the adjoint keeps
    /// every k-th step and recomputes the rest (the same result, one more forward pass per iteration).
    #[arg(long)]
    pub memory_gb: Option<f64>,
    /// Least-action prior κ (default 0: the thesis' eq. 5.10 alone): adds κ · mean |v₀ T Δt|² / (2 Δx) over the
    /// free particles, so motion the landmarks do not ask for costs something.
    #[arg(long, default_value_t = 0.0)]
    pub kinetic_weight: f64,
    /// At-rest prior λ (default 0): adds λ · Σ m |v_T T Δt|² / (2 M Δx), the kinetic energy left at the end of
    /// the horizon, so the registered shape is at rest rather than a snapshot of a swing (report.json's
    /// `energy` audits KE(0), KE(T), the elastic energy at T and the energy dissipated).
    #[arg(long, default_value_t = 0.0)]
    pub at_rest_weight: f64,
    /// A crack surface (PLY/OBJ/STL triangles, mm, organ frame; normals from one lip to the other) along which
    /// the organ is cut: particles on either side get their own grid velocity field (laparo-mpm's two-field
    /// grid), so the lips can separate. Default: none (one field, the thesis' RODS-MPM).
    #[arg(long)]
    pub crack: Option<PathBuf>,
    /// Particles within this distance (mm) of --crack are labelled by side; default 3 grid cells.
    #[arg(long)]
    pub crack_band_mm: Option<f64>,
    /// Assume the cut from one lip alone (what François et al. assume): the landmark group --assumed-cut-group
    /// (default the first) swept along the organ surface's inward normal to this depth (mm) becomes the crack
    /// surface of the two-field grid (written to OUT/crack_surface.ply, as a --crack is). Instead of --crack.
    #[arg(long, conflicts_with = "crack")]
    pub assumed_cut_depth_mm: Option<f64>,
    /// The landmark group (a lip's source polyline) the assumed cut is swept from; default the first group.
    #[arg(long, requires = "assumed_cut_depth_mm")]
    pub assumed_cut_group: Option<String>,
    /// The unknown RODS-MPM solves for (§5.3.1): velocity (v₀, the thesis) or loads (a time-constant,
    /// self-equilibrated force density on the particles the crack labels, or on every free particle without
    /// a crack, from rest with mass-proportional damping so the registered shape is an equilibrium: the
    /// ladder's rung L3; --kinetic-weight becomes the loads' L2 prior).
    #[arg(long, default_value = "velocity", value_parser = clap::builder::PossibleValuesParser::new(laparo_register::optimize::Unknown::NAMES))]
    pub unknown: String,
    /// With --unknown loads: the damping ζ T Δt over the horizon (fixed a priori; 10: underdamped modes lose
    /// e^-5 of their amplitude).
    #[arg(long, default_value_t = laparo_register::optimize::DEFAULT_DAMPING_PER_HORIZON)]
    pub damping_per_horizon: f64,
    /// Score each landmark at its nearest particle, as the thesis does, instead of at its own material point
    /// (that particle plus their rest offset; default). The nearest particle lies up to half a spacing under
    /// a surface landmark, so the thesis' loss pulls tissue towards the target by that much.
    #[arg(long)]
    pub thesis_landmarks: bool,
}

/// `laparo register rigid`.
#[derive(Args)]
pub struct RigidArgs {
    /// Source mesh or point cloud (mm).
    #[arg(long)]
    pub source: PathBuf,
    /// Target mesh or point cloud (mm).
    #[arg(long)]
    pub target: PathBuf,
    /// Source landmarks (JSON/CSV) for Procrustes.
    #[arg(long)]
    pub landmarks: Option<PathBuf>,
    /// Target landmarks (JSON/CSV, same groups and order).
    #[arg(long)]
    pub target_landmarks: Option<PathBuf>,
    /// Also estimate a scale in Procrustes.
    #[arg(long)]
    pub scale: bool,
    /// ICP variant: point-to-point, point-to-plane or none.
    #[arg(long, default_value = "point-to-point")]
    pub icp: String,
    /// Fraction of the source's closest pairs kept (trimmed ICP), in (0, 1]. Default: estimated, trying
    /// 1, 0.8, 0.6, 0.45, 0.3 and 0.2 and keeping the fit with the lowest fractional RMSD (RMSE / overlap³,
    /// Phillips et al. 2007), so a source that covers only part of the target (or the reverse) is not
    /// pulled off by the unmatched part. With a value, that overlap alone (and a warning when another
    /// overlap fits much better).
    #[arg(long)]
    pub overlap: Option<f64>,
    /// Initial source → target transform (JSON, the form `transform.json` is written in:
    /// {"source_to_target": {"R": 3 rows, "t_mm": [x, y, z]}} or {"T": 4x4 rows}); default identity.
    /// Not with --landmarks.
    #[arg(long, conflicts_with = "landmarks")]
    pub init: Option<PathBuf>,
    /// Output folder (transform.json, source_aligned.ply).
    #[arg(long)]
    pub out: PathBuf,
}

/// `laparo register synth-targets`.
#[derive(Args)]
pub struct SynthArgs {
    /// Organ mesh (OBJ, mm) whose vertex ids the contours use.
    #[arg(long)]
    pub organ: PathBuf,
    /// P2ILF 3D contours JSON.
    #[arg(long)]
    pub contours: PathBuf,
    /// Largest displacement of the smooth field (mm).
    #[arg(long, default_value_t = 10.0)]
    pub max_displacement_mm: f64,
    /// Only contours of this type (e.g. Ridge).
    #[arg(long)]
    pub only: Option<String>,
    /// Output landmarks JSON.
    #[arg(long)]
    pub landmarks_out: PathBuf,
    /// Output targets JSON.
    #[arg(long)]
    pub targets_out: PathBuf,
}

fn parse_roi(s: &str) -> Result<Roi> {
    let (kind, rest) = s.split_once(':').context("--roi: expected ball:x,y,z,r or box:x0,y0,z0,x1,y1,z1")?;
    let v: Vec<f64> = rest
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<std::result::Result<_, _>>()
        .context("--roi: numbers")?;
    match (kind, v.len()) {
        ("ball", 4) if v[3] > 0.0 => Ok(Roi::Ball { center: [v[0], v[1], v[2]], radius_mm: v[3] }),
        ("box", 6) if (0..3).all(|d| v[d] < v[d + 3]) => {
            Ok(Roi::Box { lo: [v[0], v[1], v[2]], hi: [v[3], v[4], v[5]] })
        }
        _ => bail!("--roi {s}: expected ball:x,y,z,r (r > 0) or box:x0,y0,z0,x1,y1,z1 (lo < hi)"),
    }
}

pub fn run(a: RegisterArgs) -> Result<()> {
    match a.sub {
        Some(RegisterSub::Rigid(r)) => rigid(r),
        Some(RegisterSub::SynthTargets(s)) => synth(s),
        Some(RegisterSub::Benchmark(b)) => crate::cmd::register_benchmark::run(*b),
        Some(RegisterSub::Convergence(c)) => crate::cmd::register_convergence::run(*c),
        Some(RegisterSub::Bump(b)) => bump(*b),
        Some(RegisterSub::Fig55 { out, iterations, optimizer }) => {
            let cfg = OptimizerConfig { iterations, ..optimizer_base(&optimizer)? };
            for m in fig55_figures(&out, &cfg)? {
                println!(
                    "{}: E {} nu {}, residual {:.3} -> {:.3} dx, width/target {}, mid-height ratio {:.3}, min J {:.3}, bodies {:?}, gap {} dx, {} it, {:.1} s",
                    m.case,
                    m.setup.material.youngs_modulus,
                    m.setup.material.poisson_ratio,
                    m.residual_dx[0],
                    m.residual_dx[1],
                    m.width_ratio.map_or("-".into(), |w| format!("{w:.4}")),
                    m.mid_height_ratio,
                    m.min_j,
                    m.bodies.iter().take(3).map(|b| format!("{b:.3}")).collect::<Vec<_>>(),
                    m.gap_dx.map_or("-".into(), |g| format!("{g:.2}")),
                    m.iterations,
                    m.seconds
                );
            }
            Ok(())
        }
        None => deformable(a.run),
    }
}

fn deformable(a: RunArgs) -> Result<()> {
    let need = |o: &Option<PathBuf>, name: &str| o.clone().with_context(|| format!("--{name} is required"));
    let organ = need(&a.organ, "organ")?;
    let lm_path = need(&a.landmarks, "landmarks")?;
    let tg_path = need(&a.target, "target")?;
    let out = need(&a.out, "out")?;
    let base = optimizer_base(&a.optimizer)?;
    if !(a.at_rest_weight >= 0.0 && a.at_rest_weight.is_finite()) {
        bail!("--at-rest-weight {}: must be finite and >= 0", a.at_rest_weight);
    }
    let optimizer = OptimizerConfig {
        iterations: a.iterations.unwrap_or(base.iterations),
        smoothing_dx: if base.kind == OptimizerKind::ThesisGd {
            0.0
        } else {
            a.smoothing_dx.unwrap_or(base.smoothing_dx)
        },
        max_step_dx: a.max_step_dx.unwrap_or(base.max_step_dx),
        target_mean_distance: a.target_mean_mm,
        joint_youngs_modulus: a.joint_e,
        kinetic_weight: a.kinetic_weight,
        terminal_kinetic_weight: a.at_rest_weight,
        ..base
    };
    let unknown = laparo_register::optimize::Unknown::from_name(&a.unknown, a.damping_per_horizon)
        .context("--unknown / --damping-per-horizon")?;
    let optimizer = OptimizerConfig { unknown, ..optimizer };
    let landmarks = read_landmarks(&lm_path)?;
    let crack = match &a.crack {
        Some(p) => {
            let m = laparo_core::mesh::read_mesh(p).with_context(|| format!("--crack {}", p.display()))?;
            Some(laparo_register::crack::CrackSurface::from_mesh(
                &m,
                &format!("--crack {}", p.display()),
                a.crack_band_mm,
            )?)
        }
        None => match a.assumed_cut_depth_mm {
            Some(depth) => {
                let group = match &a.assumed_cut_group {
                    Some(name) => landmarks.iter().find(|g| &g.name == name).with_context(|| {
                        format!(
                            "--assumed-cut-group {name}: no such landmark group in {} (groups: {})",
                            lm_path.display(),
                            landmarks.iter().map(|g| g.name.as_str()).collect::<Vec<_>>().join(", ")
                        )
                    })?,
                    None => landmarks.first().with_context(|| format!("{}: no landmark group", lm_path.display()))?,
                };
                let surface = laparo_register::organ::organ_surface(&organ)?;
                Some(laparo_register::crack::CrackSurface::swept_from_lip(
                    &surface,
                    &group.points,
                    depth,
                    a.crack_band_mm,
                    &format!("--assumed-cut-depth-mm: landmark group `{}`", group.name),
                )?)
            }
            None if a.crack_band_mm.is_some() => bail!("--crack-band-mm needs --crack or --assumed-cut-depth-mm"),
            None => None,
        },
    };
    let organ_config = OrganConfig {
        spacing_mm: a.spacing_mm,
        dx_mm: a.dx_mm,
        youngs_modulus_kpa: a.youngs_modulus_kpa,
        poisson_ratio: a.poisson_ratio,
        density_kg_m3: a.density_kg_m3,
        steps: a.steps,
        dt_s: a.dt_s,
        roi: a.roi.as_deref().map(parse_roi).transpose()?,
        memory_limit_bytes: a.memory_gb.map(|g| g * 1e9),
        ..Default::default()
    };
    let targets = read_targets(&tg_path, &landmarks)?;
    let overlay = match (a.image, a.camera) {
        (Some(i), Some(c)) => Some((i, c)),
        (None, None) => None,
        _ => bail!("--image and --camera go together"),
    };
    let job = Job {
        organ,
        organ_config,
        landmarks,
        targets,
        region_weight: a.region_weight,
        optimizer: optimizer.clone(),
        tumour: a.tumour,
        overlay,
        out: out.clone(),
        resume: a.resume,
        checkpoint_every: a.checkpoint_every,
        crack,
        landmark_offsets: !a.thesis_landmarks,
    };
    let pb = ProgressBar::new(optimizer.iterations as u64);
    pb.set_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} it  {msg}  [{elapsed_precise}]")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let report = run_job(&job, &mut |r| {
        pb.set_position(r.iteration as u64);
        pb.set_message(format!("loss {:.4e}  mean landmark distance {:.3} mm", r.loss, r.mean_distance));
    })?;
    pb.finish_and_clear();
    for w in &report.warnings {
        eprintln!("warning: {w}");
    }
    println!(
        "{} particles ({} fixed), spacing {} mm, Δx {} mm, n_grid {}, T {} × Δt {:.3e} s; mean landmark distance {:.3} → {:.3} mm \
         in {} iterations ({} simulations, {:.2} s each, peak {:.0} MiB); stop: {}",
        report.particles,
        report.fixed_particles,
        report.spacing_mm,
        report.dx_mm,
        report.n_grid,
        report.steps,
        report.dt_s,
        report.mean_distance_mm[0],
        report.mean_distance_mm[1],
        report.iterations,
        report.simulations,
        report.seconds_per_simulation,
        report.peak_memory_mib.unwrap_or(f64::NAN),
        report.stop_reason
    );
    println!("wrote {} (+ report.json)", report.outputs.join(", "));
    let _ = out;
    Ok(())
}

fn rigid(a: RigidArgs) -> Result<()> {
    let inputs: Vec<&std::path::Path> =
        [Some(&a.source), Some(&a.target), a.landmarks.as_ref(), a.target_landmarks.as_ref(), a.init.as_ref()]
            .into_iter()
            .flatten()
            .map(PathBuf::as_path)
            .collect();
    laparo_core::atomic::refuse_overwrite_in(&a.out, &["source_aligned.ply", "transform.json"], &inputs)
        .context("--out")?;
    let src = laparo_core::mesh::read_mesh(&a.source)?;
    let dst = laparo_core::mesh::read_mesh(&a.target)?;
    if src.vertices.is_empty() || dst.vertices.is_empty() {
        bail!("{}: empty", if src.vertices.is_empty() { a.source.display() } else { a.target.display() });
    }
    crate::cmd::check::comparable_clouds(
        (&format!("--source {}", a.source.display()), &src.vertices),
        (&format!("--target {}", a.target.display()), &dst.vertices),
    )?;
    let mut t = Similarity::identity();
    if let Some(p) = &a.init {
        let rec = laparo_core::se3::read_transform(p, "source_to_target").context("--init")?;
        let unit_mm = rec.translation_mm(laparo_core::DepthUnit::Mm);
        t = Similarity { rotation: rec.rotation, translation: unit_mm, scale: rec.scale };
    }
    let mut procrustes_rmse = None;
    match (&a.landmarks, &a.target_landmarks) {
        (Some(l), Some(tl)) => {
            let flat = |g: Vec<SourceGroup>| g.into_iter().flat_map(|g| g.points).collect::<Vec<Vector<3>>>();
            let (ls, lt) = (flat(read_landmarks(l)?), flat(read_landmarks(tl)?));
            if ls.len() != lt.len() {
                bail!("{} has {} landmarks, {} has {}", l.display(), ls.len(), tl.display(), lt.len());
            }
            t = umeyama(&ls, &lt, a.scale)?;
            let moved: Vec<Vector<3>> = ls.iter().map(|p| t.apply(p)).collect();
            procrustes_rmse = Some(rmse(&moved, &lt));
        }
        (None, None) => {}
        _ => bail!("--landmarks and --target-landmarks go together"),
    }
    let mode = match a.icp.as_str() {
        "point-to-point" => Some(IcpMode::PointToPoint),
        "point-to-plane" => Some(IcpMode::PointToPlane),
        "none" => None,
        o => bail!("--icp {o}: expected point-to-point, point-to-plane or none"),
    };
    let mut icp_json = serde_json::Value::Null;
    let mut warnings: Vec<String> = Vec::new();
    let mut icp_rmse = None;
    if let Some(mode) = mode {
        if mode == IcpMode::PointToPlane && dst.faces.is_empty() {
            bail!("{}: point-to-plane ICP needs a target mesh with faces (normals)", a.target.display());
        }
        if let Some(f) = a.overlap {
            if !(f > 0.0 && f <= 1.0) {
                bail!("--overlap {f}: must be in (0, 1]");
            }
        }
        let normals = if dst.faces.is_empty() { None } else { Some(dst.vertex_normals()) };
        let cfg = IcpConfig { mode, ..Default::default() };
        let est = icp_estimate_overlap(&src.vertices, &dst.vertices, normals.as_deref(), t, &cfg, &OVERLAP_CANDIDATES)?;
        let (r, overlap) = match a.overlap {
            None => (est.best.clone(), est.overlap),
            Some(f) => {
                let r = icp(&src.vertices, &dst.vertices, normals.as_deref(), t, &IcpConfig { overlap: f, ..cfg })?;
                let frmsd = r.rmse / f.powf(FRMSD_LAMBDA);
                let best_frmsd = est.best.rmse / est.overlap.powf(FRMSD_LAMBDA);
                let apart = rotation_angle_deg(&r.transform.rotation, &est.best.transform.rotation);
                if best_frmsd < 0.5 * frmsd && apart > 2.0 {
                    warnings.push(format!(
                        "--overlap {f} fits with RMSE {:.3} mm; overlap {} fits with RMSE {:.3} mm at a pose {apart:.1}° away \
                         (fractional RMSD {:.3} vs {:.3} mm): the source and the target may overlap \
                         only in part; leave --overlap out to estimate it",
                        r.rmse, est.overlap, est.best.rmse, best_frmsd, frmsd
                    ));
                }
                (r, f)
            }
        };
        if a.overlap.is_none() {
            let rivals = est.rivals(2.0, 2.0);
            if !rivals.is_empty() {
                warnings.push(format!(
                    "ambiguous fit: overlap {} (RMSE {:.3} mm) was kept, but {} scored within a factor 2 of it at poses \
                     {} away: the alignment from this initial pose is not unique (give --landmarks or --init)",
                    est.overlap,
                    est.best.rmse,
                    rivals
                        .iter()
                        .map(|t| format!("overlap {:.2} (RMSE {:.3} mm)", t.overlap, t.rmse_mm))
                        .collect::<Vec<_>>()
                        .join(", "),
                    rivals.iter().map(|t| format!("{:.1}°", t.degrees_from_chosen)).collect::<Vec<_>>().join(", ")
                ));
            }
        }
        let diag = bbox_diagonal(&src.vertices);
        if r.rmse > POOR_FIT_FRACTION * diag {
            warnings.push(format!(
                "poor fit: ICP RMSE {:.3} mm over the {:.0} % closest pairs is {:.1} % of the source's size ({diag:.1} mm \
                 bounding-box diagonal; over {:.0} % is suspect): a wrong overlap, an initial pose too far off \
                 (--landmarks / --init) or a source that is not the target's shape",
                r.rmse,
                100.0 * overlap,
                100.0 * r.rmse / diag,
                100.0 * POOR_FIT_FRACTION
            ));
        }
        icp_json = serde_json::json!({
            "mode": a.icp, "overlap": overlap, "overlap_estimated": a.overlap.is_none(),
            "trimmed_rmse_mm": r.rmse, "iterations": r.iterations,
            "overlap_trials": est.trials, "frmsd_lambda": FRMSD_LAMBDA,
        });
        t = r.transform;
        icp_rmse = Some(r.rmse);
    }
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let aligned = laparo_core::mesh::TriMesh {
        vertices: src.vertices.iter().map(|p| t.apply(p)).collect(),
        faces: src.faces.clone(),
    };
    laparo_core::mesh::write_ply(a.out.join("source_aligned.ply"), &aligned)?;
    let mut body = serde_json::json!({
        "source_to_target": laparo_core::se3::transform_json(&t.rotation, &t.translation, t.scale),
        "convention": "p_target = scale * R @ p_source + t_mm (R: list of rows; T: the same as one 4x4 matrix)",
        "source": a.source, "target": a.target, "warnings": warnings,
    });
    // figures only for the steps that ran (no bare null)
    if let Some(v) = procrustes_rmse {
        body["procrustes_rmse_mm"] = v.into();
    }
    if let Some(v) = icp_rmse {
        body["icp_rmse_mm"] = v.into();
        body["icp"] = icp_json.clone();
    }
    laparo_core::atomic::write_atomic(&a.out.join("transform.json"), serde_json::to_string_pretty(&body)?.as_bytes())?;
    for w in &warnings {
        eprintln!("warning: {w}");
    }
    println!(
        "rigid: Procrustes RMSE {} mm, ICP RMSE {} mm{}, scale {:.6}; wrote {}",
        procrustes_rmse.map_or("-".into(), |v| format!("{v:.4}")),
        icp_rmse.map_or("-".into(), |v| format!("{v:.4}")),
        icp_json["overlap"].as_f64().map_or(String::new(), |f| format!(
            " (overlap {f}{})",
            if a.overlap.is_none() { ", estimated" } else { "" }
        )),
        t.scale,
        a.out.join("transform.json").display()
    );
    Ok(())
}

/// An ICP RMSE above this fraction of the source's bounding-box diagonal is reported as a poor fit.
const POOR_FIT_FRACTION: f64 = 0.03;

fn synth(a: SynthArgs) -> Result<()> {
    laparo_core::atomic::refuse_overwrite_files(&[&a.landmarks_out, &a.targets_out], &[&a.organ, &a.contours])
        .context("--landmarks-out / --targets-out")?;
    let mesh = laparo_core::mesh::read_mesh(&a.organ)?;
    let mut groups = read_p2ilf_contours(&a.contours, &mesh.vertices)?;
    if let Some(only) = &a.only {
        groups.retain(|g| g.name.starts_with(only.as_str()));
        if groups.is_empty() {
            bail!("{}: no contour of type {only}", a.contours.display());
        }
    }
    // smooth field: u(x) = A ⊙ sin(k·(x − c) + φ), scaled to max |u| over the landmarks = max_displacement_mm
    let all: Vec<Vector<3>> = groups.iter().flat_map(|g| g.points.clone()).collect();
    let c = all.iter().sum::<Vector<3>>() / all.len() as f64;
    let field = |x: &Vector<3>| {
        let r = (x - c) / 60.0;
        Vector::<3>::new(
            (r[0] + 0.3).sin() + 0.5 * r[1],
            (1.3 * r[1] - 0.2).sin() - 0.4 * r[2],
            (0.7 * r[2] + 0.9 * r[0]).cos(),
        )
    };
    let m = all.iter().map(|x| field(x).norm()).fold(0.0, f64::max);
    let s = a.max_displacement_mm / m;
    let pts = |g: &SourceGroup| g.points.iter().map(|p| [p[0], p[1], p[2]]).collect::<Vec<_>>();
    let moved =
        |g: &SourceGroup| g.points.iter().map(|p| p + field(p) * s).map(|p| [p[0], p[1], p[2]]).collect::<Vec<_>>();
    let l = serde_json::json!({"groups": groups.iter().map(|g| serde_json::json!({"name": g.name, "points": pts(g)})).collect::<Vec<_>>()});
    let t = serde_json::json!({"groups": groups.iter().map(|g| serde_json::json!({"name": g.name, "type": "points", "points": moved(g)})).collect::<Vec<_>>()});
    laparo_core::atomic::write_atomic(&a.landmarks_out, serde_json::to_string_pretty(&l)?.as_bytes())?;
    laparo_core::atomic::write_atomic(&a.targets_out, serde_json::to_string_pretty(&t)?.as_bytes())?;
    println!("{} landmarks in {} groups, displaced by up to {} mm", all.len(), groups.len(), a.max_displacement_mm);
    Ok(())
}
