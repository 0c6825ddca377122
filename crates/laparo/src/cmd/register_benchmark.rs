//! `laparo register benchmark`: the in-silico incision benchmark (thesis §5.4.2, Table 5.1, Figs. 5.7–5.9)
//! on a real liver: tetrahedralise, cut (two scenarios), FEM ground truth (TET10 Neo-Hookean, calibrated
//! pressure on the crack faces), then ARAP, DRBC, François et al., LDDMM and RODS-MPM on the same landmarks,
//! scored by TRE at every node. Resumable per (method, column, seed); deterministic.
use anyhow::{bail, Context, Result};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use laparo_core::mesh::{write_vtk_fields, VtkField, VtkValues};
use laparo_fem::mesh::{
    anatomical_on, non_anatomical_on, tetrahedralize_surface, Scenario, ScenarioFrame, TetraParams,
};
use laparo_register::baselines::{ArapConfig, ArapEnergy, DrbcConfig, LddmmConfig};
use laparo_register::benchmark::build::{
    case_from, choose_roi, crack_gap_by_node_mm, fem_ground_truth_field, CrackResolution, GroundTruthConfig,
    GroundTruthKind, GroundTruthReport,
};
use laparo_register::benchmark::figures::{
    write_crack_opening, write_distance_plot, write_sweep_plot, write_tre_map, SurfaceView, SweepPanel, SweepPoint,
};
use laparo_register::benchmark::methods::{Baseline, BaselineMethod, CutDirection};
use laparo_register::benchmark::{
    aggregate, run_protocol, table51_columns, table_csv, table_json, table_markdown, Column, Method, OracleMode,
    ResultStore, RodsMethod, Rung, TwoField, RODS_MPM_NAME,
};
use laparo_register::optimize::OptimizerConfig;
use laparo_register::organ::OrganConfig;
use nalgebra::Vector3;
use std::path::{Path, PathBuf};

/// Arguments of `laparo register benchmark`.
#[derive(Args)]
pub struct BenchmarkArgs {
    /// Scenario: non-anatomical, anatomical or all (default all; quick: non-anatomical, since at the quick
    /// tier's 16 mm tetrahedra the anatomical cut detaches a fragment: use --edge-mm 12 or finer for it).
    #[arg(long)]
    pub scenario: Option<String>,
    /// Output folder (resumes what is already there).
    #[arg(long)]
    pub out: PathBuf,
    /// Closed liver surface (OBJ/PLY/STL, mm); default: the P2ILF patient liver under ../shared/data.
    #[arg(long)]
    pub liver: Option<PathBuf>,
    /// The tier the test suite affords: coarse mesh, one seed, short RODS-MPM runs. A smoke test that the
    /// benchmark runs end to end, not a ranking of the methods (its table says so).
    #[arg(long)]
    pub quick: bool,
    /// Tetrahedron edge (mm); default 10 (quick 16). The FEM solves its Newton systems by two-level conjugate
    /// gradients, in memory linear in the mesh (0.3 GB at 10 mm, 1.7 GB at 6 mm, where a direct Cholesky factor
    /// would hold 20.6 GB); 10 mm is the mesh whose whole protocol is measured overnight-safe.
    #[arg(long)]
    pub edge_mm: Option<f64>,
    /// Noise seeds per noisy column; default 5 (quick 1).
    #[arg(long)]
    pub seeds: Option<usize>,
    /// Methods, comma separated, among none (the rest mesh: the error of not registering), arap, drbc,
    /// francois, lddmm, rods, rods-two-field (RODS-MPM on laparo-mpm's two-field grid along the cut
    /// François et al. assume: --francois-depth-mm); and the diagnostics rods-ballistic, rods-dense
    /// (RODS-MPM oracles that read the ground truth: what the simulator can represent, not a registration
    /// method; with the suffix -two-field, on the two-field grid), rods-readback (no simulation: the
    /// ground truth read back from the particles to the nodes, the transfer's error floor). arap-roi,
    /// drbc-roi, francois-roi: the baseline with RODS-MPM's region of interest, its nodes outside held at
    /// rest (what RODS-MPM is told about where the tissue does not move; run where the case has a ball).
    /// The floors (floor-p1: the ground truth at the mesh nodes read by P1; floor-rods = rods-readback) and the
    /// thesis fidelity rows (rods-thesis: one field, plain GD from v₀ = 0, 500 iterations; rods-thesis-kerf: the
    /// same on a source with the blade volume (2 Δx) removed, which uses the true crack) are always added beside
    /// the methods they bound: the floors in every column, the thesis rows (with RODS-MPM) in the 50-landmark
    /// column.
    #[arg(long, default_value = "none,arap,drbc,francois,lddmm,rods")]
    pub methods: String,
    /// Region of interest of every method (identical for all): a-priori (a ball of radius 1.5 × the source lip
    /// length about the lip centroid: the mesh methods hold their nodes outside it at rest, RODS-MPM simulates
    /// inside it), none (the whole organ), or ground-truth (v1: the smallest ball whose boundary the ground truth
    /// barely moves, RODS-MPM only; chosen from the ground truth, so no headline may read it).
    #[arg(long, default_value = "a-priori")]
    pub roi: String,
    /// Spacing (mm) of the common evaluation lattice inside the source organ (plus crack-face points at about
    /// the same density, both sides).
    #[arg(long, default_value_t = 2.0)]
    pub eval_spacing_mm: f64,
    /// Ground truths per scenario, comma separated: pressure (crack-face pressure), grasper (retraction by patch
    /// loads on each lip), stiff-inclusion (the pressure loading on a liver with a 5× stiffer inclusion; every
    /// method keeps Neo-Hookean 4.1 kPa / 0.49). Default all three (quick: pressure).
    #[arg(long)]
    pub ground_truths: Option<String>,
    /// Run on even where RODS-MPM's floor (the ground truth read back through its particles) exceeds ¼ of
    /// "none"'s TRE within 10 mm of the lips (else an error naming --spacing-mm): those bins are then marked
    /// not comparable.
    #[arg(long)]
    pub allow_coarse_floor: bool,
    /// Also write, for every run of the 50-landmark column (seed 0), `<case>/points/<method>.csv`: each
    /// evaluation point's rest position (mm), side, kind, distances to the lips and the crack (mm) and TRE (mm).
    #[arg(long)]
    pub write_points: bool,
    /// DRBC (and François et al.'s DRBC): factor on DRBC's default elastic weight λ.
    #[arg(long, default_value_t = 1.0)]
    pub drbc_lambda_factor: f64,
    /// Frozen hyperparameters (a `frozen.json` written by --tune on ANOTHER case): they replace
    /// --francois-depth-mm, --drbc-lambda-factor, --lddmm-sigma-mm and --kinetic-weight; a test case equal to the
    /// tuning case (the same cut mesh) is refused.
    #[arg(long)]
    pub frozen: Option<PathBuf>,
    /// Tune instead of test: run the tuning grid (François depth, DRBC λ factor, LDDMM σ, RODS-MPM κ, one at a
    /// time, 50 noiseless landmarks) on this case, keep each value with the lowest mean TRE within 10 mm of the
    /// lips, and write OUT/frozen.json for a test run on another case (e.g. another --cut-offset-mm).
    #[arg(long)]
    pub tune: bool,
    /// Tetrahedron edge (mm) of the methods' own mesh: an independent tetrahedralisation of the same surface, cut
    /// by the same blade, so no method registers on the ground truth's mesh (the ground truth is read at its nodes
    /// on their own side, the common points are located in it); default 0.85 × --edge-mm. Equal to --edge-mm:
    /// the methods run on the ground truth's mesh (the v1 protocol).
    #[arg(long)]
    pub method_edge_mm: Option<f64>,
    /// RODS-MPM particle spacing (mm); default 3 (quick 4: at 6 mm its floor within 5 mm of the lips exceeds ¼ of "none"'s TRE).
    #[arg(long)]
    pub spacing_mm: Option<f64>,
    /// RODS-MPM optimiser iterations; default 60 (quick 8).
    #[arg(long)]
    pub iterations: Option<usize>,
    /// RODS-MPM optimiser preset: lbfgs (smoothed L-BFGS), tear (unsmoothed, for targets that pull
    /// neighbouring particles apart), adam or thesis-gd (as `laparo register --optimizer`).
    #[arg(long, default_value = "lbfgs")]
    pub optimizer: String,
    /// RODS-MPM's Poisson ratio (default 0.49, the ground truth's; the Fig. 5.9 ν panel sweeps it).
    #[arg(long)]
    pub poisson_ratio: Option<f64>,
    /// RODS-MPM grid cell Δx (mm); default 2 × the particle spacing.
    #[arg(long)]
    pub dx_mm: Option<f64>,
    /// The oracles (rods-ballistic, rods-dense) first remove the particles within half this width (mm) of the
    /// ground truth's crack faces: a kerf the simulator can see (0 = none).
    #[arg(long, default_value_t = 0.0)]
    pub oracle_kerf_mm: f64,
    /// RODS-MPM least-action prior κ (default 0: the thesis' unregularised loss): adds
    /// κ · mean |v₀ T Δt|² / (2 Δx) over the free particles to eq. 5.10.
    #[arg(long, default_value_t = 0.0)]
    pub kinetic_weight: f64,
    /// At-rest prior λ of the ladder's rung L2 (`--methods rods-l2`; the other rungs run with 0): adds
    /// λ · Σ m |v_T T Δt|² / (2 M Δx), the terminal kinetic energy, so the registered state is at rest.
    /// Fixed a priori at 1 (the scale of κ), not tuned on the test case.
    #[arg(long, default_value_t = 1.0)]
    pub at_rest_weight: f64,
    /// RODS-MPM region of interest: a ball of this radius (mm) around the crack, its boundary particles
    /// fixed, whatever the ground truth moves there (reported); default: the smallest ball from 50 to
    /// 120 mm whose boundary moves < 0.5 mm in the ground truth, else the whole organ.
    #[arg(long)]
    pub roi_mm: Option<f64>,
    /// RODS-MPM horizon T (steps); default 200 (quick 60).
    #[arg(long)]
    pub steps: Option<usize>,
    /// The crack of the two-field methods: assumed (François et al.'s cut, --francois-depth-mm) or true (the
    /// ground truth's crack faces: a diagnostic, the crack's extent is not known intraoperatively).
    #[arg(long, default_value = "assumed")]
    pub two_field_crack: String,
    /// The assumed cut (François et al., rods-two-field) leaves the source lip along the surface's inward
    /// normal (normal) or inward in the plane the target lips open across (separation).
    #[arg(long, default_value = "normal")]
    pub assumed_cut_direction: String,
    /// François et al.: assumed cut depth (mm) under the source lip polyline.
    #[arg(long, default_value_t = 20.0)]
    pub francois_depth_mm: f64,
    /// LDDMM kernel width σ_K (mm).
    #[arg(long, default_value_t = 20.0)]
    pub lddmm_sigma_mm: f64,
    /// Also run the sensitivity sweeps (Fig. 5.9: E, ν, spacing, grid, horizon; LDDMM width) at 50 landmarks.
    #[arg(long)]
    pub sweeps: bool,
    /// RODS-MPM's adjoint checkpoint budget (GB): beyond it the adjoint keeps every k-th step and recomputes
    /// the rest (the same gradient, one more forward pass), so the whole benchmark stays within 8 GB.
    #[arg(long, default_value_t = 6.0)]
    pub memory_gb: f64,
    /// FEM load increments per solve; default 20 (quick 8).
    #[arg(long)]
    pub fem_steps: Option<usize>,
    /// The ground truth's calibration target "LO,HI": the largest lip gap (mm) the crack pressure is tuned to
    /// reach; default 10,15 (non-anatomical) or 20,30 (anatomical), register.md §4. One scenario only.
    #[arg(long)]
    pub target_gap_mm: Option<String>,
    /// Another blade or fixed region than the benchmark's (each changes the ground truth, which is solved
    /// again; a folder never mixes runs of two cuts).
    #[command(flatten)]
    pub cut: crate::cmd::mesh::CutArgs,
}

