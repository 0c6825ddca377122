//! Forward simulation (`simulate`): P2G → grid update → G2P per step.
use crate::cfl;
use crate::constitutive::ConstitutiveModel;
use crate::error::MpmError;
use crate::error::Warning;
use crate::linalg::{det, vee_antisym, Matrix, Vector};
use crate::scene::{Model, Scene};
use crate::sparse_grid::SparseGrid;
use crate::{fixed_corotated::FixedCorotated, g2p, grid_update, neo_hookean::NeoHookean, p2g};

/// Per-particle state at one step: position x, velocity v, APIC affine matrix C, deformation gradient F.
#[derive(Clone, Debug)]
pub struct ParticleState<const D: usize> {
    /// Positions.
    pub x: Vec<Vector<D>>,
    /// Velocities.
    pub v: Vec<Vector<D>>,
    /// Affine velocity matrices C.
    pub c: Vec<Matrix<D>>,
    /// Deformation gradients F.
    pub f: Vec<Matrix<D>>,
}

impl<const D: usize> ParticleState<D> {
    /// The initial state of a scene (F = I).
    pub fn initial(scene: &Scene<D>) -> Self {
        let n = scene.n_particles();
        ParticleState {
            x: scene.positions.clone(),
            v: scene.velocities.clone(),
            c: if scene.affine.is_empty() { vec![Matrix::<D>::zeros(); n] } else { scene.affine.clone() },
            f: if scene.initial_deformation.is_empty() {
                vec![Matrix::<D>::identity(); n]
            } else {
                scene.initial_deformation.clone()
            },
        }
    }
    /// Overwrite with the initial state of a scene (as [`Self::initial`], reusing the buffers).
    pub fn set_initial(&mut self, scene: &Scene<D>) {
        let n = scene.n_particles();
        self.x.clone_from(&scene.positions);
        self.v.clone_from(&scene.velocities);
        if scene.affine.is_empty() {
            self.c.clear();
            self.c.resize(n, Matrix::<D>::zeros());
        } else {
            self.c.clone_from(&scene.affine);
        }
        if scene.initial_deformation.is_empty() {
            self.f.clear();
            self.f.resize(n, Matrix::<D>::identity());
        } else {
            self.f.clone_from(&scene.initial_deformation);
        }
    }
    fn zeros(n: usize) -> Self {
        ParticleState {
            x: vec![Vector::<D>::zeros(); n],
            v: vec![Vector::<D>::zeros(); n],
            c: vec![Matrix::<D>::zeros(); n],
            f: vec![Matrix::<D>::zeros(); n],
        }
    }
}

/// Result of [`simulate`].
#[derive(Clone, Debug)]
pub struct Simulation<const D: usize> {
    /// State after the last step.
    pub final_state: ParticleState<D>,
    /// Non-fatal warnings (CFL).
    pub warnings: Vec<Warning>,
}

/// Reusable buffers of one time step.
pub(crate) struct Stepper<const D: usize> {
    pub grid: SparseGrid<D>,
    pub affine: Vec<Matrix<D>>,
    /// Block keys of the current positions (written by the previous step's G2P) …
    keys: Vec<u32>,
    /// … when valid (false before the first step).
    keys_valid: bool,
}

impl<const D: usize> Stepper<D> {
    pub fn new(scene: &Scene<D>) -> Self {
        let mut grid = SparseGrid::new(scene.grid);
        grid.two_field = !scene.crack_side.is_empty();
        Stepper { grid, affine: Vec::new(), keys: Vec::new(), keys_valid: false }
    }

    /// Forget the block keys of the last step's output: the next step starts from another state (the
    /// adjoint recomputing a checkpoint segment).
    pub fn restart(&mut self) {
        self.keys_valid = false;
    }

    /// One full step `cur` → `next`: sparse-grid build (in parallel with the F update and stress of
    /// P2G, which do not need the grid), P2G scatter, grid update, G2P. `cur` must be the `next` of
    /// the previous call, if any (its block keys were computed by that call's G2P).
    pub fn step<M: ConstitutiveModel<D>>(
        &mut self,
        model: &M,
        scene: &Scene<D>,
        cur: &ParticleState<D>,
        next: &mut ParticleState<D>,
        s: usize,
    ) -> Result<(), MpmError> {
        let (mu, la) = scene.material.lame();
        let n = cur.x.len();
        if !self.keys_valid {
            let keyer = self.grid.keyer();
            self.keys.clear();
            self.keys.extend(cur.x.iter().map(|x| keyer.key(x)));
        }
        self.keys_valid = false;
        let Stepper { grid, affine, keys, .. } = self;
        let (built, stressed) = rayon::join(
            || grid.build_from_keys(keys, s),
            || p2g::stress(model, mu, la, scene, &cur.c, &cur.f, &mut next.f, affine, s),
        );
        built?;
        stressed?;
        p2g::crack_sides(grid, scene, &cur.x);
        p2g::scatter(grid, scene, &cur.x, &cur.v, affine);
        grid_update::update(grid, scene);
        keys.resize(n, 0);
        g2p::gather(grid, scene, &cur.x, &mut next.x, &mut next.v, &mut next.c, keys, s)?;
        self.keys_valid = true;
        Ok(())
    }
}

