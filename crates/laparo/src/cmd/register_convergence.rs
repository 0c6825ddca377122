//! `laparo register convergence`: mesh convergence of the incision benchmark's FEM ground truth (issue 46,
//! item 4). One scenario's case is built on two tetrahedron sizes exactly as `laparo register benchmark`
//! builds it (tetrahedralise, cut, drop detached fragments, the crack-resolution check, the calibrated TET10
//! ground truth, the common evaluation points), and the two ground truths are compared at the coarse mesh's
//! points (`laparo_register::benchmark::convergence`).
//!
//! Replicated from `register_benchmark.rs` (private there): the ground truth's input fingerprint and cache
//! file format (so a benchmark folder's `<scenario>/ground_truth.json` of the same inputs can be copied in),
//! the default liver and the crack-resolution limits.
use anyhow::{bail, Context, Result};
use clap::Args;
use indicatif::ProgressBar;
use laparo_fem::mesh::{
    anatomical_on, non_anatomical_on, tetrahedralize_surface, Scenario, ScenarioFrame, TetraParams,
};
use laparo_register::benchmark::build::{
    case_from, drop_detached_fragments, fem_ground_truth_field, CrackResolution, GroundTruthConfig, GroundTruthKind,
    GroundTruthReport,
};
use laparo_register::benchmark::convergence::{compare_ground_truths, ConvergenceConfig, DEFAULT_OUTSIDE_TOLERANCE_MM};
use laparo_register::benchmark::BenchmarkCase;
use nalgebra::Vector3;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Arguments of `laparo register convergence`.
#[derive(Args)]
pub struct ConvergenceArgs {
    /// Scenario: non-anatomical or anatomical.
    #[arg(long)]
    pub scenario: String,
    /// The two tetrahedron edges (mm), coarse then fine: "A,B", e.g. 8,6.
    #[arg(long, default_value = "8,6")]
    pub edge_mm: String,
    /// Output folder: <edge>mm/ground_truth.json per mesh (reused when solved from the same inputs),
    /// convergence.json and convergence.md.
    #[arg(long)]
    pub out: PathBuf,
    /// The ground truth: pressure, grasper or stiff-inclusion.
    #[arg(long, default_value = "pressure")]
    pub ground_truth: String,
    /// Spacing (mm) of the coarse mesh's common evaluation lattice (plus its crack-face points).
    #[arg(long, default_value_t = 2.0)]
    pub eval_spacing_mm: f64,
    /// Closed liver surface (OBJ/PLY/STL, mm); default: the P2ILF patient liver under ../shared/data.
    #[arg(long)]
    pub liver: Option<PathBuf>,
    /// A coarse-mesh point farther than this (mm) outside the fine mesh is skipped (counted).
    #[arg(long, default_value_t = DEFAULT_OUTSIDE_TOLERANCE_MM)]
    pub outside_tolerance_mm: f64,
    /// FEM load increments per solve (default: the benchmark's 20).
    #[arg(long)]
    pub fem_steps: Option<usize>,
    /// The fine mesh's load: calibrated (on its own, to the same opening range as the benchmark does), coarse
    /// (one solve at the coarse mesh's calibrated load, <edge>mm-at-coarse-load/ground_truth.json: the mesh's
    /// effect without the calibration's spread) or both (two comparisons).
    #[arg(long, default_value = "calibrated")]
    pub fine_load: String,
    /// FEM load increments per solve of the fine mesh (default: --fem-steps).
    #[arg(long)]
    pub fine_fem_steps: Option<usize>,
    /// Another blade or fixed region than the benchmark's.
    #[command(flatten)]
    pub cut: crate::cmd::mesh::CutArgs,
}

use crate::cmd::register_benchmark::{
    cached_ground_truth, ground_truth_inputs, write_json, MIN_CRACK_AREA_FRACTION, MIN_LIP_SAMPLES,
};

