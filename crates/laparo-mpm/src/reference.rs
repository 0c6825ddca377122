//! Fixtures dumped from the DiffTaichi reference scripts (`scripts/check_mpm_taichi.sh`) and the
//! comparison of laparo-mpm against them.
use crate::error::MpmError;
use crate::grid_spec::GridSpec;
use crate::linalg::Vector;
use crate::loss::LandmarkLoss;
use crate::scene::{Boundary, Material, Model, Scene, WallKind};
use crate::simulate_with_gradient;

/// One DiffTaichi run: scene parameters, initial particles, final positions, loss and ∂L/∂v₀.
#[derive(Clone, Debug, serde::Deserialize, serde::Serialize)]
pub struct TaichiFixture {
    /// Script that produced it.
    pub source: String,
    /// 2 or 3.
    pub dim: usize,
    /// Cells per axis of the unit domain.
    pub n_grid: usize,
    /// Δt.
    pub dt: f64,
    /// T.
    pub steps: usize,
    /// E.
    pub youngs_modulus: f64,
    /// ν.
    pub poisson_ratio: f64,
    /// ρ.
    pub density: f64,
    /// Gravity magnitude (along −y in 2D, −z in 3D).
    pub gravity: f64,
    /// V_p.
    pub particle_volume: f64,
    /// m_p.
    pub particle_mass: f64,
    /// Wall thickness in nodes.
    pub bound: usize,
    /// x₀.
    pub positions: Vec<Vec<f64>>,
    /// v₀.
    pub velocities: Vec<Vec<f64>>,
    /// Landmark particle indices.
    pub landmarks: Vec<usize>,
    /// Landmark targets.
    pub targets: Vec<Vec<f64>>,
    /// x_T from DiffTaichi.
    pub final_positions: Vec<Vec<f64>>,
    /// Loss from DiffTaichi.
    pub loss: f64,
    /// ∂L/∂v₀ from DiffTaichi's autodiff.
    pub grad_velocities: Vec<Vec<f64>>,
}

/// Agreement between laparo-mpm and a DiffTaichi fixture.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Comparison {
    /// Particles.
    pub particles: usize,
    /// max_p ‖x_laparo − x_taichi‖ / Δx.
    pub max_position_diff_cells: f64,
    /// |L_laparo − L_taichi| / |L_taichi|.
    pub loss_rel_diff: f64,
    /// ‖g_laparo − g_taichi‖ / ‖g_taichi‖ over all particles.
    pub grad_rel_diff: f64,
    /// max_p ‖g_laparo,p − g_taichi,p‖ / max_p ‖g_taichi,p‖.
    pub grad_max_rel_diff: f64,
}

fn vecs<const D: usize>(v: &[Vec<f64>], name: &str) -> Result<Vec<Vector<D>>, MpmError> {
    v.iter()
        .map(|r| {
            if r.len() == D {
                Ok(Vector::<D>::from_fn(|i, _| r[i]))
            } else {
                Err(MpmError::InvalidScene(format!("fixture {name}: entry of length {} (dim {D})", r.len())))
            }
        })
        .collect()
}

impl TaichiFixture {
    /// The same scene in laparo-mpm (sticky walls of `bound` nodes, ε = 1e-10 as in the scripts).
    pub fn scene<const D: usize>(&self) -> Result<Scene<D>, MpmError> {
        if self.dim != D {
            return Err(MpmError::InvalidScene(format!("fixture is {}D, asked for {D}D", self.dim)));
        }
        let material = Material {
            model: Model::NeoHookean,
            youngs_modulus: self.youngs_modulus,
            poisson_ratio: self.poisson_ratio,
            density: self.density,
        };
        let mut scene = Scene::new(
            vecs::<D>(&self.positions, "positions")?,
            self.particle_volume,
            material,
            GridSpec::unit(self.n_grid),
            self.dt,
            self.steps,
        );
        scene.velocities = vecs::<D>(&self.velocities, "velocities")?;
        scene.masses = vec![self.particle_mass; scene.n_particles()];
        scene.boundary = Boundary { walls: WallKind::Sticky, thickness: self.bound };
        scene.gravity[D - 1] = -self.gravity;
        scene.mass_epsilon = 1e-10;
        Ok(scene)
    }