/// Run the scene to its horizon; returns the final state.
/// (On a worker of the current rayon pool, see [`crate::simulate_with_gradient_in`].)
pub fn simulate<const D: usize>(scene: &Scene<D>) -> Result<Simulation<D>, MpmError> {
    laparo_core::par::on_pool(|| simulate_observed(scene, |_, _| Ok(())))
}

/// Run the scene, calling `observer(step, state)` on the initial state (step 0) and after every step;
/// an error from the observer stops the run.
pub fn simulate_observed<const D: usize>(
    scene: &Scene<D>,
    observer: impl FnMut(usize, &ParticleState<D>) -> Result<(), MpmError>,
) -> Result<Simulation<D>, MpmError> {
    scene.validate()?;
    match scene.material.model {
        Model::NeoHookean => run(&NeoHookean, scene, observer),
        Model::FixedCorotated => run(&FixedCorotated, scene, observer),
    }
}

fn run<const D: usize, M: ConstitutiveModel<D>>(
    model: &M,
    scene: &Scene<D>,
    mut observer: impl FnMut(usize, &ParticleState<D>) -> Result<(), MpmError>,
) -> Result<Simulation<D>, MpmError> {
    let mut cur = ParticleState::initial(scene);
    let mut next = ParticleState::zeros(scene.n_particles());
    let mut stepper = Stepper::new(scene);
    observer(0, &cur)?;
    for s in 0..scene.steps {
        stepper.step(model, scene, &cur, &mut next, s)?;
        std::mem::swap(&mut cur, &mut next);
        observer(s + 1, &cur)?;
    }
    Ok(Simulation { final_state: cur, warnings: cfl::cfl_warnings(scene) })
}

/// Conserved quantities and energies of a particle state.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Diagnostics {
    /// Σ ½ m |v|².
    pub kinetic_energy: f64,
    /// Σ V ψ(F).
    pub elastic_energy: f64,
    /// Σ m v (first D entries used).
    pub linear_momentum: [f64; 3],
    /// APIC angular momentum Σ m (x × v + Δx²/4 axial(C − Cᵀ)) (2D: only entry 2 used).
    pub angular_momentum: [f64; 3],
    /// min J over particles.
    pub min_j: f64,
}

/// Energies and momenta of `state` (APIC angular momentum includes the affine part, Jiang et al. 2015).
pub fn diagnostics<const D: usize>(scene: &Scene<D>, state: &ParticleState<D>) -> Diagnostics {
    let (mu, la) = scene.material.lame();
    let dxx = scene.grid.dx * scene.grid.dx / 4.0;
    let mut d = Diagnostics {
        kinetic_energy: 0.0,
        elastic_energy: 0.0,
        linear_momentum: [0.0; 3],
        angular_momentum: [0.0; 3],
        min_j: f64::INFINITY,
    };
    for p in 0..state.x.len() {
        let m = scene.masses[p];
        let (x, v, c, f) = (state.x[p], state.v[p], state.c[p], state.f[p]);
        d.kinetic_energy += 0.5 * m * v.norm_squared();
        d.elastic_energy += scene.volumes[p]
            * match scene.material.model {
                Model::NeoHookean => <NeoHookean as ConstitutiveModel<D>>::energy_density(&NeoHookean, &f, mu, la),
                Model::FixedCorotated => {
                    <FixedCorotated as ConstitutiveModel<D>>::energy_density(&FixedCorotated, &f, mu, la)
                }
            };
        for k in 0..D {
            d.linear_momentum[k] += m * v[k];
        }
        let a = vee_antisym(&c);
        if D == 2 {
            d.angular_momentum[2] += m * (x[0] * v[1] - x[1] * v[0] + dxx * a[0]);
        } else {
            d.angular_momentum[0] += m * (x[1] * v[2] - x[2] * v[1] + dxx * a[0]);
            d.angular_momentum[1] += m * (x[2] * v[0] - x[0] * v[2] + dxx * a[1]);
            d.angular_momentum[2] += m * (x[0] * v[1] - x[1] * v[0] + dxx * a[2]);
        }
        d.min_j = d.min_j.min(det(&f));
    }
    d
}
