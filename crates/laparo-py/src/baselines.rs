//! `laparo.register.arap / drbc / lddmm`: the mesh-based registration baselines of the incision
//! benchmark (thesis §5.4.2, Table 5.1) on NumPy arrays: a rest tetrahedral mesh (mm), landmark groups
//! (points in or on the mesh, located as material points by barycentric coordinates) and their targets
//! (the eq. 5.10 distance, closest point recomputed at every evaluation) → the deformed nodes.
use crate::arrays::*;
use crate::register::{landmarks_from, targets_from};
use laparo_fem::NeoHookean;
use laparo_register::baselines::{
    arap, drbc, lddmm, ArapConfig, ArapEnergy, ArapWeights, BaselineProblem, BaselineResult, DrbcConfig, LddmmConfig,
    MeshLandmarkGroup, TetLocator,
};
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// The problem every baseline solves, built and validated from the Python arguments.
fn problem(
    nodes: &Bound<'_, PyAny>,
    tets: &Bound<'_, PyAny>,
    landmarks: Option<&Bound<'_, PyAny>>,
    targets: Option<&Bound<'_, PyAny>>,
    fixed: Option<&Bound<'_, PyAny>>,
    fixed_positions: Option<&Bound<'_, PyAny>>,
    outside_tolerance_mm: f64,
) -> PyResult<BaselineProblem> {
    let mesh = tet_mesh(nodes, tets)?;
    if !(outside_tolerance_mm.is_finite() && outside_tolerance_mm >= 0.0) {
        return Err(bad("outside_tolerance_mm", format!("{outside_tolerance_mm}: must be finite and ≥ 0")));
    }
    let (groups, specs) = match (landmarks, targets) {
        (Some(l), Some(t)) => {
            let groups = landmarks_from(l)?;
            let specs = targets_from(t, &groups)?;
            (groups, specs)
        }
        (None, None) => (Vec::new(), Vec::new()),
        _ => return Err(bad("targets", "give both landmarks and targets, or neither (fixed nodes only)")),
    };
    let locator = TetLocator::new(&mesh);
    let mut out = Vec::with_capacity(groups.len());
    for (g, spec) in groups.iter().zip(&specs) {
        let points = g
            .points
            .iter()
            .enumerate()
            .map(|(k, p)| {
                let what = format!("landmarks: group {:?} landmark {k}", g.name);
                locator.locate(p, outside_tolerance_mm, &what).map_err(lib_err)
            })
            .collect::<PyResult<Vec<_>>>()?;
        out.push(MeshLandmarkGroup {
            name: g.name.clone(),
            points,
            target: spec.group_target(nalgebra::Vector3::zeros()),
            weight: g.weight,
        });
    }
    let mut p = BaselineProblem::new(mesh, out);
    match (fixed, fixed_positions) {
        (Some(f), None) => {
            let f = indices(f, "fixed", p.mesh.vertices.len())?;
            p.fix_at_rest(&f);
        }
        (Some(f), Some(x)) => {
            let f = indices(f, "fixed", p.mesh.vertices.len())?;
            let x = points3(x, "fixed_positions")?;
            if x.len() != f.len() {
                return Err(bad("fixed_positions", format!("{} positions for {} fixed nodes", x.len(), f.len())));
            }
            p.fixed = f.into_iter().zip(x).collect();
        }
        (None, Some(_)) => return Err(bad("fixed_positions", "needs fixed")),
        (None, None) => {}
    }
    p.validate().map_err(lib_err)?;
    Ok(p)
}

fn result_out<'py>(py: Python<'py>, r: &BaselineResult) -> PyResult<Bound<'py, PyAny>> {
    let out = PyDict::new(py);
    out.set_item("positions", to_numpy(py, flat(&r.positions), &[r.positions.len(), 3])?)?;
    out.set_item("report", to_py(py, &r.report)?)?;
    Ok(out.into_any())
}

fn positive(v: f64, arg: &str) -> PyResult<()> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(bad(arg, format!("{v}: must be finite and > 0")))
    }
}

/// Volumetric ARAP (Sorkine & Alexa 2007) with a soft landmark term, closest points re-linearised.
#[pyfunction]
#[pyo3(signature = (nodes, tets, landmarks=None, targets=None, fixed=None, fixed_positions=None, energy="spokes", weights="cotangent",
    landmark_weight=None, iterations=200, tolerance_mm=1e-3, outside_tolerance_mm=1.0))]
