"""laparo.mpm against `laparo mpm simulate` (PLY frames), finite differences, and torch
(gradcheck in float64; an optimisation loop equal to gradient descent on the Rust gradients)."""
import struct

import numpy as np
import pytest

import laparo
from conftest import HAVE_TORCH, needs_torch


def read_ply(path):
    data = path.read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    n = int([l for l in data[:end].decode().splitlines() if l.startswith("element vertex")][0].split()[-1])
    a = np.frombuffer(data, dtype="<f8", count=7 * n, offset=end).reshape(n, 7)
    return a[:, :3], a[:, 3:6]


def test_simulate_equals_cli_3d(cli, tmp_path):
    toml = """dim = 3
gravity = [0.0, 0.0, -2.0]
[grid]
n_grid = 16
dx = 0.0625
[material]
model = "neo_hookean"
youngs_modulus = 40.0
poisson_ratio = 0.3
density = 1.0
[time]
steps = 30
dt = 0.002
[[body]]
shape = "box"
lo = [0.35, 0.35, 0.3]
hi = [0.6, 0.55, 0.5]
spacing = 0.03125
velocity = [0.1, 0.0, 0.0]
stretch_rate = [0.5, -0.2, 0.0]
"""
    (tmp_path / "s.toml").write_text(toml)
    cli("mpm", "simulate", "--scene", tmp_path / "s.toml", "--out", tmp_path / "out", "--every", "30")
    x0, v0 = read_ply(tmp_path / "out" / "frame_00000.ply")
    xT, vT = read_ply(tmp_path / "out" / "frame_00030.ply")
    scene = laparo.mpm.Scene(
        np.ascontiguousarray(x0), particle_volume=0.03125 ** 3, youngs_modulus=40.0, poisson_ratio=0.3, density=1.0,
        n_grid=16, dx=0.0625, dt=0.002, steps=30, velocities=np.ascontiguousarray(v0), gravity=[0.0, 0.0, -2.0],
    )
    r = laparo.mpm.simulate(scene)
    np.testing.assert_array_equal(r["x"], xT)
    np.testing.assert_array_equal(r["v"], vT)
    assert not np.array_equal(xT, x0)


def small_scene(steps=15):
    x0 = laparo.mpm.box_lattice([0.4, 0.4], [0.56, 0.5], 1.0 / 64)
    n = len(x0)
    c = x0.mean(axis=0)
    v0 = np.ascontiguousarray(np.stack([1.0 * (x0[:, 0] - c[0]), -0.5 * (x0[:, 1] - c[1])], axis=1))
    dt = laparo.mpm.cfl_dt(5.0, 0.3, 1.0, 1.0 / 32, 0.3)
    scene = laparo.mpm.Scene(x0, particle_volume=(1.0 / 64) ** 2, youngs_modulus=5.0, poisson_ratio=0.3, n_grid=32,
                             dt=dt, steps=steps, velocities=v0)
    return scene, n


