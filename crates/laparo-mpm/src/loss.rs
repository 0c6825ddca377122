//! Scalar losses on particle positions for [`crate::simulate_with_gradient`].
use crate::linalg::Vector;

/// A differentiable loss on particle positions, observed after some steps (by default the last).
pub trait Loss<const D: usize>: Sync {
    /// Whether the loss depends on the positions after step `step` (0 = initial, `n_steps` = final).
    fn observes(&self, step: usize, n_steps: usize) -> bool {
        step == n_steps
    }
    /// The loss term of step `step`; adds ∂L/∂x_p into `grad` (same length as `x`).
    fn evaluate(&self, step: usize, x: &[Vector<D>], grad: &mut [Vector<D>]) -> f64;
    /// A term on the final particle velocities v_T (e.g. a terminal kinetic energy); adds ∂L/∂v_T,p into
    /// `grad` (the adjoint's terminal condition v̄_T). Default: none.
    fn terminal_velocity(&self, _v: &[Vector<D>], _grad: &mut [Vector<D>]) -> f64 {
        0.0
    }
}

/// Mean Euclidean landmark-to-target distance at the final step, (1/K) Σ_k sqrt(‖x_{l_k} − t_k‖² + 1e-12)
/// (the loss of the DiffTaichi reference scripts and of RODS-MPM landmarks).
#[derive(Clone, Debug)]
pub struct LandmarkLoss<const D: usize> {
    /// Landmark particle indices.
    pub indices: Vec<usize>,
    /// Target positions, one per landmark.
    pub targets: Vec<Vector<D>>,
}

impl<const D: usize> Loss<D> for LandmarkLoss<D> {
    fn evaluate(&self, _step: usize, x: &[Vector<D>], grad: &mut [Vector<D>]) -> f64 {
        let k = self.indices.len().max(1) as f64;
        let mut total = 0.0;
        for (&p, t) in self.indices.iter().zip(&self.targets) {
            let d = x[p] - t;
            let r = (d.norm_squared() + 1e-12).sqrt();
            total += r / k;
            grad[p] += d / (r * k);
        }
        total
    }
}

/// Any closure `f(x, grad) -> value` on the final positions as a loss.
pub struct FinalLoss<F>(pub F);

impl<const D: usize, F> Loss<D> for FinalLoss<F>
where
    F: Fn(&[Vector<D>], &mut [Vector<D>]) -> f64 + Sync,
{
    fn evaluate(&self, _step: usize, x: &[Vector<D>], grad: &mut [Vector<D>]) -> f64 {
        (self.0)(x, grad)
    }
}

/// A closure `f(step, x, grad) -> value` observed at every step in `steps` (intermediate losses).
pub struct StepsLoss<F> {
    /// Steps at which the loss is evaluated.
    pub steps: Vec<usize>,
    /// The loss term.
    pub f: F,
}

impl<const D: usize, F> Loss<D> for StepsLoss<F>
where
    F: Fn(usize, &[Vector<D>], &mut [Vector<D>]) -> f64 + Sync,
{
    fn observes(&self, step: usize, _n_steps: usize) -> bool {
        self.steps.contains(&step)
    }
    fn evaluate(&self, step: usize, x: &[Vector<D>], grad: &mut [Vector<D>]) -> f64 {
        (self.f)(step, x, grad)
    }
}