/// The TET10 ground truth from `dir/ground_truth.json` when solved from the same inputs, else solved (with a
/// spinner) and saved in `register benchmark`'s format.
fn ground_truth(
    dir: &Path,
    scn: &Scenario,
    cfg: &GroundTruthConfig,
) -> Result<(Vec<Vector3<f64>>, GroundTruthReport, bool)> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let path = dir.join("ground_truth.json");
    let inputs = format!("v2-p2 {}", ground_truth_inputs(scn, cfg));
    if path.exists() {
        match cached_ground_truth(&path, scn, &inputs)? {
            Ok((u, report)) => return Ok((u, report, true)),
            Err(stored) => {
                eprintln!("{}: solved from other inputs ({stored:?}, now {inputs:?}): solving again", path.display())
            }
        }
    }
    let pb = ProgressBar::new_spinner();
    pb.set_message(format!("{}: FEM ground truth (TET10 Neo-Hookean) in {}", scn.name, dir.display()));
    pb.enable_steady_tick(std::time::Duration::from_millis(200));
    let t0 = Instant::now();
    let (field, report) = fem_ground_truth_field(scn, cfg, &mut |k, p, g| {
        pb.suspend(|| {
            eprintln!(
                "{}: FEM solve {} at load {p:.4} kPa → calibration quantity {g:.2} mm ({:.0} s, peak {:.0} MiB)",
                scn.name,
                k + 1,
                t0.elapsed().as_secs_f64(),
                laparo_register::pipeline::peak_memory_mib().unwrap_or(f64::NAN)
            )
        });
    })?;
    pb.finish_and_clear();
    let u = field.p2_displacement_mm;
    let flat: Vec<f64> = u.iter().flat_map(|x| [x[0], x[1], x[2]]).collect();
    write_json(&path, &serde_json::json!({"inputs": inputs, "report": report, "displacement_p2_mm": flat}))?;
    Ok((u, report, false))
}

/// One mesh's case as `register benchmark` builds it.
struct Built {
    edge_mm: f64,
    case: BenchmarkCase,
    report: GroundTruthReport,
    summary: serde_json::Value,
}

/// `"8,6"` → [8, 6]: two finite positive edges, coarse first.
fn parse_edges(s: &str) -> Result<[f64; 2]> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<std::result::Result<_, _>>()
        .with_context(|| format!("--edge-mm '{s}': expected two numbers A,B (mm)"))?;
    match v[..] {
        [a, b] if a.is_finite() && b.is_finite() && b > 0.0 && a > b => Ok([a, b]),
        _ => bail!("--edge-mm '{s}': expected two edges A,B (mm) with A > B > 0, the coarse mesh first"),
    }
}

