//! Time-step selection from the CFL condition of the material's P-wave speed.
use crate::scene::{Material, Scene};

/// Something the caller should know but that does not stop the simulation (libraries don't print).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub enum Warning {
    /// c Δt / Δx exceeds the scene's `cfl_limit`: explicit MPM may blow up.
    CflViolated {
        /// Configured Δt.
        dt: f64,
        /// c Δt / Δx with c = sqrt((λ + 2μ)/ρ).
        cfl_number: f64,
        /// The limit that was exceeded.
        limit: f64,
        /// Largest Δt within the limit.
        max_dt: f64,
    },
}

impl std::fmt::Display for Warning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Warning::CflViolated { dt, cfl_number, limit, max_dt } => write!(
                f,
                "dt = {dt:.3e} violates the CFL condition: c*dt/dx = {cfl_number:.3} > {limit} (use dt <= {max_dt:.3e})"
            ),
        }
    }
}

/// Δt = safety · Δx / c, c the P-wave speed sqrt((λ + 2μ)/ρ) (safety ≈ 0.2–0.4 for MLS-MPM).
pub fn cfl_dt(material: &Material, dx: f64, safety: f64) -> f64 {
    safety * dx / material.p_wave_speed()
}

/// CFL number c Δt / Δx of a scene.
pub fn cfl_number<const D: usize>(scene: &Scene<D>) -> f64 {
    scene.material.p_wave_speed() * scene.dt / scene.grid.dx
}

/// Warnings for a scene's time step.
pub fn check<const D: usize>(scene: &Scene<D>) -> Vec<Warning> {
    let cfl = cfl_number(scene);
    if cfl > scene.cfl_limit {
        vec![Warning::CflViolated {
            dt: scene.dt,
            cfl_number: cfl,
            limit: scene.cfl_limit,
            max_dt: cfl_dt(&scene.material, scene.grid.dx, scene.cfl_limit),
        }]
    } else {
        Vec::new()
    }
}