def test_gradient_matches_finite_differences():
    scene, n = small_scene()
    idx = [0, n // 2, n - 1]
    tgt = scene.positions[idx] + np.array([[0.01, 0.0], [0.0, -0.01], [-0.005, 0.004]])
    g = laparo.mpm.simulate_with_gradient(scene, idx, tgt)
    assert abs(g["loss"] - laparo.mpm.landmark_loss_numpy(g["x"], idx, tgt)) < 1e-15
    h = 1e-6

    def loss(**kw):
        return laparo.mpm.simulate_with_gradient(scene.with_state(**kw), idx, tgt)["loss"]

    v = scene.velocities
    for p, d in [(0, 0), (n // 2, 1), (n - 1, 0), (3, 1)]:
        vp, vm = v.copy(), v.copy()
        vp[p, d] += h
        vm[p, d] -= h
        fd = (loss(velocities=vp) - loss(velocities=vm)) / (2 * h)
        assert abs(fd - g["d_velocities"][p, d]) <= 1e-5 * max(abs(fd), 1e-3), (p, d, fd, g["d_velocities"][p, d])
    for name, key, x in [("youngs_modulus", "d_youngs_modulus", 5.0), ("poisson_ratio", "d_poisson_ratio", 0.3)]:
        fd = (loss(**{name: x + h}) - loss(**{name: x - h})) / (2 * h)
        assert abs(fd - g[key]) <= 1e-5 * max(abs(fd), 1e-4), (name, fd, g[key])


def test_linear_loss_is_the_vjp_of_the_landmark_loss():
    scene, n = small_scene()
    idx = [1, 5]
    tgt = scene.positions[idx] + 0.01
    g = laparo.mpm.simulate_with_gradient(scene, idx, tgt)
    # dL/dx_T of the landmark loss, then the linear loss with those weights: same dL/dv0.
    x = g["x"]
    w = np.zeros_like(x)
    for i, t in zip(idx, tgt):
        d = x[i] - t
        w[i] += d / (np.sqrt(d @ d + 1e-12) * len(idx))
    lin = laparo.mpm.simulate_with_gradient(scene, weights=w)
    assert abs(lin["loss"] - float((w * x).sum())) <= 1e-14
    np.testing.assert_allclose(lin["d_velocities"], g["d_velocities"], rtol=1e-12, atol=1e-14)
    assert abs(lin["d_youngs_modulus"] - g["d_youngs_modulus"]) <= 1e-12 * abs(g["d_youngs_modulus"])


def test_errors_name_the_argument():
    x0 = laparo.mpm.box_lattice([0.4, 0.4], [0.5, 0.5], 1 / 64)
    kw = dict(particle_volume=1e-4, youngs_modulus=5.0, poisson_ratio=0.3, n_grid=32, dt=1e-4, steps=2)
    bad = x0.copy()
    bad[0, 0] = np.nan
    with pytest.raises(ValueError, match="positions"):
        laparo.mpm.Scene(bad, **kw)
    with pytest.raises(ValueError, match="positions"):
        laparo.mpm.Scene(np.zeros((4, 4)), **kw)
    with pytest.raises(TypeError, match="positions"):
        laparo.mpm.Scene(x0.astype(np.int64), **kw)
    with pytest.raises(ValueError, match="velocities"):
        laparo.mpm.Scene(x0, velocities=np.zeros((3, 2)), **kw)
    with pytest.raises(ValueError, match="material"):
        laparo.mpm.Scene(x0, **{**kw, "poisson_ratio": 0.5})
    with pytest.raises(ValueError, match="dt"):
        laparo.mpm.Scene(x0, **{**kw, "dt": -1.0})
    with pytest.raises(ValueError, match="fixed"):
        laparo.mpm.Scene(x0, fixed=np.zeros(3, dtype=bool), **kw)
    with pytest.raises(ValueError, match="scene"):
        laparo.mpm.Scene(x0 + 5.0, **kw)  # outside the grid
    s = laparo.mpm.Scene(x0, **kw)
    with pytest.raises(ValueError, match="indices"):
        laparo.mpm.simulate_with_gradient(s, [len(x0)], np.zeros((1, 2)))
    with pytest.raises(ValueError, match="targets"):
        laparo.mpm.simulate_with_gradient(s, [0], np.zeros((2, 2)))
    with pytest.raises(ValueError, match="weights"):
        laparo.mpm.simulate_with_gradient(s, weights=np.zeros((2, 2)))
    with pytest.raises(ValueError, match="velocities"):
        s.with_state(velocities=np.full_like(x0, np.inf))


@needs_torch
def test_torch_gradcheck_float64():
    import torch

    scene, n = small_scene(steps=10)
    v = torch.tensor(scene.velocities, dtype=torch.float64, requires_grad=True)
    e = torch.tensor(5.0, dtype=torch.float64, requires_grad=True)
    nu = torch.tensor(0.3, dtype=torch.float64, requires_grad=True)
    f = lambda v, e, nu: laparo.mpm.simulate_torch(scene, v, e, nu)
    assert torch.autograd.gradcheck(f, (v, e, nu), eps=1e-6, atol=1e-6, rtol=1e-4)
    # The forward value is the Rust simulation.
    np.testing.assert_array_equal(f(v, e, nu).detach().numpy(), laparo.mpm.simulate(scene)["x"])


@needs_torch
def test_torch_optimisation_equals_gradient_descent_on_rust_gradients():
    import torch

    scene, n = small_scene(steps=15)
    idx = [0, n // 3, n - 1]
    tgt_np = scene.positions[idx] + np.array([[-0.02, 0.01], [0.0, 0.015], [0.02, -0.01]])
    tgt = torch.tensor(tgt_np)
    lr = 40.0
    # torch: SGD on v0 through the autograd Function.
    v = torch.tensor(scene.velocities, requires_grad=True)
    opt = torch.optim.SGD([v], lr=lr)
    torch_losses = []
    for _ in range(8):
        opt.zero_grad()
        loss = laparo.mpm.landmark_loss_torch(laparo.mpm.simulate_torch(scene, v), idx, tgt)
        loss.backward()
        torch_losses.append(loss.item())
        opt.step()
    # NumPy: the same loop on the Rust landmark gradient.
    vn = scene.velocities
    np_losses = []
    for _ in range(8):
        g = laparo.mpm.simulate_with_gradient(scene.with_state(velocities=vn), idx, tgt_np)
        np_losses.append(g["loss"])
        vn = vn - lr * g["d_velocities"]
    np.testing.assert_allclose(torch_losses, np_losses, rtol=1e-10)
    np.testing.assert_allclose(v.detach().numpy(), vn, rtol=1e-9, atol=1e-12)
    assert all(b < a for a, b in zip(torch_losses, torch_losses[1:])), torch_losses
    assert torch_losses[-1] < 0.7 * torch_losses[0], torch_losses


def test_two_field_crack_lets_the_lips_translate_apart():
    """Two lips of a block cut at x = 0.5 moving apart at ±v: with crack_side they translate rigidly
    (x_T = x0 ± v T Δt to round-off); without it they share grid nodes and do not."""
    x0 = laparo.mpm.box_lattice([0.5 - 3 / 32, 0.5 - 3 / 32], [0.5 + 3 / 32, 0.5 + 3 / 32], 1 / 64)
    side = np.where(x0[:, 0] < 0.5, -1, 1)
    v0 = np.zeros_like(x0)
    v0[:, 0] = 0.3 * side
    kw = dict(particle_volume=(1 / 64) ** 2, youngs_modulus=3.0, poisson_ratio=0.3, n_grid=32, dt=2e-4, steps=40,
              velocities=v0, walls="none")
    want = x0 + v0 * 40 * 2e-4
    two = laparo.mpm.Scene(x0, crack_side=side, **kw).simulate()["x"]
    one = laparo.mpm.Scene(x0, **kw).simulate()["x"]
    assert np.abs(two - want).max() < 1e-12
    assert np.abs(one - want).max() > 0.1 * 0.3 * 40 * 2e-4
    with pytest.raises(ValueError, match="crack_side"):
        laparo.mpm.Scene(x0, crack_side=np.full(len(x0), 2), **kw)
    with pytest.raises(ValueError, match="crack_side"):
        laparo.mpm.Scene(x0, crack_side=side[:-1], **kw)