#[allow(clippy::too_many_arguments)]
pub fn register_arap<'py>(
    py: Python<'py>,
    nodes: &Bound<'py, PyAny>,
    tets: &Bound<'py, PyAny>,
    landmarks: Option<&Bound<'py, PyAny>>,
    targets: Option<&Bound<'py, PyAny>>,
    fixed: Option<&Bound<'py, PyAny>>,
    fixed_positions: Option<&Bound<'py, PyAny>>,
    energy: &str,
    weights: &str,
    landmark_weight: Option<f64>,
    iterations: usize,
    tolerance_mm: f64,
    outside_tolerance_mm: f64,
) -> PyResult<Bound<'py, PyAny>> {
    guard(|| {
        let energy = match energy {
            "spokes" => ArapEnergy::Spokes,
            "elements" => ArapEnergy::Elements,
            e => return Err(bad("energy", format!("{e:?}: expected spokes or elements"))),
        };
        let weights = match weights {
            "cotangent" => ArapWeights::Cotangent,
            "uniform" => ArapWeights::Uniform,
            w => return Err(bad("weights", format!("{w:?}: expected cotangent or uniform"))),
        };
        if let Some(w) = landmark_weight {
            positive(w, "landmark_weight")?;
        }
        if !(tolerance_mm.is_finite() && tolerance_mm >= 0.0) {
            return Err(bad(
                "tolerance_mm",
                format!("{tolerance_mm}: must be finite and ≥ 0 (0: run every iteration)"),
            ));
        }
        let p = problem(nodes, tets, landmarks, targets, fixed, fixed_positions, outside_tolerance_mm)?;
        let cfg = ArapConfig { energy, weights, landmark_weight, iterations, tolerance_mm };
        let r = par(py, || arap(&p, &cfg)).map_err(lib_err)?;
        result_out(py, &r)
    })
}

/// DRBC (Collins 2020): landmark term + λ × Neo-Hookean energy (eq. 5.3) on the tetrahedra, Newton.
#[pyfunction]
#[pyo3(signature = (nodes, tets, landmarks=None, targets=None, fixed=None, fixed_positions=None, young_kpa=4.1, poisson=0.49, lam=None,
    iterations=50, outside_tolerance_mm=1.0))]
#[allow(clippy::too_many_arguments)]
pub fn register_drbc<'py>(
    py: Python<'py>,
    nodes: &Bound<'py, PyAny>,
    tets: &Bound<'py, PyAny>,
    landmarks: Option<&Bound<'py, PyAny>>,
    targets: Option<&Bound<'py, PyAny>>,
    fixed: Option<&Bound<'py, PyAny>>,
    fixed_positions: Option<&Bound<'py, PyAny>>,
    young_kpa: f64,
    poisson: f64,
    lam: Option<f64>,
    iterations: usize,
    outside_tolerance_mm: f64,
) -> PyResult<Bound<'py, PyAny>> {
    guard(|| {
        let material = NeoHookean::from_young_poisson(young_kpa, poisson).map_err(lib_err)?;
        if let Some(l) = lam {
            positive(l, "lam")?;
        }
        let p = problem(nodes, tets, landmarks, targets, fixed, fixed_positions, outside_tolerance_mm)?;
        let cfg = DrbcConfig { material, lambda: lam, iterations, ..Default::default() };
        let r = par(py, || drbc(&p, &cfg)).map_err(lib_err)?;
        result_out(py, &r)
    })
}

/// Landmark LDDMM (Beg 2005): geodesic shooting with a Gaussian kernel of width `sigma_mm`, every node
/// advected by the flow.
#[pyfunction]
#[pyo3(signature = (nodes, tets, landmarks=None, targets=None, fixed=None, fixed_positions=None, sigma_mm=20.0, steps=10, gamma=0.01,
    iterations=300, outside_tolerance_mm=1.0))]
#[allow(clippy::too_many_arguments)]
pub fn register_lddmm<'py>(
    py: Python<'py>,
    nodes: &Bound<'py, PyAny>,
    tets: &Bound<'py, PyAny>,
    landmarks: Option<&Bound<'py, PyAny>>,
    targets: Option<&Bound<'py, PyAny>>,
    fixed: Option<&Bound<'py, PyAny>>,
    fixed_positions: Option<&Bound<'py, PyAny>>,
    sigma_mm: f64,
    steps: usize,
    gamma: f64,
    iterations: usize,
    outside_tolerance_mm: f64,
) -> PyResult<Bound<'py, PyAny>> {
    guard(|| {
        positive(sigma_mm, "sigma_mm")?;
        positive(gamma, "gamma")?;
        if steps == 0 {
            return Err(bad("steps", "must be ≥ 1"));
        }
        let p = problem(nodes, tets, landmarks, targets, fixed, fixed_positions, outside_tolerance_mm)?;
        let cfg = LddmmConfig { sigma_mm, steps, gamma, iterations, ..Default::default() };
        let r = par(py, || lddmm(&p, &cfg)).map_err(lib_err)?;
        result_out(py, &r)
    })
}
