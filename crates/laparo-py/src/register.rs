//! `laparo.register`: RODS-MPM deformable registration (thesis Ch. 5): an organ (mesh file or
//! NumPy particles, mm) + source landmark groups + targets → optimised initial velocities v₀ and
//! the registered particles (eq. 5.10 loss). `register_run` is `laparo register` (all its files
//! and report.json); `register_arrays` returns the arrays without writing anything.
use crate::arrays::*;
use laparo_mpm::{det, Vector};
use laparo_register::io::{read_landmarks, read_targets, SourceGroup, TargetSpec};
use laparo_register::optimize::{register_sided, OptimizerConfig, OptimizerKind};
use laparo_register::organ::{organ_from_mesh, organ_from_points, OrganConfig, Roi};
use laparo_register::pipeline::{build_loss, run_job, Job};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyTuple};
use std::path::PathBuf;

/// The preset of an optimiser name (`laparo_register::optimize::OptimizerConfig::preset`).
fn optimizer_preset(s: &str) -> PyResult<OptimizerConfig> {
    OptimizerConfig::preset(s).ok_or_else(|| {
        bad("optimizer", format!("{s:?}: expected one of {}", laparo_register::optimize::PRESET_NAMES.join(", ")))
    })
}

/// `ball:x,y,z,r` or `box:x0,y0,z0,x1,y1,z1` (mm), as `laparo register --roi`.
fn parse_roi(s: &str) -> PyResult<Roi> {
    let err = || bad("roi", format!("{s:?}: expected ball:x,y,z,r (r > 0) or box:x0,y0,z0,x1,y1,z1 (lo < hi)"));
    let (kind, rest) = s.split_once(':').ok_or_else(err)?;
    let v: Vec<f64> = rest.split(',').map(|x| x.trim().parse::<f64>()).collect::<Result<_, _>>().map_err(|_| err())?;
    if v.iter().any(|x| !x.is_finite()) {
        return Err(err());
    }
    match (kind, v.len()) {
        ("ball", 4) if v[3] > 0.0 => Ok(Roi::Ball { center: [v[0], v[1], v[2]], radius_mm: v[3] }),
        ("box", 6) if (0..3).all(|d| v[d] < v[d + 3]) => {
            Ok(Roi::Box { lo: [v[0], v[1], v[2]], hi: [v[3], v[4], v[5]] })
        }
        _ => Err(err()),
    }
}

/// `crack`: a mesh file or (vertices (N, 3) mm, faces (F, 3)), normals from side −1 to side +1; `crack_band_mm`
/// the labelling band (default 3 grid cells).
fn crack_from(
    obj: Option<&Bound<'_, PyAny>>,
    band_mm: Option<f64>,
) -> PyResult<Option<laparo_register::crack::CrackSurface>> {
    let Some(obj) = obj else {
        return match band_mm {
            Some(_) => Err(bad("crack_band_mm", "needs crack")),
            None => Ok(None),
        };
    };
    let (mesh, name) = if let Some(p) = as_path(obj) {
        (laparo_core::mesh::read_mesh(&p).map_err(lib_err)?, format!("crack {}", p.display()))
    } else {
        let t = obj
            .cast::<PyTuple>()
            .map_err(|_| pyo3::exceptions::PyTypeError::new_err("crack: expected a path or (vertices, faces)"))?;
        if t.len() != 2 {
            return Err(bad("crack", "expected (vertices, faces)"));
        }
        let vertices = points3(&t.get_item(0)?, "crack vertices")?;
        let faces = index_rows::<3>(&t.get_item(1)?, "faces", "crack", vertices.len())?;
        (laparo_core::mesh::TriMesh { vertices, faces }, "crack".to_string())
    };
    laparo_register::crack::CrackSurface::from_mesh(&mesh, &name, band_mm).map(Some).map_err(lib_err)
}