/// `--target-gap-mm LO,HI` (mm).
fn parse_gap(s: &str) -> Result<[f64; 2]> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<std::result::Result<_, _>>()
        .with_context(|| format!("--target-gap-mm '{s}': expected two numbers LO,HI (mm)"))?;
    match v[..] {
        [lo, hi] if lo.is_finite() && hi.is_finite() && 0.0 < lo && lo <= hi => Ok([lo, hi]),
        _ => bail!("--target-gap-mm '{s}': expected LO,HI with 0 < LO <= HI (mm)"),
    }
}

pub(crate) fn default_liver() -> Option<PathBuf> {
    let p = PathBuf::from("../shared/data/meshes/p2ilf/patient2_1_3d-liver-model.obj");
    p.exists().then_some(p)
}

pub(crate) fn write_json(path: &Path, v: &impl serde::Serialize) -> Result<()> {
    laparo_core::atomic::write_atomic(path, (serde_json::to_string_pretty(v)? + "\n").as_bytes())?;
    Ok(())
}

/// Fingerprint of everything the FEM ground truth is solved from: the cut mesh, its crack faces (where the
/// pressure acts), the fixed nodes and the solver configuration.
pub(crate) fn ground_truth_inputs(scn: &Scenario, cfg: &GroundTruthConfig) -> String {
    let mut b: Vec<u8> = format!("{cfg:?}").into_bytes();
    scn.cut.mesh.vertices.iter().flat_map(|p| p.iter()).for_each(|c| b.extend(c.to_bits().to_le_bytes()));
    let ids = scn.cut.mesh.tets.iter().flatten().chain(scn.cut.crack_faces.iter().flatten().flatten());
    ids.chain(&scn.fixed_nodes).for_each(|&i| b.extend((i as u64).to_le_bytes()));
    laparo_core::atomic::fnv1a64_hex(&b)
}

/// A stored TET10 ground truth: every TET10 node's displacement (mm) and its report.
pub(crate) type StoredGroundTruth = (Vec<Vector3<f64>>, GroundTruthReport);

/// The TET10 ground truth stored at `path` (`{"inputs", "report", "displacement_p2_mm"}`) when it was solved
/// from `inputs` for `scn`'s mesh: Ok(Ok(field, report)); Ok(Err(the inputs it was solved from)) otherwise.
pub(crate) fn cached_ground_truth(
    path: &Path,
    scn: &Scenario,
    inputs: &str,
) -> Result<std::result::Result<StoredGroundTruth, String>> {
    // the whole TET10 field: vertices first, then the edge nodes of Tet10Mesh::from_linear
    let n = laparo_fem::solid::Tet10Mesh::from_linear(&scn.cut.mesh)?.n_nodes();
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(path)?).with_context(|| path.display().to_string())?;
    let flat: Vec<f64> =
        v["displacement_p2_mm"].as_array().map(|a| a.iter().filter_map(|x| x.as_f64()).collect()).unwrap_or_default();
    if flat.len() == 3 * n && v["inputs"].as_str() == Some(inputs) {
        let u = (0..n).map(|i| Vector3::new(flat[3 * i], flat[3 * i + 1], flat[3 * i + 2])).collect();
        let report: GroundTruthReport =
            serde_json::from_value(v["report"].clone()).with_context(|| path.display().to_string())?;
        return Ok(Ok((u, report)));
    }
    Ok(Err(v["inputs"].as_str().unwrap_or("none recorded").to_string()))
}