    /// The scripts' loss: mean landmark-to-target distance.
    pub fn loss<const D: usize>(&self) -> Result<LandmarkLoss<D>, MpmError> {
        Ok(LandmarkLoss { indices: self.landmarks.clone(), targets: vecs::<D>(&self.targets, "targets")? })
    }

    /// Run laparo-mpm on the fixture's scene and compare.
    pub fn compare<const D: usize>(&self) -> Result<Comparison, MpmError> {
        let scene = self.scene::<D>()?;
        let g = simulate_with_gradient(&scene, &self.loss::<D>()?)?;
        let xt = vecs::<D>(&self.final_positions, "final_positions")?;
        let gt = vecs::<D>(&self.grad_velocities, "grad_velocities")?;
        let dx = scene.grid.dx;
        let max_pos = g.final_state.x.iter().zip(&xt).map(|(a, b)| (a - b).norm() / dx).fold(0.0, f64::max);
        let (mut num, mut den, mut max_d, mut max_g) = (0.0, 0.0, 0.0f64, 0.0f64);
        for (a, b) in g.d_velocities.iter().zip(&gt) {
            num += (a - b).norm_squared();
            den += b.norm_squared();
            max_d = max_d.max((a - b).norm());
            max_g = max_g.max(b.norm());
        }
        Ok(Comparison {
            particles: scene.n_particles(),
            max_position_diff_cells: max_pos,
            loss_rel_diff: (g.loss - self.loss).abs() / self.loss.abs(),
            grad_rel_diff: (num / den).sqrt(),
            grad_max_rel_diff: max_d / max_g,
        })
    }
}

/// The RODS box problem of the DiffTaichi scripts (`mpm2d_rods.py` / `mpm3d_rods.py`): a lattice of
/// `counts` particles at spacing Δx/2 centred in the unit domain, E = 4.1, ν = 0.49, ρ = 1, sticky
/// walls of 3 nodes, ε = 1e-10, and the landmark loss pulling the two "lips" apart by ±0.01 in x.
/// Initial velocities: the smooth stretching/shearing field of `scripts/check_mpm_taichi.sh`.
pub fn rods_scene<const D: usize>(
    counts: [usize; D],
    n_grid: usize,
    steps: usize,
    dt: f64,
) -> (Scene<D>, LandmarkLoss<D>) {
    let grid = GridSpec::unit(n_grid);
    let spacing = grid.dx / 2.0;
    let lo = Vector::<D>::from_fn(|d, _| 0.5 - counts[d] as f64 * spacing / 2.0);
    let hi = Vector::<D>::from_fn(|d, _| lo[d] + counts[d] as f64 * spacing);
    let pos = crate::scene::box_lattice(lo, hi, spacing);
    let material = Material { model: Model::NeoHookean, youngs_modulus: 4.1, poisson_ratio: 0.49, density: 1.0 };
    let mut scene = Scene::new(pos, spacing.powi(D as i32), material, grid, dt, steps);
    scene.mass_epsilon = 1e-10;
    let n = scene.n_particles() as f64;
    let c = scene.positions.iter().fold(Vector::<D>::zeros(), |a, b| a + b) / n;
    for p in 0..scene.positions.len() {
        let r = scene.positions[p] - c;
        let mut v = Vector::<D>::zeros();
        v[0] = 8.0 * r[0] + 2.0 * r[1];
        v[1] = -3.0 * r[0] + 0.3 * (40.0 * r[0]).sin();
        if D == 3 {
            v[2] = 1.5 * r[1] - 2.0 * r[2];
        }
        scene.velocities[p] = v;
    }
    let (nx, ny) = (counts[0], counts[1]);
    let nl = 25.min(ny);
    let (il, ir) = (nx / 2 - 1, nx / 2);
    let pidx = |i: usize, j: usize| if D == 2 { i * ny + j } else { (i * ny + j) * counts[D - 1] + counts[D - 1] - 1 };
    let js: Vec<usize> = (0..nl).map(|q| if D == 2 { ny - 1 - q } else { q * ny / nl }).collect();
    let mut indices: Vec<usize> = js.iter().map(|&j| pidx(il, j)).collect();
    indices.extend(js.iter().map(|&j| pidx(ir, j)));
    let targets = indices
        .iter()
        .enumerate()
        .map(|(k, &p)| {
            let mut t = scene.positions[p];
            t[0] += if k < nl { -0.01 } else { 0.01 };
            t
        })
        .collect();
    (scene, LandmarkLoss { indices, targets })
}