fn as_path(obj: &Bound<'_, PyAny>) -> Option<PathBuf> {
    obj.extract::<PathBuf>().ok()
}

/// Landmarks: a path (JSON groups or CSV), or a list of (name, (K, 3) points mm, weight).
pub(crate) fn landmarks_from(obj: &Bound<'_, PyAny>) -> PyResult<Vec<SourceGroup>> {
    if let Some(p) = as_path(obj) {
        return read_landmarks(&p).map_err(lib_err);
    }
    let list = obj.cast::<PyList>().map_err(|_| {
        pyo3::exceptions::PyTypeError::new_err("landmarks: expected a path or a list of (name, points, weight)")
    })?;
    let mut out = Vec::new();
    for (i, item) in list.iter().enumerate() {
        let t =
            item.cast::<PyTuple>().map_err(|_| bad("landmarks", format!("[{i}]: expected (name, points, weight)")))?;
        if t.len() != 3 {
            return Err(bad("landmarks", format!("[{i}]: expected (name, points, weight)")));
        }
        let name: String =
            t.get_item(0)?.extract().map_err(|_| bad("landmarks", format!("[{i}]: name is not a str")))?;
        let points = points3(&t.get_item(1)?, &format!("landmarks[{name:?}]"))?;
        let weight: f64 = t.get_item(2)?.extract().map_err(|_| bad("landmarks", format!("[{name:?}]: weight")))?;
        if !(weight > 0.0 && weight.is_finite()) {
            return Err(bad("landmarks", format!("group {name:?}: weight {weight} must be > 0")));
        }
        if out.iter().any(|g: &SourceGroup| g.name == name) {
            return Err(bad("landmarks", format!("group {name:?} given twice")));
        }
        out.push(SourceGroup { name, points, weight });
    }
    if out.iter().all(|g| g.points.is_empty()) {
        return Err(bad("landmarks", "no landmark"));
    }
    Ok(out)
}

/// Targets: a path (JSON groups by name, or a PLY/OBJ surface / point cloud shared by all
/// groups), or a list of (name, kind, (M, 3) points mm, faces or None) with kind `points`,
/// `polyline`, `cloud` or `surface`, matched to the landmark groups by name.
pub(crate) fn targets_from(obj: &Bound<'_, PyAny>, groups: &[SourceGroup]) -> PyResult<Vec<TargetSpec>> {
    if let Some(p) = as_path(obj) {
        return read_targets(&p, groups).map_err(lib_err);
    }
    let list = obj.cast::<PyList>().map_err(|_| {
        pyo3::exceptions::PyTypeError::new_err("targets: expected a path or a list of (name, kind, points, faces)")
    })?;
    let mut parsed: Vec<(String, TargetSpec)> = Vec::new();
    for (i, item) in list.iter().enumerate() {
        let t = item
            .cast::<PyTuple>()
            .map_err(|_| bad("targets", format!("[{i}]: expected (name, kind, points, faces)")))?;
        if t.len() != 4 {
            return Err(bad("targets", format!("[{i}]: expected (name, kind, points, faces)")));
        }
        let name: String = t.get_item(0)?.extract().map_err(|_| bad("targets", format!("[{i}]: name is not a str")))?;
        let kind: String = t.get_item(1)?.extract().map_err(|_| bad("targets", format!("[{name:?}]: kind")))?;
        let pts = points3(&t.get_item(2)?, &format!("targets[{name:?}]"))?;
        if pts.is_empty() {
            return Err(bad("targets", format!("group {name:?} is empty")));
        }
        let spec = match kind.as_str() {
            "points" => TargetSpec::Points(pts),
            "polyline" => TargetSpec::Polyline(pts),
            "cloud" => TargetSpec::Cloud(pts),
            "surface" => {
                let faces = index_rows::<3>(&t.get_item(3)?, "faces", &format!("target {name:?}"), pts.len())?;
                TargetSpec::Surface(pts, faces)
            }
            k => return Err(bad("targets", format!("group {name:?}: kind {k:?} (points, polyline, cloud, surface)"))),
        };
        parsed.push((name, spec));
    }
    groups
        .iter()
        .map(|g| {
            let (_, s) = parsed
                .iter()
                .find(|(n, _)| *n == g.name)
                .ok_or_else(|| bad("targets", format!("no target for landmark group {:?}", g.name)))?;
            if let TargetSpec::Points(p) = s {
                if p.len() != g.points.len() {
                    return Err(bad(
                        "targets",
                        format!("group {:?}: {} target points for {} landmarks", g.name, p.len(), g.points.len()),
                    ));
                }
            }
            Ok(s.clone())
        })
        .collect()
}