/// Ground truth from `dir/ground_truth.json` when it was solved from the same inputs ([`ground_truth_inputs`]),
/// else solved and saved; refused when `store` holds runs of the scenario made on another ground truth (the
/// folder would then hold a ground truth and runs that do not belong together).
fn ground_truth(
    dir: &Path,
    store: &ResultStore,
    scn: &Scenario,
    cfg: &GroundTruthConfig,
) -> Result<(Vec<Vector3<f64>>, GroundTruthReport)> {
    let path = dir.join("ground_truth.json");
    let inputs = format!("v2-p2 {}", ground_truth_inputs(scn, cfg));
    if path.exists() {
        let stored = match cached_ground_truth(&path, scn, &inputs)? {
            Ok(hit) => return Ok(hit),
            Err(stored) => stored,
        };
        if store.holds_runs(&scn.name) {
            bail!(
                "{}: solved from other inputs (mesh, blade, fixed region or FEM settings: {stored:?}, now {inputs:?}) \
                 and the folder holds {} runs made on it: write to another --out folder to benchmark another mesh or cut",
                path.display(),
                scn.name
            );
        }
        eprintln!("{}: solved from other inputs ({stored:?}, now {inputs:?}): solving again", path.display());
    }
    let pb = ProgressBar::new_spinner();
    pb.set_message(format!("{}: FEM ground truth (TET10 Neo-Hookean), calibrating the crack pressure", scn.name));
    pb.enable_steady_tick(std::time::Duration::from_millis(200));
    let (field, report) = fem_ground_truth_field(scn, cfg, &mut |k, p, g| {
        pb.suspend(|| {
            eprintln!("{}: FEM solve {} at load factor {p:.4} → calibration quantity {g:.2} mm", scn.name, k + 1)
        });
    })?;
    pb.finish_and_clear();
    let u = field.p2_displacement_mm;
    let flat: Vec<f64> = u.iter().flat_map(|x| [x[0], x[1], x[2]]).collect();
    write_json(&path, &serde_json::json!({"inputs": inputs, "report": report, "displacement_p2_mm": flat}))?;
    Ok((u, report))
}

/// RODS-MPM's optimiser: the `--optimizer` preset with `--iterations` (default 60, quick 8).
fn rods_optimizer(a: &BenchmarkArgs, quick: bool) -> Result<OptimizerConfig> {
    let preset = crate::cmd::register::optimizer_base(&a.optimizer)?;
    if !(a.kinetic_weight >= 0.0 && a.kinetic_weight.is_finite()) {
        bail!("--kinetic-weight {}: must be finite and >= 0", a.kinetic_weight);
    }
    if !(a.at_rest_weight >= 0.0 && a.at_rest_weight.is_finite()) {
        bail!("--at-rest-weight {}: must be finite and >= 0", a.at_rest_weight);
    }
    Ok(OptimizerConfig {
        iterations: a.iterations.unwrap_or(if quick { 8 } else { 60 }),
        kinetic_weight: a.kinetic_weight,
        ..preset
    })
}

/// RODS-MPM's organ set-up from `--spacing-mm`, `--steps`, `--dx-mm` and `--poisson-ratio` (the default run and
/// the base every Fig. 5.9 sweep setting varies one parameter of).
fn rods_organ(a: &BenchmarkArgs, quick: bool) -> Result<OrganConfig> {
    let base = OrganConfig::default();
    let organ = OrganConfig {
        spacing_mm: a.spacing_mm.unwrap_or(if quick { 4.0 } else { 3.0 }),
        steps: a.steps.unwrap_or(if quick { 60 } else { 200 }),
        dx_mm: a.dx_mm,
        poisson_ratio: a.poisson_ratio.unwrap_or(base.poisson_ratio),
        memory_limit_bytes: Some(a.memory_gb * 1e9),
        ..base
    };
    if !(a.memory_gb > 0.0 && a.memory_gb.is_finite()) {
        bail!("--memory-gb {}: must be finite and > 0", a.memory_gb);
    }
    organ.time_step_s().context("RODS-MPM's set-up (--spacing-mm, --dx-mm, --poisson-ratio, --steps)")?;
    Ok(organ)
}

/// `--roi`: how the region of interest is chosen.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum RoiMode {
    /// 1.5 × the lip length about the lip centroid, every method.
    APriori,
    /// The whole organ.
    None,
    /// v1: chosen from the ground truth, RODS-MPM only.
    GroundTruth,
}

fn roi_mode(a: &BenchmarkArgs) -> Result<RoiMode> {
    match a.roi.as_str() {
        "a-priori" => Ok(RoiMode::APriori),
        "none" => Ok(RoiMode::None),
        "ground-truth" => Ok(RoiMode::GroundTruth),
        o => bail!("--roi {o:?}: expected a-priori, none or ground-truth"),
    }
}

/// The a-priori region of interest: a ball of radius 1.5 × the source lip length about the lips' centroid.
fn a_priori_roi(c: &laparo_register::benchmark::BenchmarkCase) -> laparo_register::organ::Roi {
    let centre = incision_centre(c);
    let lip = &c.lips[0];
    let length: f64 = lip.windows(2).map(|w| (c.rest[w[1]] - c.rest[w[0]]).norm()).sum();
    laparo_register::organ::Roi::Ball { center: [centre.x, centre.y, centre.z], radius_mm: 1.5 * length }
}

fn methods(a: &BenchmarkArgs, quick: bool) -> Result<Vec<Box<dyn Method>>> {
    let shared_roi = roi_mode(a)? == RoiMode::APriori;
    let organ = rods_organ(a, quick)?;
    if !(a.oracle_kerf_mm >= 0.0 && a.oracle_kerf_mm.is_finite()) {
        bail!("--oracle-kerf-mm {}: must be finite and >= 0", a.oracle_kerf_mm);
    }
    let optimizer = rods_optimizer(a, quick)?;
    let mut out: Vec<Box<dyn Method>> = Vec::new();
    for m in a.methods.split(',').map(|s| s.trim().to_ascii_lowercase()) {
        // `-roi`: the baseline with RODS-MPM's region of interest (nodes outside it held at rest)
        let (base, hold_outside_roi) = match m.strip_suffix("-roi") {
            Some(b) if ["arap", "drbc", "francois"].contains(&b) => {
                if shared_roi {
                    bail!("--methods {m}: with --roi a-priori every method already holds the same region of interest; give {b}");
                }
                (b, true)
            }
            _ => (m.as_str(), false),
        };
        let b = |name: &str, baseline| {
            let name = if hold_outside_roi { format!("{name} (ROI)") } else { name.into() };
            let hold_outside_roi = hold_outside_roi || shared_roi;
            Box::new(BaselineMethod { name, baseline, hold_outside_roi }) as Box<dyn Method>
        };
        out.push(match base {
            // per-element rotations (libigl's tet default): cotangent spokes are unreliable on obtuse tets
            "arap" => b("ARAP", Baseline::Arap(ArapConfig { energy: ArapEnergy::Elements, ..Default::default() })),
            // diagnostics that read the ground truth (not registration methods: see RodsOracle)
            "floor-p1" => Box::new(laparo_register::benchmark::methods::P1Floor),
            "rods-thesis" | "rods-thesis-kerf" => Box::new(thesis_row(a, quick, m.ends_with("-kerf"))?),
            "rods-ballistic" | "rods-dense" | "rods-ballistic-two-field" | "rods-dense-two-field" | "rods-readback"
            | "floor-rods" => {
                Box::new(laparo_register::benchmark::rods::RodsOracle {
                    inner: RodsMethod {
                        organ: organ.clone(),
                        optimizer: optimizer.clone(),
                        two_field: m.ends_with("-two-field").then(|| two_field(a)).transpose()?,
                        rung: None,
                    },
                    mode: match m.as_str() {
                        "rods-readback" | "floor-rods" => OracleMode::Readback,
                        m if m.starts_with("rods-ballistic") => OracleMode::Ballistic,
                        _ => OracleMode::Dense,
                    },
                    kerf_mm: a.oracle_kerf_mm,
                })
            }
            "none" => Box::new(laparo_register::benchmark::methods::NoRegistration),
            "drbc" => b("DRBC", Baseline::Drbc(drbc_config(a))),
            "francois" => b(
                "François et al.",
                Baseline::Francois {
                    drbc: drbc_config(a),
                    assumed_depth_mm: a.francois_depth_mm,
                    direction: cut_direction(a)?,
                },
            ),
            "lddmm" => b("LDDMM", Baseline::Lddmm(LddmmConfig { sigma_mm: a.lddmm_sigma_mm, ..Default::default() })),
            "rods" | "rods-mpm" => {
                Box::new(RodsMethod { organ: organ.clone(), optimizer: optimizer.clone(), two_field: None, rung: None })
            }
            // laparo-mpm's two-field grid along the crack of --two-field-crack (assumed: François et al.'s cut)
            "rods-two-field" => Box::new(RodsMethod {
                organ: organ.clone(),
                optimizer: optimizer.clone(),
                two_field: Some(two_field(a)?),
                rung: None,
            }),
            // the RODS-MPM ladder (L0 thesis, L1 two fields on the assumed Σ, L2 at rest)
            r if Rung::from_method_name(r).is_some() => {
                let rung = Rung::from_method_name(r).expect("matched");
                Box::new(RodsMethod {
                    organ: organ.clone(),
                    optimizer: rung.optimizer(&optimizer, a.at_rest_weight),
                    two_field: rung.two_field().then(|| two_field(a)).transpose()?,
                    rung: Some(rung),
                })
            }
            _ => bail!("--methods: unknown method {m:?} (expected none, arap, drbc, francois, lddmm, rods, rods-two-field, rods-l0, rods-l1-blind, rods-l1, rods-l2, rods-l3, rods-thesis, rods-thesis-kerf, floor-p1, floor-rods, rods-ballistic, rods-dense, rods-ballistic-two-field, rods-dense-two-field, rods-readback; arap-roi, drbc-roi, francois-roi hold RODS-MPM's region of interest with --roi none or ground-truth)"),
        });
    }
    if out.is_empty() {
        bail!("--methods: empty");
    }
    // the floors of every listed method are always reported (a row without its floor cannot be read)
    let mut names: Vec<String> = out.iter().map(|m| m.name()).collect();
    let floors: Vec<String> = out.iter().filter_map(|m| m.floor()).collect();
    for f in floors {
        if names.contains(&f) {
            continue;
        }
        names.push(f.clone());
        if f == laparo_register::benchmark::methods::P1_FLOOR_NAME {
            out.push(Box::new(laparo_register::benchmark::methods::P1Floor));
        } else {
            out.push(Box::new(laparo_register::benchmark::rods::RodsOracle {
                inner: RodsMethod { organ: organ.clone(), optimizer: optimizer.clone(), two_field: None, rung: None },
                mode: OracleMode::Readback,
                kerf_mm: 0.0,
            }));
        }
    }
    Ok(out)
}

