//! `laparo.mpm`: differentiable MLS-MPM (thesis §5.2.3–5.2.4, eqs. 5.3–5.7) on scenes built from
//! NumPy particles; exact reverse-mode gradients w.r.t. v₀, x₀, E and ν (the RODS-MPM unknowns,
//! eq. 5.10).
use crate::arrays::*;
use laparo_mpm::{
    simulate, simulate_with_gradient, Boundary, FinalLoss, GridSpec, LandmarkLoss, Material, Matrix, Model,
    ParticleState, Scene, Vector, WallKind,
};
use pyo3::prelude::*;
use pyo3::types::PyDict;

#[derive(Clone)]
enum AnyScene {
    D2(Scene<2>),
    D3(Scene<3>),
}

/// An MPM scene (2D or 3D): particles, material, grid, walls, Δt, T.
#[pyclass(name = "MpmScene", module = "laparo._laparo", frozen)]
#[derive(Clone)]
pub struct PyMpmScene {
    scene: AnyScene,
}

fn vectors<const D: usize>(a: &Arr<f64>) -> Vec<Vector<D>> {
    a.data.chunks(D).map(Vector::<D>::from_column_slice).collect()
}

fn flat_m<const D: usize>(v: &[Matrix<D>]) -> Vec<f64> {
    // Row-major D×D per particle.
    v.iter().flat_map(|m| (0..D).flat_map(move |i| (0..D).map(move |j| m[(i, j)]))).collect()
}

fn parse_model(s: &str) -> PyResult<Model> {
    match s {
        "neo_hookean" | "neohookean" => Ok(Model::NeoHookean),
        "fixed_corotated" => Ok(Model::FixedCorotated),
        _ => Err(bad("model", format!("'{s}' (expected neo_hookean or fixed_corotated)"))),
    }
}

fn parse_walls(s: &str) -> PyResult<WallKind> {
    match s {
        "sticky" => Ok(WallKind::Sticky),
        "slip" => Ok(WallKind::Slip),
        "none" => Ok(WallKind::None),
        _ => Err(bad("walls", format!("'{s}' (expected sticky, slip or none)"))),
    }
}

fn particle_array(obj: &Bound<'_, PyAny>, arg: &str, n: Option<usize>, dim: usize) -> PyResult<Arr<f64>> {
    let a = f64_array(obj, arg)?;
    let rows = a.rows(arg, dim)?;
    if let Some(n) = n {
        if rows != n {
            return Err(bad(arg, format!("{rows} rows for {n} particles")));
        }
    }
    a.require_finite(arg)?;
    Ok(a)
}

fn state_dict<'py, const D: usize>(py: Python<'py>, s: ParticleState<D>) -> PyResult<Bound<'py, PyDict>> {
    let n = s.x.len();
    let d = PyDict::new(py);
    d.set_item("x", to_numpy(py, flat(&s.x), &[n, D])?)?;
    d.set_item("v", to_numpy(py, flat(&s.v), &[n, D])?)?;
    d.set_item("C", to_numpy(py, flat_m(&s.c), &[n, D, D])?)?;
    d.set_item("F", to_numpy(py, flat_m(&s.f), &[n, D, D])?)?;
    Ok(d)
}

fn warnings_list(w: &[laparo_mpm::Warning]) -> Vec<String> {
    w.iter().map(|w| w.to_string()).collect()
}

macro_rules! with_scene {
    ($s:expr, $sc:ident, $d:ident, $body:block) => {
        match $s {
            AnyScene::D2($sc) => {
                #[allow(dead_code)]
                const $d: usize = 2;
                $body
            }
            AnyScene::D3($sc) => {
                #[allow(dead_code)]
                const $d: usize = 3;
                $body
            }
        }
    };
}

fn build<const D: usize>(
    pos: &Arr<f64>,
    vel: Option<&Arr<f64>>,
    material: Material,
    grid: GridSpec,
    dt: f64,
    steps: usize,
    particle_volume: f64,
) -> Scene<D> {
    let mut s = Scene::<D>::new(vectors::<D>(pos), particle_volume, material, grid, dt, steps);
    if let Some(v) = vel {
        s.velocities = vectors::<D>(v);
    }
    s
}

