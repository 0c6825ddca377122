"""Optimise the initial velocities (and Young's modulus) of an MPM scene with a torch optimiser
so that landmark particles reach target positions after T steps — the RODS-MPM idea (thesis
eq. 5.10) on a small 2D body. The simulation and its exact gradients run in Rust.

    python examples/python/mpm_torch_optimise.py
"""
import numpy as np
import torch

import laparo


def main():
    x0 = laparo.mpm.box_lattice([0.35, 0.4], [0.65, 0.5], 1 / 128)
    n = len(x0)
    dt = laparo.mpm.cfl_dt(20.0, 0.3, 1.0, 1 / 64, 0.3)
    scene = laparo.mpm.Scene(x0, particle_volume=(1 / 128) ** 2, youngs_modulus=20.0, poisson_ratio=0.3,
                             n_grid=64, dt=dt, steps=60)
    # Landmarks: the four corners of the block; targets: the block stretched and lifted.
    corners = [int(np.argmin(x0 @ s)) for s in ([1, 1], [-1, 1], [1, -1], [-1, -1])]
    targets = torch.tensor(x0[corners] + [[-0.01, 0.01], [0.01, 0.01], [-0.01, 0.015], [0.01, 0.015]])
    v = torch.zeros((n, 2), dtype=torch.float64, requires_grad=True)
    log_e = torch.tensor(np.log(20.0), dtype=torch.float64, requires_grad=True)
    opt = torch.optim.Adam([{"params": [v], "lr": 0.02}, {"params": [log_e], "lr": 0.05}])
    for it in range(40):
        opt.zero_grad()
        x_t = laparo.mpm.simulate_torch(scene, v, torch.exp(log_e))
        loss = laparo.mpm.landmark_loss_torch(x_t, corners, targets)
        loss.backward()
        opt.step()
        if it % 5 == 0 or it == 39:
            print(f"iteration {it:2d}: landmark loss {loss.item():.2e} (domain units, side 1), E = {torch.exp(log_e).item():.2f}")


if __name__ == "__main__":
    main()