/// DRBC's settings (`--drbc-lambda-factor`).
fn drbc_config(a: &BenchmarkArgs) -> DrbcConfig {
    DrbcConfig { lambda_factor: a.drbc_lambda_factor, ..Default::default() }
}

/// Fingerprint of a case's cut mesh (vertices, tetrahedra, crack faces): equal for two ground truths of one
/// blade on one mesh whatever their loading, so a tuning case and a test case are told apart by their cut.
fn cut_fingerprint(scn: &Scenario) -> String {
    let mut b: Vec<u8> = Vec::new();
    scn.cut.mesh.vertices.iter().flat_map(|p| p.iter()).for_each(|c| b.extend(c.to_bits().to_le_bytes()));
    let ids = scn.cut.mesh.tets.iter().flatten().chain(scn.cut.crack_faces.iter().flatten().flatten());
    ids.for_each(|&i| b.extend((i as u64).to_le_bytes()));
    laparo_core::atomic::fnv1a64_hex(&b)
}

/// `--tune`: the tuning grid's rows on `cases` (50 noiseless landmarks), the selection, OUT/frozen.json.
fn tune(
    a: &BenchmarkArgs,
    quick: bool,
    cases: &[laparo_register::benchmark::BenchmarkCase],
    fingerprints: Vec<String>,
    store: &ResultStore,
) -> Result<()> {
    use laparo_register::benchmark::tuning::{select, tuning_row_name, FrozenSettings, Knob, TuningGrid};
    let grid = TuningGrid::default();
    let shared_roi = roi_mode(a)? == RoiMode::APriori;
    let mut rows: Vec<Box<dyn Method>> = Vec::new();
    for (knob, v) in grid.candidates() {
        let name = tuning_row_name(knob, v);
        let baseline = |baseline| -> Box<dyn Method> {
            Box::new(BaselineMethod { name: name.clone(), baseline, hold_outside_roi: shared_roi })
        };
        rows.push(match knob {
            Knob::FrancoisDepth => {
                baseline(Baseline::Francois { drbc: drbc_config(a), assumed_depth_mm: v, direction: cut_direction(a)? })
            }
            Knob::DrbcLambda => baseline(Baseline::Drbc(DrbcConfig { lambda_factor: v, ..Default::default() })),
            Knob::LddmmSigma => baseline(Baseline::Lddmm(LddmmConfig { sigma_mm: v, ..Default::default() })),
            Knob::RodsKinetic => Box::new(NamedRods {
                name: name.clone(),
                inner: RodsMethod {
                    organ: rods_organ(a, quick)?,
                    optimizer: OptimizerConfig { kinetic_weight: v, ..rods_optimizer(a, quick)? },
                    two_field: None,
                    rung: None,
                },
            }),
        });
    }
    let refs: Vec<&dyn Method> = rows.iter().map(|m| m.as_ref()).collect();
    let pb = ProgressBar::new(refs.len() as u64 * cases.len() as u64);
    pb.set_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} tuning runs  {msg}  [{elapsed_precise}]")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let column = Column { landmarks: 50, noise_sigma_mm: 0.0 };
    let results = run_protocol(cases, &refs, &[column], 1, store, &mut |e| {
        pb.set_position(e.done as u64);
        pb.set_message(e.result.key.method.clone());
    })?;
    pb.finish_and_clear();
    let cells = aggregate(&results);
    let (hyperparameters, candidates) = select(&grid, &cells)?;
    let frozen = FrozenSettings {
        hyperparameters,
        tuning_case_fingerprints: fingerprints,
        tuning_case: format!(
            "{}: {} ({:?}, edge {} mm)",
            cases.iter().map(|c| c.scenario.as_str()).collect::<Vec<_>>().join(", "),
            a.liver.clone().or_else(default_liver).map(|p| p.display().to_string()).unwrap_or_default(),
            a.cut,
            a.edge_mm.unwrap_or(if quick { 16.0 } else { 10.0 })
        ),
        candidates,
    };
    let path = a.out.join("frozen.json");
    write_json(&path, &frozen)?;
    for (name, score) in &frozen.candidates {
        println!("{name}: {score:.3} mm within 10 mm of the lips");
    }
    println!("frozen: {:?}\nwrote {}", frozen.hyperparameters, path.display());
    Ok(())
}

/// A thesis fidelity row: one field, plain gradient descent from v₀ = 0 (500 iterations; quick: the quick
/// tier's --iterations), optionally on a source with a 2 Δx kerf along the true crack.
fn thesis_row(a: &BenchmarkArgs, quick: bool, kerf: bool) -> Result<laparo_register::benchmark::rods::ThesisRods> {
    let organ = rods_organ(a, quick)?;
    let iterations = if quick { a.iterations.unwrap_or(8) } else { 500 };
    let optimizer = OptimizerConfig { iterations, ..OptimizerConfig::thesis() };
    let dx = organ.dx_mm.unwrap_or(2.0 * organ.spacing_mm);
    Ok(laparo_register::benchmark::rods::ThesisRods {
        inner: RodsMethod { organ, optimizer, two_field: None, rung: None },
        kerf_mm: if kerf { 2.0 * dx } else { 0.0 },
    })
}

/// Fig. 5.9 panels: axis label and whether the axis is logarithmic; a sweep setting names its panel by index.
const SWEEP_PANELS: [(&str, bool); 5] = [
    ("E / 4.1 kPa (Young's modulus factor)", true),
    ("Poisson ratio ν", false),
    ("particle spacing [mm]", false),
    ("grid cell Δx [mm]", false),
    ("horizon T [steps]", false),
];

/// One sweep setting: the method, and for RODS-MPM settings the panel and value it plots at.
struct SweepSetting {
    method: Box<dyn Method>,
    panel: Option<(usize, f64)>,
}