#[pymethods]
impl PyMpmScene {
    /// Build a scene; see `laparo.mpm.Scene` for the parameters.
    #[new]
    #[pyo3(signature = (positions, particle_volume, youngs_modulus, poisson_ratio, density = 1.0, n_grid = 64, dx = None, dt = 1e-4, steps = 100, velocities = None, model = "neo_hookean", walls = "sticky", wall_thickness = 3, gravity = None, fixed = None, external_forces = None, crack_side = None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        positions: &Bound<'_, PyAny>,
        particle_volume: f64,
        youngs_modulus: f64,
        poisson_ratio: f64,
        density: f64,
        n_grid: usize,
        dx: Option<f64>,
        dt: f64,
        steps: usize,
        velocities: Option<&Bound<'_, PyAny>>,
        model: &str,
        walls: &str,
        wall_thickness: usize,
        gravity: Option<Vec<f64>>,
        fixed: Option<&Bound<'_, PyAny>>,
        external_forces: Option<&Bound<'_, PyAny>>,
        crack_side: Option<Vec<i64>>,
    ) -> PyResult<Self> {
        guard(|| {
            let pa = f64_array(positions, "positions")?;
            let dim = match pa.shape.as_slice() {
                [n, d] if *n > 0 && (*d == 2 || *d == 3) => *d,
                s => return Err(bad("positions", format!("expected shape (N, 2) or (N, 3) with N > 0, got {s:?}"))),
            };
            pa.require_finite("positions")?;
            let n = pa.shape[0];
            let va = velocities.map(|v| particle_array(v, "velocities", Some(n), dim)).transpose()?;
            let fa = external_forces.map(|v| particle_array(v, "external_forces", Some(n), dim)).transpose()?;
            let fixed = match fixed {
                Some(f) => {
                    let a = bool_array(f, "fixed")?;
                    if a.shape != [n] {
                        return Err(bad("fixed", format!("expected shape ({n},), got {:?}", a.shape)));
                    }
                    a.data
                }
                None => Vec::new(),
            };
            let crack_side: Vec<i8> = match crack_side {
                Some(c) if c.len() != n => {
                    return Err(bad("crack_side", format!("expected {n} values (one per particle), got {}", c.len())))
                }
                Some(c) => match c.iter().position(|v| !(-1..=1).contains(v)) {
                    Some(p) => return Err(bad("crack_side", format!("particle {p}: {} (must be -1, 0 or +1)", c[p]))),
                    None => c.iter().map(|&v| v as i8).collect(),
                },
                None => Vec::new(),
            };
            for (name, v) in [("particle_volume", particle_volume), ("dt", dt), ("density", density)] {
                if !(v.is_finite() && v > 0.0) {
                    return Err(bad(name, format!("{v} (must be finite and > 0)")));
                }
            }
            if n_grid < 8 {
                return Err(bad("n_grid", format!("{n_grid} (must be >= 8)")));
            }
            let grid = match dx {
                Some(dx) if !(dx.is_finite() && dx > 0.0) => return Err(bad("dx", format!("{dx} (must be > 0)"))),
                Some(dx) => GridSpec { n_grid, dx },
                None => GridSpec::unit(n_grid),
            };
            let material = Material { model: parse_model(model)?, youngs_modulus, poisson_ratio, density };
            material.validate().map_err(|e| bad("material", e))?;
            let g = gravity.unwrap_or_else(|| vec![0.0; dim]);
            if g.len() != dim || g.iter().any(|v| !v.is_finite()) {
                return Err(bad("gravity", format!("expected {dim} finite values, got {g:?}")));
            }
            let boundary = Boundary { walls: parse_walls(walls)?, thickness: wall_thickness };
            let scene = if dim == 2 {
                let mut s = build::<2>(&pa, va.as_ref(), material, grid, dt, steps, particle_volume);
                s.gravity = Vector::<2>::from_column_slice(&g);
                s.boundary = boundary;
                s.fixed = fixed;
                s.external_forces = fa.as_ref().map(vectors::<2>).unwrap_or_default();
                s.crack_side = crack_side;
                s.validate().map_err(|e| bad("scene", e))?;
                AnyScene::D2(s)
            } else {
                let mut s = build::<3>(&pa, va.as_ref(), material, grid, dt, steps, particle_volume);
                s.gravity = Vector::<3>::from_column_slice(&g);
                s.boundary = boundary;
                s.fixed = fixed;
                s.external_forces = fa.as_ref().map(vectors::<3>).unwrap_or_default();
                s.crack_side = crack_side;
                s.validate().map_err(|e| bad("scene", e))?;
                AnyScene::D3(s)
            };
            Ok(PyMpmScene { scene })
        })
    }

    /// Spatial dimension (2 or 3).
    #[getter]
    fn dim(&self) -> usize {
        match &self.scene {
            AnyScene::D2(_) => 2,
            AnyScene::D3(_) => 3,
        }
    }
    /// Number of particles.
    #[getter]
    fn n_particles(&self) -> usize {
        with_scene!(&self.scene, s, D, { s.n_particles() })
    }
    /// Initial positions (N, D).
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        with_scene!(&self.scene, s, D, { to_numpy(py, flat(&s.positions), &[s.n_particles(), D]) })
    }
    /// Initial velocities (N, D).
    #[getter]
    fn velocities<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        with_scene!(&self.scene, s, D, { to_numpy(py, flat(&s.velocities), &[s.n_particles(), D]) })
    }
    /// Young's modulus E.
    #[getter]
    fn youngs_modulus(&self) -> f64 {
        with_scene!(&self.scene, s, D, { s.material.youngs_modulus })
    }
    /// Poisson's ratio ν.
    #[getter]
    fn poisson_ratio(&self) -> f64 {
        with_scene!(&self.scene, s, D, { s.material.poisson_ratio })
    }
    /// Number of steps T.
    #[getter]
    fn steps(&self) -> usize {
        with_scene!(&self.scene, s, D, { s.steps })
    }
    /// Time step Δt.
    #[getter]
    fn dt(&self) -> f64 {
        with_scene!(&self.scene, s, D, { s.dt })
    }

    /// A copy with other initial velocities / positions / E / ν (the optimisation unknowns).
    #[pyo3(signature = (velocities = None, positions = None, youngs_modulus = None, poisson_ratio = None))]
    fn with_state(
        &self,
        velocities: Option<&Bound<'_, PyAny>>,
        positions: Option<&Bound<'_, PyAny>>,
        youngs_modulus: Option<f64>,
        poisson_ratio: Option<f64>,
    ) -> PyResult<Self> {
        guard(|| {
            let mut out = self.clone();
            with_scene!(&mut out.scene, s, D, {
                let n = s.n_particles();
                if let Some(v) = velocities {
                    s.velocities = vectors::<D>(&particle_array(v, "velocities", Some(n), D)?);
                }
                if let Some(p) = positions {
                    s.positions = vectors::<D>(&particle_array(p, "positions", Some(n), D)?);
                }
                if let Some(e) = youngs_modulus {
                    s.material.youngs_modulus = e;
                }
                if let Some(nu) = poisson_ratio {
                    s.material.poisson_ratio = nu;
                }
                s.material.validate().map_err(|e| bad("material", e))?;
                s.validate().map_err(|e| bad("scene", e))?;
            });
            Ok(out)
        })
    }

    /// Run T steps: dict(x, v, C, F, warnings) of the final particle state.
    fn simulate<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        guard(|| {
            with_scene!(&self.scene, s, D, {
                let sim = par(py, || simulate(s)).map_err(lib_err)?;
                let d = state_dict(py, sim.final_state)?;
                d.set_item("warnings", warnings_list(&sim.warnings))?;
                Ok(d)
            })
        })
    }

    /// Simulate and differentiate. Loss: landmark (mean distance of particles `indices` to
    /// `targets` after T steps, as the Rust `LandmarkLoss`), or linear `sum(weights * x_T)`
    /// (a vector-Jacobian product, what torch's backward needs). Returns dict(loss, x, v, C, F,
    /// d_velocities, d_positions, d_youngs_modulus, d_poisson_ratio, d_mu, d_lambda, warnings).
    #[pyo3(signature = (indices = None, targets = None, weights = None))]
    fn simulate_with_gradient<'py>(
        &self,
        py: Python<'py>,
        indices: Option<Vec<i64>>,
        targets: Option<&Bound<'py, PyAny>>,
        weights: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        guard(|| {
            with_scene!(&self.scene, s, D, {
                let n = s.n_particles();
                let r = match (indices, targets, weights) {
                    (Some(idx), Some(t), None) => {
                        let ta = particle_array(t, "targets", Some(idx.len()), D)?;
                        let mut ii = Vec::with_capacity(idx.len());
                        for &i in &idx {
                            if i < 0 || i as usize >= n {
                                return Err(bad("indices", format!("{i} out of range (0..{n})")));
                            }
                            ii.push(i as usize);
                        }
                        if ii.is_empty() {
                            return Err(bad("indices", "empty"));
                        }
                        let loss = LandmarkLoss::<D> { indices: ii, targets: vectors::<D>(&ta) };
                        par(py, || simulate_with_gradient(s, &loss)).map_err(lib_err)?
                    }
                    (None, None, Some(w)) => {
                        let wa = vectors::<D>(&particle_array(w, "weights", Some(n), D)?);
                        let loss = FinalLoss(move |x: &[Vector<D>], g: &mut [Vector<D>]| {
                            let mut l = 0.0;
                            for p in 0..x.len() {
                                l += wa[p].dot(&x[p]);
                                g[p] += wa[p];
                            }
                            l
                        });
                        par(py, || simulate_with_gradient(s, &loss)).map_err(lib_err)?
                    }
                    _ => return Err(bad("indices/targets/weights", "give indices and targets, or weights")),
                };
                let d = state_dict(py, r.final_state)?;
                d.set_item("loss", r.loss)?;
                d.set_item("d_velocities", to_numpy(py, flat(&r.d_velocities), &[n, D])?)?;
                d.set_item("d_positions", to_numpy(py, flat(&r.d_positions), &[n, D])?)?;
                d.set_item("d_youngs_modulus", r.d_youngs_modulus)?;
                d.set_item("d_poisson_ratio", r.d_poisson_ratio)?;
                d.set_item("d_mu", r.d_mu)?;
                d.set_item("d_lambda", r.d_lambda)?;
                d.set_item("warnings", warnings_list(&r.warnings))?;
                Ok(d)
            })
        })
    }

    fn __repr__(&self) -> String {
        with_scene!(&self.scene, s, D, {
            format!(
                "MpmScene(dim={}, n_particles={}, E={}, nu={}, n_grid={}, dt={}, steps={})",
                D,
                s.n_particles(),
                s.material.youngs_modulus,
                s.material.poisson_ratio,
                s.grid.n_grid,
                s.dt,
                s.steps
            )
        })
    }
}