pub fn run(a: ConvergenceArgs) -> Result<()> {
    let t_all = Instant::now();
    let name = match a.scenario.as_str() {
        n @ ("non-anatomical" | "anatomical") => n,
        o => bail!("--scenario {o:?}: expected non-anatomical or anatomical"),
    };
    let edges = parse_edges(&a.edge_mm)?;
    let kind: GroundTruthKind =
        a.ground_truth.trim().parse().map_err(|e| anyhow::anyhow!("--ground-truth {:?}: {e}", a.ground_truth))?;
    if !(a.eval_spacing_mm.is_finite() && a.eval_spacing_mm > 0.0) {
        bail!("--eval-spacing-mm {}: must be finite and > 0", a.eval_spacing_mm);
    }
    if !(a.outside_tolerance_mm.is_finite() && a.outside_tolerance_mm >= 0.0) {
        bail!("--outside-tolerance-mm {}: must be finite and >= 0", a.outside_tolerance_mm);
    }
    if a.fem_steps == Some(0) || a.fine_fem_steps == Some(0) {
        bail!("--fem-steps / --fine-fem-steps 0: need at least one load increment");
    }
    let (fine_calibrated, fine_at_coarse) = match a.fine_load.as_str() {
        "calibrated" => (true, false),
        "coarse" => (false, true),
        "both" => (true, true),
        o => bail!("--fine-load {o:?}: expected calibrated, coarse or both"),
    };
    let frame = a.cut.frame(ScenarioFrame::default())?;
    a.cut.check_for(&[name])?;
    let blade = if name == "anatomical" {
        serde_json::to_value(a.cut.anatomical()?)?
    } else {
        serde_json::to_value(a.cut.non_anatomical()?)?
    };
    let liver = match a.liver.clone().or_else(crate::cmd::register_benchmark::default_liver) {
        Some(p) => p,
        None => bail!(
            "--liver: no liver surface given and ../shared/data/meshes/p2ilf/patient2_1_3d-liver-model.obj is absent"
        ),
    };
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    // never write over the input: the liver must be none of the files written here
    if let (Ok(l), Ok(o)) = (liver.canonicalize(), a.out.canonicalize()) {
        let mut written = vec![o.join("convergence.json"), o.join("convergence.md")];
        for e in edges {
            written.push(o.join(format!("{e}mm")).join("ground_truth.json"));
        }
        written.push(o.join(format!("{}mm-at-coarse-load", edges[1])).join("ground_truth.json"));
        if written.contains(&l) {
            bail!("--out {}: would write over the input {}", a.out.display(), l.display());
        }
    }
    let surface = laparo_core::mesh::read_mesh(&liver)?;
    let organ = laparo_fem::mesh::Surface::new(surface.clone(), &liver.display().to_string())?;
    let case_name =
        if kind == GroundTruthKind::Pressure { name.to_string() } else { format!("{name}-{}", kind.name()) };
    let cfg = ConvergenceConfig { outside_tolerance_mm: a.outside_tolerance_mm, ..Default::default() };
    let mut meshes: Vec<serde_json::Value> = Vec::new();
    let mut coarse: Option<Built> = None;
    let mut comparisons: Vec<serde_json::Value> = Vec::new();
    let mut md = String::new();
    let mut compare_s = 0.0;
    for (k, edge) in edges.into_iter().enumerate() {
        let t0 = Instant::now();
        let (mesh, quality) = tetrahedralize_surface(
            surface.clone(),
            &liver.display().to_string(),
            &TetraParams { edge_mm: edge, ..Default::default() },
        )?;
        let mesh_s = t0.elapsed().as_secs_f64();
        let mut scn = if name == "anatomical" {
            anatomical_on(&mesh, &surface, &frame, &a.cut.anatomical()?)?
        } else {
            non_anatomical_on(&mesh, &surface, &frame, &a.cut.non_anatomical()?)?
        };
        let dropped = drop_detached_fragments(&mut scn);
        if dropped > 0 {
            eprintln!("{name} at {edge} mm: the blade cut a fragment of {dropped} nodes free of the organ: removed (resected)");
        }
        let resolution = CrackResolution::of(&scn, &organ);
        resolution
            .check(edge, MIN_CRACK_AREA_FRACTION, MIN_LIP_SAMPLES)
            .with_context(|| format!("--edge-mm {edge}: the {name} incision"))?;
        let mut gcfg = GroundTruthConfig::control(&scn, kind)?;
        scn.name = case_name.clone();
        if let Some(s) = if k == 0 { a.fem_steps } else { a.fine_fem_steps.or(a.fem_steps) } {
            gcfg.steps = s;
        }
        println!(
            "{edge} mm: {} nodes, {} tets after the cut (min dihedral {:.1}°, {mesh_s:.1} s)",
            scn.cut.mesh.vertices.len(),
            scn.cut.mesh.tets.len(),
            quality.min_dihedral_deg
        );
        meshes.push(serde_json::json!({
            "edge_mm": edge, "nodes": scn.cut.mesh.vertices.len(), "tets": scn.cut.mesh.tets.len(),
            "mesh_quality": quality, "fragment_nodes_removed": dropped, "crack_resolution": resolution, "mesh_s": mesh_s,
        }));
        // the ground truths of this mesh: A calibrated; B calibrated and / or at A's calibrated load
        let mut runs: Vec<(&str, GroundTruthConfig, PathBuf)> = Vec::new();
        if k == 0 || fine_calibrated {
            runs.push(("calibrated", gcfg.clone(), a.out.join(format!("{edge}mm"))));
        }
        if let (1, true, Some(c)) = (k, fine_at_coarse, coarse.as_ref()) {
            let mut at = gcfg.clone();
            at.initial_pressure_kpa = c.report.pressure_kpa;
            at.target_gap_mm = [1e-9, 1e9];
            at.max_solves = 1;
            runs.push(("at the coarse load", at, a.out.join(format!("{edge}mm-at-coarse-load"))));
        }
        for (label, gcfg, dir) in runs {
            let t1 = Instant::now();
            let (u_p2, rep, cached) = ground_truth(&dir, &scn, &gcfg)?;
            let gt_s = t1.elapsed().as_secs_f64();
            let t2 = Instant::now();
            let case = build_case(&scn, u_p2, a.eval_spacing_mm)?;
            let points_s = t2.elapsed().as_secs_f64();
            let p = case.points.as_ref().map_or(0, |p| p.len());
            println!(
                "{edge} mm {label}: ground truth {} ({:.1} s{}): load {:.4} kPa, mean mouth opening {:.2} mm, largest gap \
                 {:.2} mm, max |u| {:.2} mm, min J {:.3}, {} solver, {} steps; {p} evaluation points ({points_s:.1} s); peak {:.0} MiB",
                if cached { "reused" } else { "solved" },
                if cached { rep.seconds } else { gt_s },
                if cached { " when solved" } else { "" },
                rep.pressure_kpa,
                rep.mean_mouth_opening_mm,
                rep.max_gap_mm,
                rep.max_displacement_mm,
                rep.min_j,
                rep.linear_solver,
                gcfg.steps,
                laparo_register::pipeline::peak_memory_mib().unwrap_or(f64::NAN)
            );
            let summary = serde_json::json!({
                "edge_mm": edge, "load": label, "config": gcfg, "ground_truth": rep, "ground_truth_reused": cached,
                "ground_truth_wall_s": gt_s, "points_s": points_s, "evaluation_points": p,
                "folder": dir.display().to_string(),
            });
            let b = Built { edge_mm: edge, case, report: rep, summary };
            let Some(c) = coarse.as_ref() else {
                coarse = Some(b);
                continue;
            };
            let t3 = Instant::now();
            let report = compare_ground_truths(&c.case, &b.case, &cfg)?;
            compare_s += t3.elapsed().as_secs_f64();
            let what = format!("B {label}");
            print_figures(&what, &report);
            md.push_str(&format!(
                "\n## {} mm (A) vs {} mm (B), B {label}\n\nGround truth {} ({}): A {:.4} kPa → mean mouth opening {:.2} mm \
                 (calibrated); B {:.4} kPa → {:.2} mm. Evaluation points: A's, {} mm lattice plus crack-face points.\n\n{}",
                c.edge_mm,
                b.edge_mm,
                kind.name(),
                c.report.calibration_quantity,
                c.report.pressure_kpa,
                c.report.mean_mouth_opening_mm,
                b.report.pressure_kpa,
                b.report.mean_mouth_opening_mm,
                a.eval_spacing_mm,
                report.markdown()
            ));
            comparisons.push(
                serde_json::json!({"fine_load": label, "coarse": c.summary, "fine": b.summary, "report": report}),
            );
        }
    }
    let peak = laparo_register::pipeline::peak_memory_mib().unwrap_or(f64::NAN);
    let total_s = t_all.elapsed().as_secs_f64();
    let md = format!(
        "# Ground-truth mesh convergence: {case_name}, {} mm vs {} mm\n{md}\nWall time {:.1} min (comparisons {compare_s:.1} s), \
         peak memory {peak:.0} MiB.\n",
        edges[0],
        edges[1],
        total_s / 60.0
    );
    write_json(
        &a.out.join("convergence.json"),
        &serde_json::json!({
            "scenario": name, "case": case_name, "ground_truth_kind": kind.name(), "blade": blade,
            "fixed_fraction": frame.fixed_fraction, "edges_mm": edges, "eval_spacing_mm": a.eval_spacing_mm,
            "liver": liver.display().to_string(), "meshes": meshes, "comparisons": comparisons,
            "compare_s": compare_s, "wall_s": total_s, "peak_memory_mib": peak,
        }),
    )?;
    laparo_core::atomic::write_atomic(&a.out.join("convergence.md"), md.as_bytes())?;
    println!("wrote {} ({:.1} min, peak {peak:.0} MiB)", a.out.display(), total_s / 60.0);
    Ok(())
}