/// `--assumed-cut-direction`.
fn cut_direction(a: &BenchmarkArgs) -> Result<CutDirection> {
    match a.assumed_cut_direction.as_str() {
        "normal" => Ok(CutDirection::SurfaceNormal),
        "separation" => Ok(CutDirection::LipSeparation),
        o => bail!("--assumed-cut-direction: {o:?} is neither normal nor separation"),
    }
}

/// The crack of the two-field methods (`--two-field-crack`).
fn two_field(a: &BenchmarkArgs) -> Result<TwoField> {
    match a.two_field_crack.as_str() {
        "assumed" => Ok(TwoField::AssumedCut { depth_mm: a.francois_depth_mm, direction: cut_direction(a)? }),
        "true" => Ok(TwoField::TrueCrack),
        o => bail!("--two-field-crack: {o:?} is neither assumed nor true"),
    }
}

/// Sensitivity sweeps (Fig. 5.9) as extra named methods, and the default value of every panel.
fn sweep_methods(a: &BenchmarkArgs, quick: bool) -> Result<(Vec<SweepSetting>, [f64; 5])> {
    let base = rods_organ(a, quick)?;
    let (spacing, steps) = (base.spacing_mm, base.steps);
    let optimizer = rods_optimizer(a, quick)?;
    let defaults = [1.0, base.poisson_ratio, spacing, base.dx_mm.unwrap_or(2.0 * spacing), steps as f64];
    let mut out: Vec<SweepSetting> = Vec::new();
    let mut rods = |name: String, organ: OrganConfig, panel: usize, value: f64| {
        out.push(SweepSetting {
            method: Box::new(NamedRods {
                name,
                inner: RodsMethod { organ, optimizer: optimizer.clone(), two_field: None, rung: None },
            }),
            panel: Some((panel, value)),
        })
    };
    // With Δt from the CFL condition the registered shape does not depend on E at all (E × f with Δt / √f
    // and v₀ × √f is the same motion, and nothing else sets a time scale), so the E sweep holds Δt (and the
    // physical horizon T Δt) at the value the stiffest setting needs, E × 1 included.
    let e_factors = [0.25, 0.5, 1.0, 2.0, 3.0, 10.0];
    let stiffest = OrganConfig { youngs_modulus_kpa: base.youngs_modulus_kpa * 10.0, ..base.clone() };
    let dt_s = stiffest.time_step_s().context("the E sweep's time step")?;
    for f in e_factors {
        let organ = OrganConfig { youngs_modulus_kpa: base.youngs_modulus_kpa * f, dt_s: Some(dt_s), ..base.clone() };
        rods(format!("RODS-MPM E×{f} (Δt {:.2e} s)", dt_s), organ, 0, f);
    }
    for nu in [0.3, 0.4, 0.45] {
        rods(format!("RODS-MPM ν {nu}"), OrganConfig { poisson_ratio: nu, ..base.clone() }, 1, nu);
    }
    for s in [1.5 * spacing, 0.75 * spacing] {
        rods(format!("RODS-MPM spacing {s:.2} mm"), OrganConfig { spacing_mm: s, ..base.clone() }, 2, s);
    }
    for g in [0.75, 1.5] {
        let dx = g * defaults[3];
        rods(format!("RODS-MPM Δx {dx:.1} mm"), OrganConfig { dx_mm: Some(dx), ..base.clone() }, 3, dx);
    }
    for t in [steps / 2, 2 * steps] {
        rods(format!("RODS-MPM T {t}"), OrganConfig { steps: t, ..base.clone() }, 4, t as f64);
    }
    for s in [10.0, 30.0, 40.0] {
        out.push(SweepSetting {
            method: Box::new(BaselineMethod {
                name: format!("LDDMM σ {s}"),
                baseline: Baseline::Lddmm(LddmmConfig { sigma_mm: s, ..Default::default() }),
                hold_outside_roi: false,
            }),
            panel: None,
        });
    }
    Ok((out, defaults))
}

/// Fig. 5.9 for one scenario from the pooled cells: every panel's settings plus the default RODS-MPM run
/// (when it ran), and the registration baseline with the lowest all-node mean as the dashed reference.
fn write_fig59(
    path: &Path,
    scenario: &str,
    cells: &[laparo_register::benchmark::Cell],
    settings: &[SweepSetting],
    defaults: &[f64; 5],
    column: Column,
    baselines: &[String],
) -> Result<()> {
    let cell = |m: &str| cells.iter().find(|c| c.scenario == scenario && c.column == column && c.method == m);
    let point = |c: &laparo_register::benchmark::Cell, value: f64| SweepPoint {
        value,
        mean_mm: c.mean_mm,
        near_mm: c.bin_means_mm.first().copied().unwrap_or(f64::NAN),
    };
    let base = cell(RODS_MPM_NAME);
    let panels: Vec<SweepPanel> = SWEEP_PANELS
        .iter()
        .enumerate()
        .map(|(k, &(label, log_x))| {
            let mut points: Vec<SweepPoint> = settings
                .iter()
                .filter_map(|s| match s.panel {
                    Some((p, v)) if p == k => cell(&s.method.name()).map(|c| point(c, v)),
                    _ => None,
                })
                .collect();
            if !points.iter().any(|p| p.value == defaults[k]) {
                points.extend(base.map(|c| point(c, defaults[k])));
            }
            SweepPanel { parameter: label.to_string(), default_value: defaults[k], log_x, points }
        })
        .filter(|p| !p.points.is_empty())
        .collect();
    if panels.is_empty() {
        return Ok(());
    }
    let reference = cells
        .iter()
        .filter(|c| c.scenario == scenario && c.column == column)
        .filter(|c| baselines.contains(&c.method))
        .min_by(|a, b| a.mean_mm.total_cmp(&b.mean_mm));
    write_sweep_plot(
        path,
        &panels,
        reference.map(|c| (c.method.as_str(), c.mean_mm, c.bin_means_mm.first().copied().unwrap_or(f64::NAN))),
        &format!("{scenario}: RODS-MPM sensitivity (Fig. 5.9, {} landmarks, noiseless)", column.landmarks),
    )
    .with_context(|| format!("writing {}", path.display()))
}

/// RODS-MPM under another name (sweeps).
struct NamedRods {
    name: String,
    inner: RodsMethod,
}

impl Method for NamedRods {
    fn name(&self) -> String {
        self.name.clone()
    }
    fn settings(&self) -> String {
        self.inner.settings()
    }
    fn register(
        &self,
        case: &laparo_register::benchmark::BenchmarkCase,
        lm: &[laparo_register::benchmark::LandmarkSet],
    ) -> laparo_register::Result<laparo_register::benchmark::MethodOutput> {
        self.inner.register(case, lm)
    }
}

/// One evaluation point per line: rest position, side, kind, distances and TRE (mm).
fn write_points_csv(path: &Path, p: &laparo_register::benchmark::EvalPoints, x: &[Vector3<f64>]) -> Result<()> {
    use std::fmt::Write;
    if let Some(d) = path.parent() {
        std::fs::create_dir_all(d).with_context(|| format!("creating {}", d.display()))?;
    }
    let mut s = String::from("x_mm,y_mm,z_mm,side,kind,d_lip_mm,d_crack_mm,tre_mm\n");
    for (i, (r, xi)) in p.rest.iter().zip(x).enumerate() {
        let kind = if p.kind[i] == laparo_register::benchmark::PointKind::CrackFace { "crack-face" } else { "lattice" };
        writeln!(
            s,
            "{:.4},{:.4},{:.4},{},{kind},{:.4},{:.4},{:.6}",
            r.x,
            r.y,
            r.z,
            p.side[i],
            p.d_lip_mm[i],
            p.d_crack_mm[i],
            (xi - p.ground_truth[i]).norm()
        )?;
    }
    laparo_core::atomic::write_atomic(path, s.as_bytes())?;
    Ok(())
}

/// The row name of no registration.
const NONE_NAME: &str = laparo_register::benchmark::table::NONE_NAME;