/// The organ and optimiser settings of `laparo register` (same defaults and rules).
#[allow(clippy::too_many_arguments)]
fn configs(
    spacing_mm: f64,
    dx_mm: Option<f64>,
    optimizer: &str,
    iterations: Option<usize>,
    roi: Option<&str>,
    youngs_modulus_kpa: f64,
    poisson_ratio: f64,
    density_kg_m3: f64,
    steps: usize,
    dt_s: Option<f64>,
    joint_e: bool,
    smoothing_dx: Option<f64>,
    max_step_dx: Option<f64>,
    target_mean_mm: f64,
    memory_gb: Option<f64>,
    kinetic_weight: f64,
    at_rest_weight: f64,
    unknown: &str,
    damping_per_horizon: f64,
) -> PyResult<(OrganConfig, OptimizerConfig)> {
    for (name, v) in [
        ("spacing_mm", spacing_mm),
        ("youngs_modulus_kpa", youngs_modulus_kpa),
        ("poisson_ratio", poisson_ratio),
        ("density_kg_m3", density_kg_m3),
        ("smoothing_dx", smoothing_dx.unwrap_or(0.0)),
        ("max_step_dx", max_step_dx.unwrap_or(1.0)),
        ("target_mean_mm", target_mean_mm),
        ("kinetic_weight", kinetic_weight),
        ("at_rest_weight", at_rest_weight),
    ] {
        if !v.is_finite() {
            return Err(bad(name, format!("{v} is not finite")));
        }
    }
    let base = optimizer_preset(optimizer)?;
    let kind = base.kind;
    let opt = OptimizerConfig {
        iterations: iterations.unwrap_or(base.iterations),
        smoothing_dx: if kind == OptimizerKind::ThesisGd { 0.0 } else { smoothing_dx.unwrap_or(base.smoothing_dx) },
        max_step_dx: max_step_dx.unwrap_or(base.max_step_dx),
        target_mean_distance: target_mean_mm,
        joint_youngs_modulus: joint_e,
        kinetic_weight,
        terminal_kinetic_weight: at_rest_weight,
        unknown: laparo_register::optimize::Unknown::from_name(unknown, damping_per_horizon).map_err(lib_err)?,
        ..base
    };
    let organ = OrganConfig {
        spacing_mm,
        dx_mm,
        youngs_modulus_kpa,
        poisson_ratio,
        density_kg_m3,
        steps,
        dt_s,
        roi: roi.map(parse_roi).transpose()?,
        memory_limit_bytes: memory_gb.map(|g| g * 1e9),
        ..Default::default()
    };
    Ok((organ, opt))
}

