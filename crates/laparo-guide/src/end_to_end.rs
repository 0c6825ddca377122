//! The whole guidance chain in one call (issue 16): the FEM ground truth of an incision on the organ
//! (laparo-fem's mesh and cut, laparo-register's calibrated TET10 Neo-Hookean solve, §5.4.2), the
//! rendered scenario ([`crate::scenario`]), the pipeline ([`crate::pipeline`]) once per stereo route,
//! and an index report comparing the routes. Every step is cached in its folder, so a run that was
//! stopped resumes where it was.
use crate::deformation::Deformation;
use crate::error::{GuideError, Result};
use crate::pipeline::{self, GuideConfig, GuideReport, Route, StageRecord};
use crate::scenario::{self, ScenarioConfig};
use laparo_core::atomic::write_atomic;
use laparo_fem::mesh::{
    anatomical_on, non_anatomical_on, tetrahedralize_surface, AnatomicalParams, NonAnatomicalParams, ScenarioFrame,
    TetraParams,
};
use laparo_register::benchmark::build::{drop_detached_fragments, fem_ground_truth, GroundTruthConfig};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Settings of [`run`].
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct EndToEndConfig {
    /// Incision scenario of the benchmark: `non-anatomical` (wedge cut around a virtual tumour) or
    /// `anatomical` (needs a tumour: not available).
    pub incision: String,
    /// Tetrahedron edge of the FEM ground truth (mm).
    pub edge_mm: f64,
    /// FEM load increments per solve.
    pub fem_steps: usize,
    /// FEM region (mm): nodes farther than this from every crack node are held fixed (`None`: the
    /// whole organ with only the posterior region fixed). The incision benchmark measures |u| < 0.01 mm
    /// beyond 60 mm from the cut, so a 70 mm region changes the opening little and cuts the free DOFs.
    pub fem_region_mm: Option<f64>,
    /// Scenario rendering.
    pub scenario: ScenarioConfig,
    /// Pipeline settings, one run per route.
    pub routes: Vec<GuideConfig>,
}

impl EndToEndConfig {
    /// The demo-sized chain: 960×540 images, 10 mm tetrahedra, both routes.
    pub fn quick() -> Self {
        EndToEndConfig {
            incision: "non-anatomical".into(),
            edge_mm: 10.0,
            fem_steps: 8,
            fem_region_mm: Some(70.0),
            scenario: ScenarioConfig::quick(),
            routes: vec![GuideConfig::quick(Route::Calibrated), GuideConfig::quick(Route::SelfRectified)],
        }
    }
    /// Full size: 1920×1080 images, 8 mm tetrahedra, both routes.
    pub fn full() -> Self {
        EndToEndConfig {
            incision: "non-anatomical".into(),
            edge_mm: 8.0,
            fem_steps: 10,
            fem_region_mm: Some(70.0),
            scenario: ScenarioConfig::full(),
            routes: vec![GuideConfig::full(Route::Calibrated), GuideConfig::full(Route::SelfRectified)],
        }
    }
}

/// One step of [`run`], for progress display.
#[derive(Clone, Debug, Serialize)]
pub struct StepRecord {
    /// What ran.
    pub name: String,
    /// Wall time (s); 0 when the result was reused from the folder.
    pub seconds: f64,
    /// One line about the result.
    pub detail: String,
}

/// Result of [`run`].
#[derive(Debug, Serialize)]
pub struct EndToEndReport {
    /// Settings.
    pub config: EndToEndConfig,
    /// Ground truth, scenario and route runs with their times.
    pub steps: Vec<StepRecord>,
    /// The FEM ground truth (calibration report, mesh size).
    pub ground_truth: serde_json::Value,
    /// Per route: the pipeline summary and the stage times.
    pub routes: Vec<serde_json::Value>,
    /// Final TRE (mean over the liver nodes, mm), self-rectified minus calibrated.
    pub tre_difference_mm: Option<f64>,
    /// Why `tre_difference_mm` is missing (a route was not run or has no TRE).
    #[serde(rename = "tre_difference_mm_reason", skip_serializing_if = "Option::is_none")]
    pub tre_difference_reason: Option<String>,
    /// Peak resident memory of the process (MiB); left out where the system does not report it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub peak_memory_mib: Option<f64>,
    /// Total wall time (s).
    pub total_seconds: f64,
}

fn stage_err(input: impl Into<String>, msg: impl Into<String>) -> GuideError {
    GuideError::stage("ground truth", input, msg)
}

