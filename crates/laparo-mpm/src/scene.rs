//! The simulation scene: particles, material, background grid, boundary conditions, time stepping.
use crate::constitutive::lame;
use crate::error::MpmError;
use crate::grid_spec::GridSpec;
use crate::linalg::{Matrix, Vector};

/// Constitutive model of the body.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Model {
    /// Compressible Neo-Hookean (eq. 5.3), the thesis' choice.
    NeoHookean,
    /// Fixed-corotated (Stomakhin et al. 2012).
    FixedCorotated,
}

/// Homogeneous elastic material.
#[derive(Clone, Copy, Debug, serde::Serialize, serde::Deserialize)]
pub struct Material {
    /// Constitutive model.
    pub model: Model,
    /// Young's modulus E (stress units, e.g. kPa), > 0.
    pub youngs_modulus: f64,
    /// Poisson's ratio ν ∈ (−1, 0.5).
    pub poisson_ratio: f64,
    /// Mass density ρ (mass per volume), > 0; used for the P-wave speed of the CFL condition.
    pub density: f64,
}

impl Material {
    /// Lamé parameters (μ, λ) (eq. 5.4).
    pub fn lame(&self) -> (f64, f64) {
        lame(self.youngs_modulus, self.poisson_ratio)
    }
    /// P-wave speed c = sqrt((λ + 2μ)/ρ).
    pub fn p_wave_speed(&self) -> f64 {
        let (mu, la) = self.lame();
        ((la + 2.0 * mu) / self.density).sqrt()
    }
    /// Validate E > 0, −1 < ν < 0.5, ρ > 0.
    pub fn validate(&self) -> Result<(), MpmError> {
        let bad = |name: &str, value: f64, reason: &str| {
            Err(MpmError::InvalidParameter { name: name.into(), value, reason: reason.into() })
        };
        if !(self.youngs_modulus > 0.0 && self.youngs_modulus.is_finite()) {
            return bad("youngs_modulus", self.youngs_modulus, "Young's modulus E must be finite and > 0");
        }
        if !(self.poisson_ratio > -1.0 && self.poisson_ratio < 0.5) {
            return bad("poisson_ratio", self.poisson_ratio, "Poisson's ratio must satisfy -1 < nu < 0.5");
        }
        if !(self.density > 0.0 && self.density.is_finite()) {
            return bad("density", self.density, "density must be finite and > 0");
        }
        Ok(())
    }
}

/// Behaviour of the domain walls (grid nodes within `Boundary::thickness` cells of a face).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum WallKind {
    /// A node moving into the wall stops completely (DiffTaichi's `grid_op`).
    Sticky,
    /// A node moving into the wall loses only its normal velocity component.
    Slip,
    /// No walls: particles leaving the grid are an error.
    None,
}

/// Domain walls.
#[derive(Clone, Copy, Debug, serde::Serialize, serde::Deserialize)]
pub struct Boundary {
    /// Wall behaviour.
    pub walls: WallKind,
    /// Node layers treated as wall: nodes with index < thickness or > n_grid − thickness (DiffTaichi: 3).
    pub thickness: usize,
}

impl Default for Boundary {
    fn default() -> Self {
        Boundary { walls: WallKind::Sticky, thickness: 3 }
    }
}

/// A complete MPM problem in D = 2 or 3 dimensions.
///
/// The time step follows eqs. 5.6–5.7 with APIC/MLS transfers and quadratic B-splines exactly as in
/// DiffTaichi's `diffmpm` (see the crate README).
#[derive(Clone, Debug)]
pub struct Scene<const D: usize> {
    /// Initial particle positions x₀ (length units; inside the grid domain).
    pub positions: Vec<Vector<D>>,
    /// Initial particle velocities v₀ (length / time).
    pub velocities: Vec<Vector<D>>,
    /// Initial affine velocity matrices C₀ (APIC); empty = zero.
    pub affine: Vec<Matrix<D>>,
    /// Initial deformation gradients F₀ (e.g. a pre-stretched body); empty = identity.
    pub initial_deformation: Vec<Matrix<D>>,
    /// Particle masses m_p.
    pub masses: Vec<f64>,
    /// Particle reference volumes V_p.
    pub volumes: Vec<f64>,
    /// Material.
    pub material: Material,
    /// Background grid.
    pub grid: GridSpec,
    /// Domain walls.
    pub boundary: Boundary,
    /// Gravity acceleration (added to grid velocities).
    pub gravity: Vector<D>,
    /// Fixed particles (attached tissue): they keep their position; empty = none.
    pub fixed: Vec<bool>,
    /// Constant external force per particle (force units), spread to the grid; empty = none.
    pub external_forces: Vec<Vector<D>>,
    /// Side of a pre-existing crack per particle (−1, 0 or +1; empty = no crack): the **two-field
    /// grid** (CRAMP, Nairn 2003; cf. CPIC, Hu et al. 2018). Each node takes the sign of Σ_p w_ip m_p
    /// side_p as its own side; a particle of the other side scatters to and gathers from a second
    /// velocity field of that node, so the two lips of a zero-thickness cut move independently while
    /// side-0 particles (beyond the crack front, or far from it) couple both sides as usual.
    pub crack_side: Vec<i8>,
    /// Mass-proportional (Rayleigh α) damping ζ (1/time; 0 = none): every step the grid velocities are
    /// divided by 1 + ζ Δt before gravity (implicit, stable for any ζ), so a constant load settles to
    /// equilibrium. Differentiated exactly.
    pub damping: f64,
    /// Time step Δt.
    pub dt: f64,
    /// Horizon T (number of steps).
    pub steps: usize,
    /// ε in v_i = p_i / (m_i + ε) (DiffTaichi uses 1e-10 in its normalised units; 0 = exact division on
    /// nodes with mass).
    pub mass_epsilon: f64,
    /// CFL number above which [`crate::cfl_warnings`] warns (c Δt / Δx).
    pub cfl_limit: f64,
    /// Steps per adjoint checkpoint segment (0 or 1: every step's state and grid are kept, the fastest).
    /// k > 1 keeps every k-th step's particle state and recomputes each segment in the reverse pass:
    /// memory for about ⌈T/k⌉ + k steps instead of T, one more forward pass, the same gradient bit for bit.
    /// [`checkpoint_segment_for`](crate::checkpoint_segment_for) picks k for a memory budget.
    pub checkpoint_segment: usize,
}

