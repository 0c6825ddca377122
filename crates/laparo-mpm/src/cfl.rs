//! Time-step selection from the CFL condition of the material's P-wave speed.
use crate::error::Warning;
use crate::scene::{Material, Scene};

/// Δt = safety · Δx / c, c the P-wave speed sqrt((λ + 2μ)/ρ) (safety ≈ 0.2–0.4 for MLS-MPM).
pub fn cfl_dt(material: &Material, dx: f64, safety: f64) -> f64 {
    safety * dx / material.p_wave_speed()
}

/// CFL number c Δt / Δx of a scene.
pub fn cfl_number<const D: usize>(scene: &Scene<D>) -> f64 {
    scene.material.p_wave_speed() * scene.dt / scene.grid.dx
}

/// Warnings for a scene's time step ([`Warning::CflViolated`] when c Δt / Δx > `scene.cfl_limit`).
pub fn cfl_warnings<const D: usize>(scene: &Scene<D>) -> Vec<Warning> {
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