/// The benchmark case of `scn` with its TET10 ground truth `u_p2` and evaluation points at `spacing_mm`.
fn build_case(scn: &Scenario, u_p2: Vec<Vector3<f64>>, spacing_mm: f64) -> Result<BenchmarkCase> {
    let n = scn.cut.mesh.vertices.len();
    let mut case = case_from(scn, &u_p2[..n.min(u_p2.len())], None);
    case.ground_truth_p2 = Some(u_p2);
    case.with_points(spacing_mm)
        .with_context(|| format!("{}: the evaluation points (--eval-spacing-mm {spacing_mm})", scn.name))
}

fn print_figures(what: &str, r: &laparo_register::benchmark::convergence::ConvergenceReport) {
    let faces = r.crack_face_points;
    println!(
        "{what}: {} of {} points compared ({} skipped outside B by > {} mm; {faces} crack-face, {} read from their own side's nearest tet up to {:.2} mm away)",
        r.points_compared, r.points_a, r.points_skipped, r.outside_tolerance_mm, r.points_read_off_side, r.max_off_side_distance_mm
    );
    println!(
        "{what}: relative RMS {:.2} % (RMS diff {:.3} mm / RMS |u_B| {:.3} mm) {}; within {} mm of the lips {:.2} % ({} points) {}; crack faces {:.2} %; max diff {:.3} mm",
        100.0 * r.relative_rms,
        r.rms_diff_mm,
        r.rms_u_mm,
        if r.passes_5pct { "≤ 5 %" } else { "> 5 % FAIL" },
        r.near_lip_mm,
        100.0 * r.near_lip_relative_rms,
        r.points_near_lip,
        if r.passes_10pct_near { "≤ 10 %" } else { "> 10 % FAIL" },
        100.0 * r.crack_face_relative_rms,
        r.max_diff_mm
    );
    let bins: Vec<String> = (0..r.bin_counts.len())
        .map(|k| {
            format!(
                "≥{} mm: {:.3}/{:.3} ({:.1} %, n {})",
                r.bin_lo_mm[k],
                r.none_bins_a_mm[k],
                r.none_bins_b_mm[k],
                100.0 * r.none_bin_relative_diff[k],
                r.bin_counts[k]
            )
        })
        .collect();
    println!(
        "{what}: none's TRE per bin A/B mm: {} → {}",
        bins.join("; "),
        if r.none_bins_within_10pct { "all within 10 %" } else { "NOT all within 10 % (FAIL)" }
    );
}