impl<const D: usize> Scene<D> {
    /// A scene with particles at `positions`, each of volume `particle_volume` and mass ρ·V, zero
    /// initial velocity, sticky walls of thickness 3, no gravity, ε = 0.
    pub fn new(
        positions: Vec<Vector<D>>,
        particle_volume: f64,
        material: Material,
        grid: GridSpec,
        dt: f64,
        steps: usize,
    ) -> Self {
        let n = positions.len();
        Scene {
            velocities: vec![Vector::<D>::zeros(); n],
            affine: Vec::new(),
            initial_deformation: Vec::new(),
            masses: vec![material.density * particle_volume; n],
            volumes: vec![particle_volume; n],
            positions,
            material,
            grid,
            boundary: Boundary::default(),
            gravity: Vector::<D>::zeros(),
            fixed: Vec::new(),
            external_forces: Vec::new(),
            crack_side: Vec::new(),
            damping: 0.0,
            dt,
            steps,
            mass_epsilon: 0.0,
            cfl_limit: 0.5,
            checkpoint_segment: 0,
        }
    }

    /// Number of particles.
    pub fn n_particles(&self) -> usize {
        self.positions.len()
    }

    /// Check everything a simulation relies on; errors name the offending parameter / particle.
    pub fn validate(&self) -> Result<(), MpmError> {
        if !(D == 2 || D == 3) {
            return Err(MpmError::InvalidScene(format!("dimension {D} is not supported (2 or 3)")));
        }
        let n = self.positions.len();
        if n == 0 {
            return Err(MpmError::NoParticles);
        }
        self.material.validate()?;
        let len = |name: &str, got: usize, allow_empty: bool| {
            if got == n || (allow_empty && got == 0) {
                Ok(())
            } else {
                Err(MpmError::LengthMismatch { name: name.into(), expected: n, got })
            }
        };
        len("velocities", self.velocities.len(), false)?;
        len("affine", self.affine.len(), true)?;
        len("initial_deformation", self.initial_deformation.len(), true)?;
        len("masses", self.masses.len(), false)?;
        len("volumes", self.volumes.len(), false)?;
        len("fixed", self.fixed.len(), true)?;
        len("external_forces", self.external_forces.len(), true)?;
        len("crack_side", self.crack_side.len(), true)?;
        if !(self.damping >= 0.0 && self.damping.is_finite()) {
            return Err(MpmError::InvalidScene(format!("damping {} must be finite and >= 0", self.damping)));
        }
        if let Some(p) = self.crack_side.iter().position(|s| !(-1..=1).contains(s)) {
            return Err(MpmError::InvalidScene(format!(
                "particle {p}: crack_side {} must be -1, 0 or +1",
                self.crack_side[p]
            )));
        }
        if self.grid.n_grid < 4 || !(self.grid.dx > 0.0 && self.grid.dx.is_finite()) {
            return Err(MpmError::InvalidScene(format!(
                "grid needs n_grid >= 4 and dx > 0 (got n_grid = {}, dx = {})",
                self.grid.n_grid, self.grid.dx
            )));
        }
        // Block keys are u32 (u32::MAX marks "outside") and node coordinates i32.
        let blocks_per_axis = self.grid.n_grid.div_ceil(crate::sparse_grid::BLOCK) as f64;
        if blocks_per_axis.powi(D as i32) >= u32::MAX as f64 || !(1.0 / self.grid.dx).is_finite() {
            return Err(MpmError::InvalidScene(format!(
                "grid too large or too fine: n_grid = {} ({}D), dx = {:e}",
                self.grid.n_grid, D, self.grid.dx
            )));
        }
        if self.boundary.thickness > self.grid.n_grid / 2 {
            return Err(MpmError::InvalidParameter {
                name: "boundary.thickness".into(),
                value: self.boundary.thickness as f64,
                reason: format!("must be <= n_grid/2 = {}", self.grid.n_grid / 2),
            });
        }
        if !self.gravity.iter().all(|g| g.is_finite()) {
            return Err(MpmError::InvalidScene(format!("gravity {:?} is not finite", self.gravity.as_slice())));
        }
        if !(self.dt > 0.0 && self.dt.is_finite()) {
            return Err(MpmError::InvalidParameter {
                name: "dt".into(),
                value: self.dt,
                reason: "dt must be > 0".into(),
            });
        }
        if !(self.mass_epsilon >= 0.0 && self.mass_epsilon.is_finite()) {
            return Err(MpmError::InvalidParameter {
                name: "mass_epsilon".into(),
                value: self.mass_epsilon,
                reason: "must be >= 0".into(),
            });
        }
        for p in 0..n {
            if self.masses[p] <= 0.0 || !self.masses[p].is_finite() {
                return Err(MpmError::InvalidScene(format!("particle {p}: mass {} must be > 0", self.masses[p])));
            }
            if self.volumes[p] <= 0.0 || !self.volumes[p].is_finite() {
                return Err(MpmError::InvalidScene(format!("particle {p}: volume {} must be > 0", self.volumes[p])));
            }
            if !self.velocities[p].iter().all(|v| v.is_finite()) {
                return Err(MpmError::InvalidScene(format!("particle {p}: non-finite initial velocity")));
            }
            if let Some(f) = self.external_forces.get(p) {
                if !f.iter().all(|v| v.is_finite()) {
                    return Err(MpmError::InvalidScene(format!("particle {p}: non-finite external force")));
                }
            }
            if let Some(c) = self.affine.get(p) {
                if !c.iter().all(|v| v.is_finite()) {
                    return Err(MpmError::InvalidScene(format!("particle {p}: non-finite affine matrix C")));
                }
            }
            if let Some(f) = self.initial_deformation.get(p) {
                if !(crate::linalg::det(f) > 0.0) {
                    return Err(MpmError::InvalidScene(format!("particle {p}: initial deformation has det <= 0")));
                }
            }
            self.grid.stencil_base(&self.positions[p]).ok_or(MpmError::OutsideDomain { particle: p, step: 0 })?;
        }
        Ok(())
    }