/// Largest ground-truth displacement (mm) of a node the region of interest holds at rest (outside the ball).
fn held_displacement_mm(x: &[Vector3<f64>], u: &[Vector3<f64>], roi: &laparo_register::organ::Roi) -> f64 {
    x.iter().zip(u).filter(|(p, _)| !roi.inside(p)).map(|(_, u)| u.norm()).fold(0.0, f64::max)
}

/// The floor line ([`laparo_register::benchmark::table::check_floor_line`]): an error naming --spacing-mm, or
/// a warning with --allow-coarse-floor.
fn check_floor_line(results: &[laparo_register::benchmark::RunResult], a: &BenchmarkArgs, quick: bool) -> Result<()> {
    let spacing = rods_organ(a, quick)?.spacing_mm;
    match laparo_register::benchmark::table::check_floor_line(results, spacing) {
        Ok(()) => Ok(()),
        Err(e) if a.allow_coarse_floor => {
            eprintln!("warning: --spacing-mm: {e} (--allow-coarse-floor: those bins are marked not comparable)");
            Ok(())
        }
        Err(e) => bail!("--spacing-mm: {e} (or --allow-coarse-floor to mark those bins not comparable)"),
    }
}

/// Mean rest position of the lip nodes.
fn incision_centre(c: &laparo_register::benchmark::BenchmarkCase) -> Vector3<f64> {
    let ids: Vec<usize> = c.lips.iter().flatten().copied().collect();
    ids.iter().map(|&i| c.rest[i]).sum::<Vector3<f64>>() / ids.len().max(1) as f64
}

/// The crack must cover this fraction of the blade inside the organ ...
pub(crate) const MIN_CRACK_AREA_FRACTION: f64 = 0.6;
/// ... and the mouth this many lip samples, else the mesh is too coarse for the incision.
pub(crate) const MIN_LIP_SAMPLES: usize = 5;