/// The FEM ground truth of `incision` on the closed `organ` surface at `edge_mm` tetrahedra, as a guide
/// [`Deformation`]; cached in `dir` (`deformation/`, `ground_truth.json`) for the same settings.
/// `progress` sees one line per FEM solve.
pub fn fem_incision(
    organ: &Path,
    incision: &str,
    edge_mm: f64,
    fem_steps: usize,
    region_mm: Option<f64>,
    dir: &Path,
    progress: &mut dyn FnMut(String),
) -> Result<(Deformation, serde_json::Value)> {
    if !(edge_mm.is_finite() && edge_mm > 0.0) {
        return Err(stage_err("edge_mm", format!("{edge_mm} mm: must be a positive length")));
    }
    if fem_steps == 0 {
        return Err(stage_err("fem_steps", "must be ≥ 1"));
    }
    if let Some(r) = region_mm {
        if !(r.is_finite() && r > 0.0) {
            return Err(stage_err("fem_region_mm", format!("{r} mm: must be a positive distance")));
        }
    }
    let key = serde_json::json!({"organ": organ.display().to_string(), "incision": incision, "edge_mm": edge_mm, "fem_steps": fem_steps, "fem_region_mm": region_mm});
    let report_path = dir.join("ground_truth.json");
    if let Ok(text) = std::fs::read_to_string(&report_path) {
        if let Ok(v) = serde_json::from_str::<serde_json::Value>(&text) {
            if v["settings"] == key {
                if let Ok(d) = Deformation::read(&dir.join("deformation")) {
                    return Ok((d, v));
                }
            }
        }
    }
    std::fs::create_dir_all(dir).map_err(|e| laparo_core::CoreError::io(dir, e))?;
    let surface = laparo_core::mesh::read_mesh(organ)?;
    let name = organ.display().to_string();
    let (mesh, quality) =
        tetrahedralize_surface(surface.clone(), &name, &TetraParams { edge_mm, ..Default::default() })
            .map_err(|e| stage_err(&name, e.to_string()))?;
    let frame = ScenarioFrame::default();
    let mut scn = match incision {
        "non-anatomical" => non_anatomical_on(&mesh, &surface, &frame, &NonAnatomicalParams::default()),
        "anatomical" => anatomical_on(&mesh, &surface, &frame, &AnatomicalParams::default()),
        o => return Err(stage_err("incision", format!("{o:?}: expected non-anatomical or anatomical"))),
    }
    .map_err(|e| stage_err(&name, e.to_string()))?;
    let Some(tumour) = scn.tumour else {
        return Err(stage_err(
            "incision",
            format!("the {incision} scenario has no tumour to guide to: use non-anatomical"),
        ));
    };
    let dropped = drop_detached_fragments(&mut scn);
    let mut region_fixed = 0;
    if let Some(r) = region_mm {
        let x = &scn.cut.mesh.vertices;
        let crack: Vec<_> = scn.cut.crack_faces.iter().flatten().flatten().map(|&i| x[i]).collect();
        let d = laparo_register::benchmark::tre::distance_to_nearest(x, &crack)?;
        let before = scn.fixed_nodes.len();
        scn.fixed_nodes.extend((0..x.len()).filter(|&i| d[i] > r));
        scn.fixed_nodes.sort_unstable();
        scn.fixed_nodes.dedup();
        region_fixed = scn.fixed_nodes.len() - before;
        if region_fixed + before >= x.len() {
            return Err(stage_err("fem_region_mm", format!("{r} mm leaves no free node")));
        }
    }
    let mut gcfg = GroundTruthConfig::for_scenario(incision);
    gcfg.steps = fem_steps;
    let (u, rep) = fem_ground_truth(&scn, &gcfg, &mut |k, p, g| {
        progress(format!("FEM solve {} at {p:.4} kPa → lip gap {g:.2} mm", k + 1))
    })?;
    let d = Deformation {
        rest: scn.cut.mesh.clone(),
        deformed: scn.cut.mesh.vertices.iter().zip(&u).map(|(x, u)| x + u).collect(),
        lips: scn.cut.lips.clone(),
        tumour_centre_mm: tumour.centre,
        tumour_radius_mm: tumour.radius_mm,
    };
    d.write(&dir.join("deformation"))?;
    let v = serde_json::json!({
        "settings": key,
        "mesh": {"nodes": quality.nodes, "tets": quality.tets, "min_dihedral_deg": quality.min_dihedral_deg},
        "fragment_nodes_removed": dropped,
        "fem_region_mm": region_mm,
        "nodes_fixed_outside_the_region": region_fixed,
        "report": rep,
    });
    write_atomic(&report_path, serde_json::to_string_pretty(&v).unwrap_or_default().as_bytes())?;
    Ok((d, v))
}

fn route_dir(r: Route) -> &'static str {
    match r {
        Route::Calibrated => "calibrated",
        Route::SelfRectified => "self-rectified",
    }
}

