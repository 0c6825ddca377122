"""Differentiable MLS-MPM (thesis §5.2.3–5.2.4): Neo-Hookean energy (eq. 5.3) with Lamé
parameters from (E, ν) (eq. 5.4), APIC P2G (5.6), G2P/advection (5.7), quadratic B-splines,
and exact reverse-mode gradients — the engine of RODS-MPM (eq. 5.10), whose unknowns are the
initial particle velocities.

>>> x0 = laparo.mpm.box_lattice([0.4, 0.4], [0.6, 0.5], 1/128)          # doctest: +SKIP
>>> scene = laparo.mpm.Scene(x0, particle_volume=(1/128)**2, youngs_modulus=5.0,
...                          poisson_ratio=0.3, n_grid=64, dt=2e-4, steps=50)  # doctest: +SKIP
>>> x_T = laparo.mpm.simulate(scene)["x"]                               # doctest: +SKIP

With PyTorch installed, :func:`simulate_torch` / :class:`MpmFunction` make x_T a differentiable
function of (v₀, E, ν) for torch optimisers. Registration (RODS-MPM): :mod:`laparo.register`.
"""
from __future__ import annotations

from typing import Any, Dict, Optional, Sequence

import numpy as np

from . import _laparo

Scene = _laparo.MpmScene
Scene.__doc__ = """An MPM scene in 2D or 3D.

Scene(positions (N, D) float64, particle_volume, youngs_modulus, poisson_ratio, density=1.0,
      n_grid=64, dx=None (1/n_grid: domain [0, 1]^D), dt=1e-4, steps=100, velocities=None,
      model="neo_hookean"|"fixed_corotated", walls="sticky"|"slip"|"none", wall_thickness=3,
      gravity=None, fixed=None (N,) bool, external_forces=None (N, D), crack_side=None (N,) in {-1, 0, 1})

``crack_side`` turns on the two-field grid of a pre-existing crack: particles of side −1 and +1 no longer
share node velocities across it (the lips of a zero-thickness cut can separate); 0 = coupled as usual.

Particle mass = density · particle_volume. ``with_state(velocities=, positions=,
youngs_modulus=, poisson_ratio=)`` returns a modified copy; ``simulate()`` and
``simulate_with_gradient(indices=, targets=)`` / ``(weights=)`` run it."""


def box_lattice(lo: Sequence[float], hi: Sequence[float], spacing: float) -> np.ndarray:
    """Particles on a regular lattice in the box [lo, hi] (2D or 3D), shape (N, D)."""
    return _laparo.mpm_box_lattice([float(v) for v in lo], [float(v) for v in hi], float(spacing))


def cfl_dt(youngs_modulus: float, poisson_ratio: float, density: float, dx: float, cfl: float = 0.3) -> float:
    """Δt giving CFL number ``cfl`` = c Δt / Δx with the P-wave speed c = sqrt((λ + 2μ)/ρ)."""
    return _laparo.mpm_cfl_dt(float(youngs_modulus), float(poisson_ratio), float(density), float(dx), float(cfl))


def simulate(scene: "Scene") -> Dict[str, Any]:
    """Run the scene's T steps: dict(x, v (N, D), C, F (N, D, D), warnings)."""
    return scene.simulate()


def simulate_with_gradient(
    scene: "Scene",
    indices: Optional[Sequence[int]] = None,
    targets: Optional[np.ndarray] = None,
    weights: Optional[np.ndarray] = None,
) -> Dict[str, Any]:
    """Simulate and differentiate a loss on the final positions x_T.

    * landmark loss (``indices``, ``targets`` (K, D)): L = (1/K) Σ_k sqrt(‖x_T[i_k] − t_k‖² + 1e-12),
      the RODS-MPM landmark term;
    * linear loss (``weights`` (N, D)): L = Σ weights · x_T (a vector-Jacobian product).

    Returns dict(loss, x, v, C, F, d_velocities, d_positions (N, D), d_youngs_modulus,
    d_poisson_ratio, d_mu, d_lambda, warnings).
    """
    if weights is not None:
        return scene.simulate_with_gradient(weights=np.ascontiguousarray(weights, dtype=np.float64))
    if indices is None or targets is None:
        raise ValueError("indices/targets: give indices and targets, or weights")
    return scene.simulate_with_gradient(indices=[int(i) for i in indices], targets=np.ascontiguousarray(targets, dtype=np.float64))