/// The cut surface assumed from one lip (`laparo register --assumed-cut-depth-mm`): `organ`'s surface,
/// the lip polyline (K, 3) mm and the depth (mm) → (vertices (2K, 3) mm, faces (2K − 2, 3) as int64).
#[pyfunction]
pub fn register_assumed_cut<'py>(
    py: Python<'py>,
    organ: PathBuf,
    lip: &Bound<'py, PyAny>,
    depth_mm: f64,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    guard(|| {
        let lip = points3(lip, "lip")?;
        let surface = laparo_register::organ::organ_surface(&organ).map_err(lib_err)?;
        let c = laparo_register::crack::CrackSurface::swept_from_lip(&surface, &lip, depth_mm, None, "lip")
            .map_err(lib_err)?;
        let v: Vec<f64> = c.vertices.iter().flat_map(|p| [p[0], p[1], p[2]]).collect();
        let f: Vec<i64> = c.faces.iter().flat_map(|f| f.map(|i| i as i64)).collect();
        Ok((to_numpy(py, v, &[c.vertices.len(), 3])?, to_numpy(py, f, &[c.faces.len(), 3])?))
    })
}

/// `laparo register`: sample the organ mesh, register, write every output file of the CLI into
/// `out` (particles, surfaces, deformed meshes, overlay, loss curve, report.json, checkpoint).
/// Returns report.json as a dict.
#[pyfunction]
#[pyo3(signature = (organ, landmarks, targets, out, spacing_mm = 3.0, dx_mm = None, optimizer = "lbfgs", iterations = None, roi = None, tumour = None, image = None, camera = None, youngs_modulus_kpa = 4.1, poisson_ratio = 0.49, density_kg_m3 = 1000.0, steps = 200, dt_s = None, region_weight = 0.0, joint_e = false, smoothing_dx = None, max_step_dx = None, target_mean_mm = 0.0, resume = false, checkpoint_every = 5, memory_gb = None, kinetic_weight = 0.0, at_rest_weight = 0.0, crack = None, crack_band_mm = None, unknown = "velocity", damping_per_horizon = 10.0, thesis_landmarks = false))]
#[allow(clippy::too_many_arguments)]
pub fn register_run<'py>(
    py: Python<'py>,
    organ: PathBuf,
    landmarks: &Bound<'py, PyAny>,
    targets: &Bound<'py, PyAny>,
    out: PathBuf,
    spacing_mm: f64,
    dx_mm: Option<f64>,
    optimizer: &str,
    iterations: Option<usize>,
    roi: Option<&str>,
    tumour: Option<PathBuf>,
    image: Option<PathBuf>,
    camera: Option<PathBuf>,
    youngs_modulus_kpa: f64,
    poisson_ratio: f64,
    density_kg_m3: f64,
    steps: usize,
    dt_s: Option<f64>,
    region_weight: f64,
    joint_e: bool,
    smoothing_dx: Option<f64>,
    max_step_dx: Option<f64>,
    target_mean_mm: f64,
    resume: bool,
    checkpoint_every: usize,
    memory_gb: Option<f64>,
    kinetic_weight: f64,
    at_rest_weight: f64,
    crack: Option<&Bound<'py, PyAny>>,
    crack_band_mm: Option<f64>,
    unknown: &str,
    damping_per_horizon: f64,
    thesis_landmarks: bool,
) -> PyResult<Bound<'py, PyAny>> {
    guard(|| {
        let (organ_config, opt) = configs(
            spacing_mm,
            dx_mm,
            optimizer,
            iterations,
            roi,
            youngs_modulus_kpa,
            poisson_ratio,
            density_kg_m3,
            steps,
            dt_s,
            joint_e,
            smoothing_dx,
            max_step_dx,
            target_mean_mm,
            memory_gb,
            kinetic_weight,
            at_rest_weight,
            unknown,
            damping_per_horizon,
        )?;
        let crack = crack_from(crack, crack_band_mm)?;
        if !(region_weight >= 0.0 && region_weight.is_finite()) {
            return Err(bad("region_weight", format!("{region_weight} (must be ≥ 0)")));
        }
        let groups = landmarks_from(landmarks)?;
        let tg = targets_from(targets, &groups)?;
        let overlay = match (image, camera) {
            (Some(i), Some(c)) => Some((i, c)),
            (None, None) => None,
            _ => return Err(bad("image", "image and camera go together")),
        };
        let job = Job {
            organ,
            organ_config,
            landmarks: groups,
            targets: tg,
            region_weight,
            optimizer: opt,
            tumour,
            overlay,
            out,
            resume,
            checkpoint_every,
            crack,
            landmark_offsets: !thesis_landmarks,
        };
        let report = par(py, || run_job(&job, &mut |_| {})).map_err(lib_err)?;
        to_py(py, &report)
    })
}