pub fn run(mut a: BenchmarkArgs) -> Result<()> {
    let quick = a.quick;
    let frozen = match &a.frozen {
        Some(p) => {
            if a.tune {
                bail!("--frozen with --tune: tune on a case, then test another with its frozen.json");
            }
            let f = laparo_register::benchmark::tuning::FrozenSettings::read(p)?;
            let h = &f.hyperparameters;
            a.francois_depth_mm = h.francois_depth_mm;
            a.drbc_lambda_factor = h.drbc_lambda_factor;
            a.lddmm_sigma_mm = h.lddmm_sigma_mm;
            a.kinetic_weight = h.rods_kinetic_weight;
            println!("frozen hyperparameters from {} (tuned on {}): {h:?}", p.display(), f.tuning_case);
            Some(f)
        }
        None => None,
    };
    if !(a.drbc_lambda_factor.is_finite() && a.drbc_lambda_factor > 0.0) {
        bail!("--drbc-lambda-factor {}: must be finite and > 0", a.drbc_lambda_factor);
    }
    let scenario = a.scenario.clone().unwrap_or_else(|| if quick { "non-anatomical".into() } else { "all".into() });
    let scenarios: Vec<&str> = match scenario.as_str() {
        "all" => vec!["non-anatomical", "anatomical"],
        "non-anatomical" => vec!["non-anatomical"],
        "anatomical" => vec!["anatomical"],
        o => bail!("--scenario {o:?}: expected non-anatomical, anatomical or all"),
    };
    let ms = methods(&a, quick)?;
    if scenarios.len() > 1 {
        if let Some(l) = a.cut.cut_length_mm {
            bail!("--cut-length-mm {l} with --scenario all: the two blades differ (60 / 100 mm); give one --scenario");
        }
        if let Some(g) = &a.target_gap_mm {
            bail!("--target-gap-mm {g} with --scenario all: the two openings differ (10–15 / 20–30 mm); give one --scenario");
        }
    }
    let target_gap = a.target_gap_mm.as_deref().map(parse_gap).transpose()?;
    let frame = a.cut.frame(ScenarioFrame::default())?;
    a.cut.check_for(&scenarios)?;
    let blades = (a.cut.non_anatomical()?, a.cut.anatomical()?);
    let liver = match a.liver.clone().or_else(default_liver) {
        Some(p) => p,
        None => bail!(
            "--liver: no liver surface given and ../shared/data/meshes/p2ilf/patient2_1_3d-liver-model.obj is absent"
        ),
    };
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let t_all = std::time::Instant::now();
    // 1. volume mesh
    let edge = a.edge_mm.unwrap_or(if quick { 16.0 } else { 10.0 });
    let surface = laparo_core::mesh::read_mesh(&liver)?;
    let t0 = std::time::Instant::now();
    let (mesh, quality) = tetrahedralize_surface(
        surface.clone(),
        &liver.display().to_string(),
        &TetraParams { edge_mm: edge, ..Default::default() },
    )?;
    let mesh_s = t0.elapsed().as_secs_f64();
    write_json(&a.out.join("mesh_quality.json"), &quality)?;
    laparo_core::mesh::write_vtk(a.out.join("mesh.vtk"), &mesh)?;
    println!(
        "mesh: {} nodes, {} tets, min dihedral {:.1}°, edge {edge} mm ({mesh_s:.1} s)",
        quality.nodes, quality.tets, quality.min_dihedral_deg
    );
    let organ = laparo_fem::mesh::Surface::new(surface.clone(), &liver.display().to_string())?;
    // the methods' own mesh (another tetrahedralisation of the same surface)
    let method_edge = a.method_edge_mm.unwrap_or(0.85 * edge);
    if !(method_edge.is_finite() && method_edge > 0.0) {
        bail!("--method-edge-mm {method_edge}: must be finite and > 0");
    }
    let method_mesh = if (method_edge - edge).abs() > 1e-9 {
        let (m, q) = tetrahedralize_surface(
            surface.clone(),
            &liver.display().to_string(),
            &TetraParams { edge_mm: method_edge, ..Default::default() },
        )?;
        println!(
            "methods' mesh: {} nodes, {} tets, min dihedral {:.1}°, edge {method_edge} mm (independent of the ground truth's)",
            q.nodes, q.tets, q.min_dihedral_deg
        );
        Some(m)
    } else {
        None
    };
    let store = ResultStore::new(a.out.join("runs"));
    let mut cases = Vec::new();
    let mut cut_fingerprints = Vec::new();
    let mut gt_reports = Vec::new();
    let kinds: Vec<GroundTruthKind> = a
        .ground_truths
        .clone()
        .unwrap_or_else(|| if quick { "pressure".into() } else { "pressure,grasper,stiff-inclusion".into() })
        .split(',')
        .map(|k| k.trim().parse::<GroundTruthKind>().map_err(|e| anyhow::anyhow!("--ground-truths {k:?}: {e}")))
        .collect::<Result<_>>()?;
    let roi_mode = roi_mode(&a)?;
    if !(a.eval_spacing_mm.is_finite() && a.eval_spacing_mm > 0.0) {
        bail!("--eval-spacing-mm {}: must be finite and > 0", a.eval_spacing_mm);
    }
    for (name, kind) in scenarios.iter().flat_map(|n| kinds.iter().map(move |k| (*n, *k))) {
        // the pressure ground truth keeps the scenario's name (and folder); the controls add their kind
        let case_name =
            if kind == GroundTruthKind::Pressure { name.to_string() } else { format!("{name}-{}", kind.name()) };
        let dir = a.out.join(&case_name);
        std::fs::create_dir_all(&dir)?;
        let (scn, blade) = if name == "anatomical" {
            (anatomical_on(&mesh, &surface, &frame, &blades.1)?, serde_json::to_value(&blades.1)?)
        } else {
            (non_anatomical_on(&mesh, &surface, &frame, &blades.0)?, serde_json::to_value(&blades.0)?)
        };
        let mut scn = scn;
        let dropped = laparo_register::benchmark::build::drop_detached_fragments(&mut scn);
        if dropped > 0 {
            eprintln!("{name}: the blade cut a fragment of {dropped} nodes free of the organ: removed (resected)");
        }
        let resolution = CrackResolution::of(&scn, &organ);
        resolution
            .check(edge, MIN_CRACK_AREA_FRACTION, MIN_LIP_SAMPLES)
            .with_context(|| format!("--edge-mm {edge}: the {name} incision"))?;
        let cut_fp = cut_fingerprint(&scn);
        if let Some(f) = &frozen {
            f.check_test_case(&cut_fp, &format!("the {name} case (--cut-*, --edge-mm, --liver)"))?;
        }
        cut_fingerprints.push(cut_fp);
        let mut gcfg = GroundTruthConfig::control(&scn, kind)?;
        scn.name = case_name.clone();
        if let Some(g) = target_gap {
            gcfg.target_gap_mm = g;
        }
        if let Some(s) = a.fem_steps {
            gcfg.steps = s;
        } else if quick {
            gcfg.steps = 8;
        }
        let t0 = std::time::Instant::now();
        let (u, rep) = ground_truth(&dir, &store, &scn, &gcfg)?;
        let x = &scn.cut.mesh.vertices;
        let u_p2 = u;
        let u: Vec<Vector3<f64>> = u_p2[..x.len()].to_vec();
        let crack: Vec<Vector3<f64>> = scn.cut.crack_faces.iter().flatten().flatten().map(|&i| x[i]).collect();
        let centre = crack.iter().sum::<Vector3<f64>>() / crack.len().max(1) as f64;
        let roi = match (roi_mode, a.roi_mm) {
            (_, Some(r)) if !(r > 0.0 && r.is_finite()) => bail!("--roi-mm {r}: must be a finite radius > 0"),
            (RoiMode::APriori, Some(r)) => bail!("--roi-mm {r} with --roi a-priori: the a-priori ball's radius is 1.5 × the lip length; give --roi ground-truth to force a radius"),
            (RoiMode::APriori, None) => {
                let ball = a_priori_roi(&case_from(&scn, &u, None));
                Some((ball, held_displacement_mm(x, &u, &ball)))
            }
            (RoiMode::None, _) => None,
            (RoiMode::GroundTruth, Some(r)) => choose_roi(x, &u, centre, r, r, 6.0, f64::INFINITY),
            (RoiMode::GroundTruth, None) => choose_roi(x, &u, centre, 50.0, 120.0, 6.0, 0.5),
        };
        println!(
            "{case_name}: {} nodes after the cut (crack nodes duplicated), largest lip gap {:.2} mm at load {:.4} kPa, max |u| {:.2} mm, |u| beyond 60 mm {:.3} mm (p95 {:.3} mm, {:.1} % of those nodes above 1 mm), min J {:.3} ({:.1} s); ROI {}",
            x.len(),
            rep.max_gap_mm,
            rep.pressure_kpa,
            rep.max_displacement_mm,
            rep.far_displacement_mm,
            rep.far_displacement_p95_mm,
            100.0 * rep.far_share_over_1mm,
            rep.min_j,
            t0.elapsed().as_secs_f64(),
            match (&roi, roi_mode) {
                (Some((laparo_register::organ::Roi::Ball { radius_mm, .. }, w)), RoiMode::APriori) => format!("a priori ball {radius_mm:.1} mm = 1.5 × the lip length (ground-truth |u| up to {w:.3} mm on its boundary shell and outside, where every method holds the tissue at rest)"),
                (Some((laparo_register::organ::Roi::Ball { radius_mm, .. }, w)), _) => format!("ball {radius_mm} mm (ground-truth |u| ≤ {w:.3} mm on its boundary shell and outside, where it holds the tissue at rest)"),
                (None, RoiMode::None) => "whole organ (--roi none)".into(),
                _ => "whole organ (no ball up to 120 mm keeps the displacement on its boundary shell and outside < 0.5 mm)".into(),
            }
        );
        let mut case = case_from(&scn, &u, roi.map(|r| r.0));
        case.ground_truth_p2 = Some(u_p2.clone());
        let t0 = std::time::Instant::now();
        let case = case
            .with_points(a.eval_spacing_mm)
            .with_context(|| format!("{case_name}: the evaluation points (--eval-spacing-mm {})", a.eval_spacing_mm))?;
        if let Some(p) = &case.points {
            let faces = p.kind.iter().filter(|k| **k == laparo_register::benchmark::PointKind::CrackFace).count();
            println!(
                "{case_name}: {} evaluation points ({} on the lattice at {} mm, {faces} on the crack faces; {:.1} s)",
                p.len(),
                p.len() - faces,
                a.eval_spacing_mm,
                t0.elapsed().as_secs_f64()
            );
        }
        // the ground truth on the surface, for people to look at
        let mag: Vec<f64> = u.iter().map(|v| v.norm()).collect();
        let view = SurfaceView { direction: -Vector3::from(frame.anterior), up: Vector3::z(), size_px: 420 };
        write_tre_map(
            &dir.join("ground_truth.png"),
            &case.ground_truth,
            &case.surface,
            &mag,
            rep.max_displacement_mm.max(1e-6),
            &view,
            (centre, 60.0),
            (&format!("{name}: FEM ground truth (deformed), whole liver and the incision"), "|u| [mm]"),
        )?;
        // the crack face-on, coloured by the ground truth's opening: where it opens, and any uncut slot
        write_crack_opening(
            &dir.join("crack.png"),
            &scn,
            Some(&crack_gap_by_node_mm(&scn.cut, &case.ground_truth)),
            &format!("{name}: the crack face-on, its ground-truth opening at {:.4} kPa", rep.pressure_kpa),
        )?;
        write_vtk_fields(
            dir.join("ground_truth.vtk"),
            "laparo incision benchmark: FEM ground truth (mm)",
            &case.rest,
            &case.tets,
            &[
                VtkField::new("u_norm_mm", VtkValues::Double(&mag)),
                VtkField::new("displacement_mm", VtkValues::Vector(&u)),
            ],
            &[],
        )?;
        // the same ground truth as a `laparo guide scenario --deformation` input (issue 16)
        if let Some(t) = &scn.tumour {
            let d = laparo_guide::deformation::Deformation {
                rest: scn.cut.mesh.clone(),
                deformed: case.ground_truth.clone(),
                lips: scn.cut.lips.clone(),
                tumour_centre_mm: t.centre,
                tumour_radius_mm: t.radius_mm,
            };
            d.write(&dir.join("deformation"))?;
        }
        gt_reports.push(serde_json::json!({"scenario": name, "case": case_name, "ground_truth_kind": kind.name(), "config": gcfg, "blade": blade, "fixed_fraction": frame.fixed_fraction, "ground_truth": rep, "roi": roi.map(|r| r.0), "fragment_nodes_removed": dropped, "crack_resolution": resolution}));
        let case = match &method_mesh {
            None => case,
            Some(mm) => {
                let mut mscn = if name == "anatomical" {
                    anatomical_on(mm, &surface, &frame, &blades.1)?
                } else {
                    non_anatomical_on(mm, &surface, &frame, &blades.0)?
                };
                laparo_register::benchmark::build::drop_detached_fragments(&mut mscn);
                CrackResolution::of(&mscn, &organ)
                    .check(method_edge, MIN_CRACK_AREA_FRACTION, MIN_LIP_SAMPLES)
                    .with_context(|| {
                        format!("--method-edge-mm {method_edge}: the {name} incision on the methods' mesh")
                    })?;
                mscn.name = case_name.clone();
                // the ground truth at the methods' nodes, each read on its own side (0.5 × the coarser edge
                // covers where the two meshes approximate the surface differently)
                let tol = 0.5 * edge.max(method_edge);
                // ... at every TET10 node of the methods' mesh (an edge node on the side of its vertices), so
                // the particles' read-back floor is not the P1 floor again
                let sides = laparo_register::benchmark::build::node_sides(&mscn.cut);
                let t10 = laparo_fem::solid::Tet10Mesh::from_linear(&mscn.cut.mesh)?;
                let mut q: Vec<(Vector3<f64>, u8)> = t10.nodes.iter().map(|x| (*x, 0u8)).collect();
                for (i, s) in sides.iter().enumerate() {
                    q[i].1 = *s;
                }
                for (&(a, b), &e) in &t10.edge_nodes {
                    q[e].1 = sides[a].max(sides[b]);
                }
                let gt_nodes = laparo_register::benchmark::points::ground_truth_of(&case, &q, tol)
                    .context("the ground truth at the methods' mesh nodes")?;
                let u_p2m: Vec<Vector3<f64>> = gt_nodes.iter().zip(&q).map(|(g, (x, _))| g - x).collect();
                let mut mcase = case_from(&mscn, &u_p2m[..t10.n_vertices], case.roi);
                mcase.ground_truth_p2 = Some(u_p2m);
                let pts = case.points.as_ref().context("the ground truth's evaluation points")?;
                let (moved, dropped) = pts.relocated(&mcase, tol)?;
                println!(
                    "{case_name}: methods' mesh {} nodes after the cut; {} of {} evaluation points located in it on their own side ({dropped} beyond {tol} mm outside it dropped)",
                    mcase.rest.len(),
                    moved.len(),
                    pts.len()
                );
                mcase.points = Some(std::sync::Arc::new(moved));
                mcase
            }
        };
        cases.push(case);
    }
    write_json(&a.out.join("ground_truth.json"), &gt_reports)?;
    if a.tune {
        cut_fingerprints.dedup();
        return tune(&a, quick, &cases, cut_fingerprints, &store);
    }
    // 2. the protocol
    let n_seeds = a.seeds.unwrap_or(if quick { 1 } else { 5 });
    let refs: Vec<&dyn Method> = ms.iter().map(|m| m.as_ref()).collect();
    let columns = table51_columns();
    let pb = ProgressBar::new(0);
    pb.set_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} runs  {msg}  [{elapsed_precise}]")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let map_column = Column { landmarks: 50, noise_sigma_mm: 0.0 };
    let mut map_err: Option<anyhow::Error> = None;
    let mut on_event = |e: &laparo_register::benchmark::RunEvent| {
        pb.set_length(e.total as u64);
        pb.set_position(e.done as u64);
        let k = &e.result.key;
        pb.set_message(format!(
            "{} {} {} seed {}: TRE {:.2} mm{}",
            k.scenario,
            k.method,
            k.column.label(),
            k.seed,
            e.result.tre_volume.mean,
            if e.registered.is_none() { " (resumed)" } else { "" }
        ));
        if let (Some(x), Some(p), true) =
            (e.registered_points, &e.case.points, a.write_points && k.column == map_column && k.seed == 0)
        {
            let path = a.out.join(&k.scenario).join("points").join(format!(
                "{}.csv",
                k.method.replace(|c: char| !(c.is_ascii_alphanumeric() || c == '-' || c == '.'), "_")
            ));
            if let Err(x) = write_points_csv(&path, p, x) {
                map_err.get_or_insert(x);
            }
        }
        if let (Some(nodes), true) = (e.registered, k.column == map_column && k.seed == 0) {
            let err: Vec<f64> = nodes.iter().zip(&e.case.ground_truth).map(|(a, b)| (a - b).norm()).collect();
            let dir = a.out.join(&k.scenario).join("maps");
            let stem = k.method.replace([' ', '/'], "_");
            let view = SurfaceView { direction: -Vector3::from(frame.anterior), up: Vector3::z(), size_px: 420 };
            let res = std::fs::create_dir_all(&dir)
                .map_err(anyhow::Error::from)
                .and_then(|_| {
                    Ok(write_tre_map(
                        &dir.join(format!("{stem}.png")),
                        nodes,
                        &e.case.surface,
                        &err,
                        10.0,
                        &view,
                        (incision_centre(e.case), 60.0),
                        (
                            &format!("{} {}: TRE, 50 landmarks, whole liver and the incision", k.scenario, k.method),
                            "TRE [mm]",
                        ),
                    )?)
                })
                .and_then(|_| {
                    Ok(write_vtk_fields(
                        dir.join(format!("{stem}.vtk")),
                        "laparo incision benchmark: TRE per node (mm)",
                        nodes,
                        &e.case.tets,
                        &[VtkField::new("tre_mm", VtkValues::Double(&err))],
                        &[],
                    )?)
                });
            if let Err(x) = res {
                map_err.get_or_insert(x);
            }
        }
    };
    let sweeps = sweep_methods(&a, quick)?;
    // the registration baselines (not RODS-MPM, not the rest mesh): Fig. 5.9's reference is the best of them
    let baselines: Vec<String> =
        refs.iter().map(|m| m.name()).filter(|n| !n.starts_with(RODS_MPM_NAME) && !n.starts_with("none")).collect();
    // the floors and "none" first (cheap, landmark-free): a RODS-MPM floor above ¼ of "none" within 10 mm of
    // the lips means the chosen spacing cannot resolve what the comparison reads there
    let (first, rest_methods): (Vec<&dyn Method>, Vec<&dyn Method>) =
        refs.iter().partition(|m| !m.uses_landmarks() || m.name() == NONE_NAME);
    let mut results = run_protocol(&cases, &first, &columns, n_seeds, &store, &mut on_event)?;
    check_floor_line(&results, &a, quick)?;
    results.extend(run_protocol(&cases, &rest_methods, &columns, n_seeds, &store, &mut on_event)?);
    // the thesis fidelity rows beside RODS-MPM, in the 50-landmark column
    let with_rods = a.methods.split(',').any(|m| ["rods", "rods-mpm", "rods-two-field", "rods-l0"].contains(&m.trim()));
    let thesis = if with_rods { vec![thesis_row(&a, quick, false)?, thesis_row(&a, quick, true)?] } else { vec![] };
    let trefs: Vec<&dyn Method> = thesis.iter().map(|m| m as &dyn Method).collect();
    results.extend(run_protocol(&cases, &trefs, &[map_column], 1, &store, &mut on_event)?);
    if a.sweeps {
        let srefs: Vec<&dyn Method> = sweeps.0.iter().map(|s| s.method.as_ref()).collect();
        results.extend(run_protocol(&cases, &srefs, &[map_column], 1, &store, &mut on_event)?);
    }
    pb.finish_and_clear();
    if let Some(e) = map_err {
        return Err(e.context("writing a TRE map"));
    }
    // 3. tables and figures
    let cells = aggregate(&results);
    let md = if quick {
        format!(
            "> **Quick tier: a smoke test, not a ranking.** Coarse mesh, one seed and short RODS-MPM runs check \
             that the benchmark runs end to end; the order of the methods below means nothing (run without \
             --quick for Table 5.1).\n\n{}",
            table_markdown(&cells)
        )
    } else {
        table_markdown(&cells)
    };
    laparo_core::atomic::write_atomic(&a.out.join("table51.md"), md.as_bytes())?;
    laparo_core::atomic::write_atomic(&a.out.join("table51.csv"), table_csv(&cells).as_bytes())?;
    laparo_core::atomic::write_atomic(&a.out.join("table51.json"), table_json(&cells).as_bytes())?;
    for case in &cases {
        let name = &case.scenario;
        let main: Vec<&laparo_register::benchmark::Cell> = cells
            .iter()
            .filter(|c| c.scenario == *name && c.column == map_column && refs.iter().any(|m| m.name() == c.method))
            .collect();
        write_distance_plot(
            &a.out.join(name).join("fig58_tre_vs_distance.png"),
            &main,
            &format!("{name}: TRE vs distance to the source lips (50 landmarks; dashed: floors)"),
        )?;
    }
    for name in &scenarios {
        if a.sweeps {
            let fig = a.out.join(name).join("fig59_sensitivity.png");
            write_fig59(&fig, name, &cells, &sweeps.0, &sweeps.1, map_column, &baselines)?;
        }
    }
    print!("{md}");
    println!(
        "wrote {} ({:.1} min, peak {:.0} MiB)",
        a.out.display(),
        t_all.elapsed().as_secs_f64() / 60.0,
        laparo_register::pipeline::peak_memory_mib().unwrap_or(f64::NAN)
    );
    Ok(())
}