/// FEM ground truth → scenario → pipeline per route → `out/index.html` and `out/summary.json`.
/// `organ`, `frame` and `camera` are the scenario inputs of [`scenario::generate`].
pub fn run(
    organ: &Path,
    frame: &Path,
    camera: &Path,
    cfg: &EndToEndConfig,
    out: &Path,
    progress: &mut dyn FnMut(&str),
) -> Result<EndToEndReport> {
    let t_all = Instant::now();
    if cfg.routes.is_empty() {
        return Err(GuideError::stage("guide", "routes", "no stereo route to run"));
    }
    std::fs::create_dir_all(out).map_err(|e| laparo_core::CoreError::io(out, e))?;
    let mut steps = Vec::new();
    // 1. ground truth
    let t0 = Instant::now();
    let gt_dir = out.join("ground-truth");
    let (_, gt) =
        fem_incision(organ, &cfg.incision, cfg.edge_mm, cfg.fem_steps, cfg.fem_region_mm, &gt_dir, &mut |s| {
            progress(&format!("[ground truth] {s}"))
        })?;
    let r = &gt["report"];
    let detail = format!(
        "{} TET10 free DOFs, lip gap {:.2} mm at {:.4} kPa, max |u| {:.2} mm, min J {:.3}",
        r["free_dofs"],
        r["max_gap_mm"].as_f64().unwrap_or(f64::NAN),
        r["pressure_kpa"].as_f64().unwrap_or(f64::NAN),
        r["max_displacement_mm"].as_f64().unwrap_or(f64::NAN),
        r["min_j"].as_f64().unwrap_or(f64::NAN)
    );
    progress(&format!("[ground truth] {detail} ({:.1} s)", t0.elapsed().as_secs_f64()));
    steps.push(StepRecord { name: "FEM ground truth".into(), seconds: t0.elapsed().as_secs_f64(), detail });
    // 2. scenario (re-rendered every run: seconds)
    let t0 = Instant::now();
    let scn_dir = out.join("scenario");
    let s = scenario::generate(organ, frame, camera, Some(&gt_dir.join("deformation")), &cfg.scenario, &scn_dir)?;
    let detail = format!(
        "{}×{} px, displacement mean {:.2} / max {:.2} mm, liver pixels {:?}",
        cfg.scenario.width,
        cfg.scenario.height,
        s.manifest.displacement_mm[0],
        s.manifest.displacement_mm[1],
        s.liver_pixels
    );
    progress(&format!("[scenario] {detail} ({:.1} s)", t0.elapsed().as_secs_f64()));
    steps.push(StepRecord { name: "scenario".into(), seconds: t0.elapsed().as_secs_f64(), detail });
    // 3. the pipeline, per route
    let mut reports: Vec<(Route, GuideReport)> = Vec::new();
    for rc in &cfg.routes {
        let t0 = Instant::now();
        let name = route_dir(rc.route);
        let rep = pipeline::run(&scn_dir, &out.join(name), rc, &mut |st: &StageRecord| {
            progress(&format!("[{name}] {} ({:.1} s): {}", st.name, st.seconds, st.metrics))
        })?;
        let tre = rep.summary["tre_mean_mm"].as_f64().unwrap_or(f64::NAN);
        steps.push(StepRecord {
            name: format!("pipeline ({name})"),
            seconds: t0.elapsed().as_secs_f64(),
            detail: format!("final TRE {tre:.2} mm"),
        });
        reports.push((rc.route, rep));
    }
    let tre = |r: Route| reports.iter().find(|(k, _)| *k == r).and_then(|(_, g)| g.summary["tre_mean_mm"].as_f64());
    let (tre_difference_mm, tre_difference_reason) = match (tre(Route::SelfRectified), tre(Route::Calibrated)) {
        (Some(a), Some(b)) => (Some(a - b), None),
        _ => (None, Some("needs both stereo routes (calibrated and self-rectified) with a final TRE".to_string())),
    };
    let routes = reports
        .iter()
        .map(|(k, g)| {
            serde_json::json!({
                "route": route_dir(*k),
                "summary": g.summary,
                "stages": g.stages.iter().map(|s| serde_json::json!({"name": s.name, "seconds": s.seconds})).collect::<Vec<_>>(),
                "total_seconds": g.total_seconds,
            })
        })
        .collect();
    let rep = EndToEndReport {
        config: cfg.clone(),
        steps,
        ground_truth: gt,
        routes,
        tre_difference_mm,
        tre_difference_reason,
        peak_memory_mib: laparo_register::pipeline::peak_memory_mib(),
        total_seconds: t_all.elapsed().as_secs_f64(),
    };
    write_atomic(&out.join("summary.json"), serde_json::to_string_pretty(&rep).unwrap_or_default().as_bytes())?;
    crate::report::write_index(out, &rep, &reports.iter().map(|(k, g)| (route_dir(*k), g)).collect::<Vec<_>>())?;
    Ok(rep)
}

/// Path of the index report of an end-to-end run.
pub fn index_path(out: &Path) -> PathBuf {
    out.join("index.html")
}