    pub(crate) fn is_fixed(&self, p: usize) -> bool {
        !self.fixed.is_empty() && self.fixed[p]
    }

    /// Crack side of particle p as f64 (0 without a crack).
    #[inline(always)]
    pub(crate) fn crack_label(&self, p: usize) -> f64 {
        if self.crack_side.is_empty() {
            0.0
        } else {
            self.crack_side[p] as f64
        }
    }
}

/// Particles on a regular lattice filling the axis-aligned box [lo, hi] with spacing `spacing`
/// (cell-centred: the first particle sits at lo + spacing/2, as in DiffTaichi's scripts).
pub fn box_lattice<const D: usize>(lo: Vector<D>, hi: Vector<D>, spacing: f64) -> Vec<Vector<D>> {
    lattice_where(lo, hi, spacing, |_| true)
}

/// Particles on the lattice of `box_lattice(lo, hi, spacing)` that satisfy `inside`.
pub fn lattice_where<const D: usize>(
    lo: Vector<D>,
    hi: Vector<D>,
    spacing: f64,
    inside: impl Fn(&Vector<D>) -> bool,
) -> Vec<Vector<D>> {
    let mut counts = [0usize; D];
    for d in 0..D {
        counts[d] = ((hi[d] - lo[d]) / spacing + 1e-9).floor().max(0.0) as usize;
    }
    let total: usize = counts.iter().product();
    let mut out = Vec::with_capacity(total);
    // Row-major with the last axis fastest (DiffTaichi's particle numbering).
    for lin in 0..total {
        let mut rem = lin;
        let mut p = Vector::<D>::zeros();
        for d in (0..D).rev() {
            let i = rem % counts[d];
            rem /= counts[d];
            p[d] = lo[d] + (i as f64 + 0.5) * spacing;
        }
        if inside(&p) {
            out.push(p);
        }
    }
    out
}

/// Particles on a lattice inside the ellipsoid (ellipse) with `center` and semi-axes `radii`.
pub fn ellipsoid_lattice<const D: usize>(center: Vector<D>, radii: Vector<D>, spacing: f64) -> Vec<Vector<D>> {
    lattice_where(center - radii, center + radii, spacing, |p| {
        (0..D).map(|d| ((p[d] - center[d]) / radii[d]).powi(2)).sum::<f64>() <= 1.0
    })
}