def landmark_loss_numpy(x: np.ndarray, indices: Sequence[int], targets: np.ndarray) -> float:
    """The landmark loss of :func:`simulate_with_gradient` on given positions (for checks)."""
    d = x[np.asarray(indices)] - targets
    return float(np.mean(np.sqrt((d * d).sum(axis=1) + 1e-12)))


_MPM_FUNCTION = None


def _torch() -> Any:
    try:
        import torch
    except Exception as e:  # pragma: no cover - exercised when torch is absent
        raise ImportError("laparo.mpm: PyTorch is required for simulate_torch / MpmFunction (pip install torch)") from e
    return torch


def _mpm_function() -> Any:
    """The ``torch.autograd.Function`` (built on first use so that ``import laparo`` does not import torch)."""
    global _MPM_FUNCTION
    if _MPM_FUNCTION is not None:
        return _MPM_FUNCTION
    torch = _torch()

    class MpmFunction(torch.autograd.Function):  # type: ignore[misc,name-defined]
        """x_T = MPM(v₀, E, ν) as a ``torch.autograd.Function``.

        ``MpmFunction.apply(velocities (N, D), youngs_modulus (), poisson_ratio (), scene)``.
        The backward pass runs the exact adjoint of the Rust simulator on the linear loss
        ⟨grad_output, x_T⟩, so ∂/∂v₀, ∂/∂E and ∂/∂ν are exact (float64 inside).
        """

        @staticmethod
        def forward(ctx: Any, velocities: Any, youngs_modulus: Any, poisson_ratio: Any, scene: Any) -> Any:  # type: ignore[override]
            v = velocities.detach().to("cpu", torch.float64).contiguous().numpy()
            s = scene.with_state(velocities=v, youngs_modulus=float(youngs_modulus), poisson_ratio=float(poisson_ratio))
            ctx.scene = s
            ctx.meta = (velocities.dtype, velocities.device, youngs_modulus, poisson_ratio)
            x = s.simulate()["x"]
            return torch.from_numpy(x).to(device=velocities.device, dtype=velocities.dtype)

        @staticmethod
        def backward(ctx: Any, grad_x: Any) -> Any:  # type: ignore[override]
            dtype, device, e, nu = ctx.meta
            g = grad_x.detach().to("cpu", torch.float64).contiguous().numpy()
            r = ctx.scene.simulate_with_gradient(weights=g)
            dv = torch.from_numpy(r["d_velocities"]).to(device=device, dtype=dtype)
            de = torch.tensor(r["d_youngs_modulus"], dtype=e.dtype, device=e.device).reshape(e.shape)
            dnu = torch.tensor(r["d_poisson_ratio"], dtype=nu.dtype, device=nu.device).reshape(nu.shape)
            return dv, de, dnu, None

    _MPM_FUNCTION = MpmFunction
    return MpmFunction


def __getattr__(name: str) -> Any:
    if name == "MpmFunction":
        return _mpm_function()
    raise AttributeError(f"module 'laparo.mpm' has no attribute {name!r}")


def simulate_torch(scene: "Scene", velocities: Any, youngs_modulus: Any = None, poisson_ratio: Any = None) -> Any:
    """Final positions x_T (N, D) as a differentiable function of the tensors ``velocities``
    (N, D), ``youngs_modulus`` and ``poisson_ratio`` (0-dim; default: the scene's, constant)
    through :class:`MpmFunction` (``laparo.mpm.MpmFunction``). Requires PyTorch."""
    t = _torch()
    e = youngs_modulus if youngs_modulus is not None else t.tensor(scene.youngs_modulus, dtype=t.float64)
    nu = poisson_ratio if poisson_ratio is not None else t.tensor(scene.poisson_ratio, dtype=t.float64)
    if not isinstance(e, t.Tensor):
        e = t.tensor(float(e), dtype=t.float64)
    if not isinstance(nu, t.Tensor):
        nu = t.tensor(float(nu), dtype=t.float64)
    return _mpm_function().apply(velocities, e, nu, scene)


def landmark_loss_torch(x: Any, indices: Sequence[int], targets: Any) -> Any:
    """The landmark loss of :func:`simulate_with_gradient` in torch. Requires PyTorch."""
    t = _torch()
    d = x[t.as_tensor(list(indices), dtype=t.long)] - targets
    return t.sqrt((d * d).sum(dim=1) + 1e-12).mean()