/// Register in memory: the organ from a mesh file (`organ`) or from particle positions
/// (`particles`, (N, 3) mm, sampled at `spacing_mm`); nothing is written. Returns the registered
/// and rest particle positions (model mm), v₀ (mm/s), J = det F, the iteration history, the
/// residuals before/after and the set-up (Δx, Δt, grid, offset).
#[pyfunction]
#[pyo3(signature = (landmarks, targets, organ = None, particles = None, spacing_mm = 3.0, dx_mm = None, optimizer = "lbfgs", iterations = None, roi = None, youngs_modulus_kpa = 4.1, poisson_ratio = 0.49, density_kg_m3 = 1000.0, steps = 200, dt_s = None, region_weight = 0.0, joint_e = false, smoothing_dx = None, max_step_dx = None, target_mean_mm = 0.0, memory_gb = None, kinetic_weight = 0.0, at_rest_weight = 0.0, crack = None, crack_band_mm = None, unknown = "velocity", damping_per_horizon = 10.0, thesis_landmarks = false))]
#[allow(clippy::too_many_arguments)]
pub fn register_arrays<'py>(
    py: Python<'py>,
    landmarks: &Bound<'py, PyAny>,
    targets: &Bound<'py, PyAny>,
    organ: Option<PathBuf>,
    particles: Option<&Bound<'py, PyAny>>,
    spacing_mm: f64,
    dx_mm: Option<f64>,
    optimizer: &str,
    iterations: Option<usize>,
    roi: Option<&str>,
    youngs_modulus_kpa: f64,
    poisson_ratio: f64,
    density_kg_m3: f64,
    steps: usize,
    dt_s: Option<f64>,
    region_weight: f64,
    joint_e: bool,
    smoothing_dx: Option<f64>,
    max_step_dx: Option<f64>,
    target_mean_mm: f64,
    memory_gb: Option<f64>,
    kinetic_weight: f64,
    at_rest_weight: f64,
    crack: Option<&Bound<'py, PyAny>>,
    crack_band_mm: Option<f64>,
    unknown: &str,
    damping_per_horizon: f64,
    thesis_landmarks: bool,
) -> PyResult<Bound<'py, PyDict>> {
    guard(|| {
        let (organ_config, opt) = configs(
            spacing_mm,
            dx_mm,
            optimizer,
            iterations,
            roi,
            youngs_modulus_kpa,
            poisson_ratio,
            density_kg_m3,
            steps,
            dt_s,
            joint_e,
            smoothing_dx,
            max_step_dx,
            target_mean_mm,
            memory_gb,
            kinetic_weight,
            at_rest_weight,
            unknown,
            damping_per_horizon,
        )?;
        let crack = crack_from(crack, crack_band_mm)?;
        if !(region_weight >= 0.0 && region_weight.is_finite()) {
            return Err(bad("region_weight", format!("{region_weight} (must be ≥ 0)")));
        }
        let pts = match (&organ, particles) {
            (Some(_), Some(_)) => return Err(bad("particles", "give organ (a mesh file) or particles, not both")),
            (None, None) => return Err(bad("organ", "give organ (a mesh file) or particles ((N, 3) mm)")),
            (None, Some(p)) => {
                let v = points3(p, "particles")?;
                if v.is_empty() {
                    return Err(bad("particles", "no particle"));
                }
                Some(v)
            }
            (Some(_), None) => None,
        };
        let groups = landmarks_from(landmarks)?;
        let tg = targets_from(targets, &groups)?;
        let res = par(py, || -> laparo_register::Result<_> {
            let o = match (pts, &organ) {
                (Some(p), _) => organ_from_points(p, &organ_config, "particles")?,
                (None, Some(path)) => organ_from_mesh(path, &organ_config)?,
                (None, None) => unreachable!("checked above"),
            };
            let mut o = o;
            let labels = match &crack {
                Some(c) => {
                    let rest = o.rest_model();
                    Some(laparo_register::crack::label_organ(&mut o, c, &rest, &rest)?)
                }
                None => None,
            };
            let mut loss = build_loss(&o, &groups, &tg, region_weight, "landmarks")?;
            if !thesis_landmarks {
                loss.offsets = laparo_register::pipeline::landmark_offsets(&o, &groups, &loss);
            }
            let before = loss.residuals(&o.scene.positions);
            let reg = register_sided(&o.scene, &loss, &opt, None, &o.smoothing_sides, &mut |_, _| true)?;
            let after = loss.residuals(&reg.final_state.x);
            Ok((o, reg, before, after, labels))
        })
        .map_err(lib_err)?;
        let (o, reg, before, after, labels) = res;
        let off = o.offset;
        let flat = |v: &[Vector<3>], shift: bool| -> Vec<f64> {
            v.iter()
                .flat_map(|p| {
                    let q = if shift { p - off } else { *p };
                    [q[0], q[1], q[2]]
                })
                .collect()
        };
        let n = o.scene.n_particles();
        let fin = &reg.final_state;
        let d = PyDict::new(py);
        d.set_item("positions", to_numpy(py, flat(&fin.x, true), &[n, 3])?)?;
        d.set_item("rest_positions", to_numpy(py, flat(&o.scene.positions, true), &[n, 3])?)?;
        d.set_item("velocities", to_numpy(py, flat(&reg.velocities, false), &[n, 3])?)?;
        if let Some(f) = &reg.loads {
            d.set_item("loads", to_numpy(py, flat(f, false), &[n, 3])?)?;
        }
        d.set_item("final_velocities", to_numpy(py, flat(&fin.v, false), &[n, 3])?)?;
        d.set_item("j", to_numpy(py, fin.f.iter().map(det).collect::<Vec<f64>>(), &[n])?)?;
        d.set_item("history", to_py(py, &reg.history)?)?;
        let (first, last) = (reg.history.first().map(|r| r.mean_distance), reg.history.last().map(|r| r.mean_distance));
        d.set_item("mean_distance_mm", (first.unwrap_or(f64::NAN), last.unwrap_or(f64::NAN)))?;
        d.set_item("residual_before", to_py(py, &before)?)?;
        d.set_item("residual_after", to_py(py, &after)?)?;
        d.set_item("stop_reason", &reg.stop_reason)?;
        d.set_item("youngs_modulus_kpa", reg.youngs_modulus)?;
        d.set_item("fixed_particles", o.fixed_count)?;
        d.set_item("spacing_mm", o.spacing_mm)?;
        d.set_item("dx_mm", o.scene.grid.dx)?;
        d.set_item("n_grid", o.scene.grid.n_grid)?;
        d.set_item("dt_s", o.scene.dt)?;
        d.set_item("steps", o.scene.steps)?;
        d.set_item("offset_mm", (off[0], off[1], off[2]))?;
        d.set_item("warnings", o.warnings.clone())?;
        d.set_item("crack", to_py(py, &labels)?)?;
        d.set_item(
            "crack_side",
            to_numpy(
                py,
                o.scene.crack_side.iter().map(|&c| c as i64).collect::<Vec<i64>>(),
                &[o.scene.crack_side.len()],
            )?,
        )?;
        d.set_item("optimizer", to_py(py, &opt)?)?;
        d.set_item("organ_config", to_py(py, &organ_config)?)?;
        Ok(d)
    })
}