/// A regular lattice of particles in the box [lo, hi] with the given spacing (as the Rust
/// `box_lattice`), shape (N, D).
#[pyfunction]
pub fn mpm_box_lattice<'py>(py: Python<'py>, lo: Vec<f64>, hi: Vec<f64>, spacing: f64) -> PyResult<Bound<'py, PyAny>> {
    guard(|| {
        if lo.len() != hi.len() || !(lo.len() == 2 || lo.len() == 3) {
            return Err(bad("lo/hi", "expected two points of dimension 2 or 3"));
        }
        if !(spacing.is_finite() && spacing > 0.0) || lo.iter().chain(&hi).any(|v| !v.is_finite()) {
            return Err(bad("spacing", "lo, hi and spacing must be finite, spacing > 0"));
        }
        if lo.len() == 2 {
            let p = laparo_mpm::box_lattice(
                Vector::<2>::from_column_slice(&lo),
                Vector::<2>::from_column_slice(&hi),
                spacing,
            );
            to_numpy(py, flat(&p), &[p.len(), 2])
        } else {
            let p = laparo_mpm::box_lattice(
                Vector::<3>::from_column_slice(&lo),
                Vector::<3>::from_column_slice(&hi),
                spacing,
            );
            to_numpy(py, flat(&p), &[p.len(), 3])
        }
    })
}

/// The largest stable Δt for the CFL number `cfl` (c Δt / Δx).
#[pyfunction]
pub fn mpm_cfl_dt(youngs_modulus: f64, poisson_ratio: f64, density: f64, dx: f64, cfl: f64) -> PyResult<f64> {
    let m = Material { model: Model::NeoHookean, youngs_modulus, poisson_ratio, density };
    m.validate().map_err(|e| bad("material", e))?;
    Ok(laparo_mpm::cfl_dt(&m, dx, cfl))
}
