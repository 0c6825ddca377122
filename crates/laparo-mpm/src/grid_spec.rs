//! The background grid of a scene: cell count, cell width and the stencil base node of a particle.
use crate::linalg::Vector;

/// Background grid: `n_grid` cells of size `dx` per axis, domain [0, n_grid·dx]^D, nodes at i·dx.
#[derive(Clone, Copy, Debug, serde::Serialize, serde::Deserialize)]
pub struct GridSpec {
    /// Number of cells per axis.
    pub n_grid: usize,
    /// Cell width Δx (length units).
    pub dx: f64,
}

impl GridSpec {
    /// A grid of `n_grid` cells covering [0, 1]^D (DiffTaichi's normalised domain).
    pub fn unit(n_grid: usize) -> Self {
        GridSpec { n_grid, dx: 1.0 / n_grid as f64 }
    }
    /// Domain side length n_grid·Δx.
    pub fn extent(&self) -> f64 {
        self.n_grid as f64 * self.dx
    }

    /// Stencil base node of a particle: floor(x/Δx − 0.5) per axis, or `None` when the 3-node stencil
    /// is not inside the grid (nodes 0..n_grid−1).
    #[inline(always)]
    pub fn stencil_base<const D: usize>(&self, x: &Vector<D>) -> Option<[i32; D]> {
        let inv_dx = 1.0 / self.dx;
        let mut b = [0i32; D];
        for d in 0..D {
            let q = x[d] * inv_dx - 0.5;
            if !(q >= 0.0 && q < (self.n_grid as f64 - 2.0)) {
                return None;
            }
            b[d] = q as i32;
        }
        Some(b)
    }
}
