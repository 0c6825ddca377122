"""laparo.register against the CLI (`laparo register`: particles_registered.ply, report.json) and
independent checks: the registration reduces the landmark distance, in-memory and file routes
agree, particles given as arrays reproduce the mesh route, errors name the argument."""
import json

import numpy as np
import pytest

import laparo
from conftest import cli_json  # noqa: F401

R = laparo.register
OPTS = dict(spacing_mm=4.0, steps=40, iterations=3)
CLI_OPTS = ["--spacing-mm", "4", "--steps", "40", "--iterations", "3"]
LANDMARKS = {"tip": [[39.0, 12.0, 8.0], [39.0, 4.0, 8.0]], "edge": [[20.0, 23.0, 8.0]]}
TARGETS = {"tip": [[42.0, 12.0, 8.0], [42.0, 4.0, 8.0]]}


def box_obj(path, lo, hi):
    v = [[hi[0] if i & 1 else lo[0], hi[1] if i & 2 else lo[1], hi[2] if i & 4 else lo[2]] for i in range(8)]
    s = "".join(f"v {a} {b} {c}\n" for a, b, c in v)
    for f in [[1, 3, 4, 2], [5, 6, 8, 7], [1, 2, 6, 5], [3, 7, 8, 4], [1, 5, 7, 3], [2, 4, 8, 6]]:
        s += f"f {f[0]} {f[1]} {f[2]}\nf {f[0]} {f[2]} {f[3]}\n"
    path.write_text(s)


def read_particles_ply(path):
    data = path.read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    return np.frombuffer(data[end:], dtype="<f8").reshape(-1, 7)


@pytest.fixture()
def job(tmp_path):
    box_obj(tmp_path / "organ.obj", [0.0, 0.0, 0.0], [40.0, 24.0, 16.0])
    (tmp_path / "L.json").write_text(json.dumps({"groups": [{"name": k, "points": v} for k, v in LANDMARKS.items()]}))
    (tmp_path / "T.json").write_text(json.dumps({"groups": [
        {"name": "tip", "type": "points", "points": TARGETS["tip"]},
        {"name": "edge", "type": "polyline", "points": [[0.0, 25.5, 8.0], [40.0, 25.5, 8.0]]},
    ]}))
    return tmp_path


def py_targets():
    return [
        {"name": "tip", "type": "points", "points": TARGETS["tip"]},
        {"name": "edge", "type": "polyline", "points": [[0.0, 25.5, 8.0], [40.0, 25.5, 8.0]]},
    ]


def test_register_equals_cli(cli, job):
    cli("register", "--organ", job / "organ.obj", "--landmarks", job / "L.json", "--target", job / "T.json",
        "--out", job / "cli", *CLI_OPTS)
    ref = read_particles_ply(job / "cli" / "particles_registered.ply")
    rest = read_particles_ply(job / "cli" / "particles_rest.ply")
    got = R.register(LANDMARKS, py_targets(), organ=job / "organ.obj", **OPTS)
    np.testing.assert_array_equal(got["positions"], ref[:, :3])
    np.testing.assert_array_equal(got["final_velocities"], ref[:, 3:6])
    np.testing.assert_array_equal(got["j"], ref[:, 6])
    np.testing.assert_array_equal(got["rest_positions"], rest[:, :3])
    np.testing.assert_array_equal(got["velocities"], rest[:, 3:6])
    rep = json.loads((job / "cli" / "report.json").read_text())
    assert list(got["mean_distance_mm"]) == rep["mean_distance_mm"]
    assert got["stop_reason"] == rep["stop_reason"] and got["dt_s"] == rep["dt_s"] and got["n_grid"] == rep["n_grid"]
    assert got["residual_after"] == rep["residual_after"]
    # The file route (the CLI's job from Python) writes the same particles and report.
    r2 = R.run(job / "organ.obj", job / "L.json", job / "T.json", job / "py", **OPTS)
    np.testing.assert_array_equal(read_particles_ply(job / "py" / "particles_registered.ply"), ref)
    timing = {"seconds_per_simulation", "optimisation_seconds", "peak_memory_mib", "organ", "outputs"}
    assert {k: v for k, v in r2.items() if k not in timing} == {k: v for k, v in rep.items() if k not in timing}


def test_registration_moves_landmarks_towards_targets(job):
    tg = TARGETS | {"edge": [[20.0, 25.5, 8.0]]}
    got = R.register(LANDMARKS, tg, organ=job / "organ.obj", **OPTS)
    before, after = got["mean_distance_mm"]
    # The thesis scores each landmark at its nearest rest particle (lattice at 2, 6, 10, … mm): the mean of
    # their distances to the targets (eq. 5.10, unsmoothed).
    rest = got["rest_positions"]
    d = []
    for name, pts in LANDMARKS.items():
        for p, t in zip(np.array(pts), np.array(tg[name])):
            near = rest[np.argmin(np.linalg.norm(rest - p, axis=1))]
            d.append(np.linalg.norm(near - t))
    # Scored at their own material points (the default), at rest each landmark is exactly where it was given.
    direct = [np.linalg.norm(np.array(p) - np.array(t)) for n in LANDMARKS for p, t in zip(LANDMARKS[n], tg[n])]
    assert before == pytest.approx(np.mean(direct), rel=1e-9)
    assert after < 0.8 * before
    thesis = R.register(LANDMARKS, tg, organ=job / "organ.obj", thesis_landmarks=True, **OPTS)
    assert thesis["mean_distance_mm"][0] == pytest.approx(np.mean(d), rel=1e-9)
    n = got["positions"].shape[0]
    assert n == 10 * 6 * 4 and got["velocities"].shape == (n, 3) and got["j"].shape == (n,)
    # Particles as arrays: the rest lattice of the mesh route gives the same registration.
    again = R.register(LANDMARKS, TARGETS | {"edge": [[20.0, 25.5, 8.0]]}, particles=got["rest_positions"], **OPTS)
    np.testing.assert_allclose(again["positions"], got["positions"], atol=1e-9)
    assert again["mean_distance_mm"][1] == pytest.approx(after, rel=1e-9)


def test_tear_preset_equals_cli(cli, job):
    """optimizer="tear" (and the preset's σ / step cap when not given) is the CLI's --optimizer tear."""
    cli("register", "--organ", job / "organ.obj", "--landmarks", job / "L.json", "--target", job / "T.json",
        "--out", job / "cli", "--optimizer", "tear", *CLI_OPTS)
    ref = read_particles_ply(job / "cli" / "particles_registered.ply")
    got = R.register(LANDMARKS, py_targets(), organ=job / "organ.obj", optimizer="tear", **OPTS)
    np.testing.assert_array_equal(got["positions"], ref[:, :3])
    # the explicit defaults of the lbfgs preset differ from tear's (σ 2 Δx vs 0): a different run
    other = R.register(LANDMARKS, py_targets(), organ=job / "organ.obj", optimizer="tear", smoothing_dx=2.0,
                       max_step_dx=0.5, **OPTS)
    assert not np.array_equal(other["positions"], got["positions"])
    with pytest.raises(ValueError, match="lbfgs, tear, adam, thesis-gd"):
        R.register(LANDMARKS, TARGETS, organ=job / "organ.obj", optimizer="sgd")


def test_register_errors_name_the_argument(job):
    with pytest.raises(ValueError, match="optimizer"):
        R.register(LANDMARKS, TARGETS, organ=job / "organ.obj", optimizer="sgd")
    with pytest.raises(ValueError, match="roi"):
        R.register(LANDMARKS, TARGETS, organ=job / "organ.obj", roi="sphere:1,2,3")
    with pytest.raises(ValueError, match="targets"):
        R.register(LANDMARKS, {"tip": TARGETS["tip"]}, organ=job / "organ.obj", **OPTS)
    with pytest.raises(ValueError, match="organ"):
        R.register(LANDMARKS, TARGETS)
    with pytest.raises(ValueError, match="particles"):
        R.register(LANDMARKS, TARGETS, particles=np.full((5, 3), np.nan))
    with pytest.raises(ValueError, match="landmarks"):
        R.register({"tip": [[1.0, 2.0]]}, TARGETS, organ=job / "organ.obj")
    with pytest.raises(ValueError, match="spacing_mm"):
        R.register(LANDMARKS, py_targets(), organ=job / "organ.obj", spacing_mm=float("nan"))
    with pytest.raises((OSError, ValueError), match="missing.obj"):
        R.run(job / "missing.obj", job / "L.json", job / "T.json", job / "o", **OPTS)


def test_crack_labels_sides_by_hand_and_lets_the_lips_separate(cli, job):
    """A plane x = 20 mm (normal +x) across the box: the particles within the band are labelled by side
    (counted here with numpy), and with both ends pulled apart the particles next to the plane jump across
    it, where one field keeps them together; the CLI's --crack gives the same registration."""
    lm = {"right": [[38.0, 12.0, 8.0], [38.0, 4.0, 8.0]], "left": [[2.0, 12.0, 8.0], [2.0, 4.0, 8.0]]}
    tg = {"right": [[42.0, 12.0, 8.0], [42.0, 4.0, 8.0]], "left": [[-2.0, 12.0, 8.0], [-2.0, 4.0, 8.0]]}
    plane = (np.array([[20.0, -5, -5], [20, 30, -5], [20, 30, 25], [20, -5, 25]]), np.array([[0, 1, 2], [0, 2, 3]]))
    opts = dict(OPTS, iterations=8)
    one = R.register(lm, tg, organ=job / "organ.obj", **opts)
    two = R.register(lm, tg, organ=job / "organ.obj", crack=plane, crack_band_mm=5.0, **opts)
    rest = two["rest_positions"]
    side = np.where(np.abs(rest[:, 0] - 20.0) <= 5.0, np.sign(rest[:, 0] - 20.0), 0).astype(np.int64)
    np.testing.assert_array_equal(two["crack_side"], side)
    assert two["crack"]["particles"] == [int((side == -1).sum()), int((side == 1).sum())]
    assert one["crack"] is None and one["crack_side"].shape == (0,)

    def jump(r):
        u = r["positions"][:, 0] - r["rest_positions"][:, 0]
        x = r["rest_positions"][:, 0]
        return u[(x > 20) & (x < 24)].mean() - u[(x > 16) & (x < 20)].mean()

    assert jump(two) > 2.0 and jump(two) > 3.0 * abs(jump(one)), (jump(one), jump(two))
    # the CLI with the same crack as a file
    (job / "crack.obj").write_text("".join(f"v {a} {b} {c}\n" for a, b, c in plane[0]) + "f 1 2 3\nf 1 3 4\n")
    (job / "L5.json").write_text(json.dumps({"groups": [{"name": k, "points": v} for k, v in lm.items()]}))
    (job / "T5.json").write_text(json.dumps({"groups": [{"name": k, "type": "points", "points": v} for k, v in tg.items()]}))
    cli("register", "--organ", job / "organ.obj", "--landmarks", job / "L5.json", "--target", job / "T5.json",
        "--out", job / "crack_cli", "--crack", job / "crack.obj", "--crack-band-mm", "5", *CLI_OPTS[:4], "--iterations", "8")
    ref = read_particles_ply(job / "crack_cli" / "particles_registered.ply")
    np.testing.assert_array_equal(two["positions"], ref[:, :3])
    # bad crack inputs name the argument
    with pytest.raises(ValueError, match="crack"):
        R.register(lm, tg, organ=job / "organ.obj", crack=(plane[0], np.array([[0, 1, 9]])), **opts)
    with pytest.raises(ValueError, match="misses the organ"):
        R.register(lm, tg, organ=job / "organ.obj", crack=(plane[0] + [100.0, 0, 0], plane[1]), **opts)
    with pytest.raises(ValueError, match="crack_band_mm"):
        R.register(lm, tg, organ=job / "organ.obj", crack_band_mm=3.0, **opts)


def test_at_rest_weight_leaves_less_kinetic_energy_at_the_end(job):
    # The at-rest prior λ Σ m |v_T T Δt|² / (2 M Δx) (ladder rung L2): uniform particle masses, so KE(T) / KE(0)
    # is Σ |v_T|² / Σ |v₀|², computed here from the returned arrays.
    tg = TARGETS | {"edge": [[20.0, 25.5, 8.0]]}
    opts = OPTS | dict(iterations=8)

    def ratio(got):
        return np.sum(got["final_velocities"] ** 2) / np.sum(got["velocities"] ** 2)

    free = R.register(LANDMARKS, tg, organ=job / "organ.obj", **opts)
    rest = R.register(LANDMARKS, tg, organ=job / "organ.obj", at_rest_weight=4.0, **opts)
    assert ratio(rest) < ratio(free)
    assert rest["mean_distance_mm"][1] < rest["mean_distance_mm"][0]
    with pytest.raises(ValueError, match="at_rest_weight"):
        R.register(LANDMARKS, tg, organ=job / "organ.obj", at_rest_weight=float("nan"), **opts)


def test_loads_on_a_cut_assumed_from_the_lip(cli, job):
    # Rung L3 from Python: the cut assumed from one lip (the ribbon: each lip point 2 mm above and 10 mm
    # below along the top face's normal -z), loads as the unknown. The loads are self-equilibrated (their
    # sum is 0), carried only by the particles the cut labels, the lips move towards their targets, and the
    # same run through the CLI writes the same particles.
    mid = [[12.0 + 4.0 * k, 12.0, 16.0] for k in range(5)]
    verts, faces = R.assumed_cut(job / "organ.obj", mid, 10.0)
    assert verts.shape == (10, 3) and faces.shape == (8, 3)
    np.testing.assert_allclose(verts[0::2], np.array(mid) + [0.0, 0.0, 2.0], atol=1e-12)
    np.testing.assert_allclose(verts[1::2], np.array(mid) - [0.0, 0.0, 10.0], atol=1e-12)
    lips = {"a": [[12.0 + 4.0 * k, 11.0, 16.0] for k in range(5)], "b": [[12.0 + 4.0 * k, 13.0, 16.0] for k in range(5)]}
    tg = [
        {"name": "a", "type": "polyline", "points": [[p[0], 9.0, 16.0] for p in lips["a"]]},
        {"name": "b", "type": "polyline", "points": [[p[0], 15.0, 16.0] for p in lips["b"]]},
    ]
    opts = dict(spacing_mm=2.0, steps=200, iterations=6)
    got = R.register(lips, tg, organ=job / "organ.obj", crack=(verts, faces), unknown="loads", **opts)
    f = got["loads"]
    np.testing.assert_allclose(f.sum(axis=0), 0.0, atol=1e-9 * np.abs(f).sum())
    assert np.all(np.abs(f[got["crack_side"] == 0]) == 0.0)
    assert np.all(got["velocities"] == 0.0), "loads start from rest"
    assert got["mean_distance_mm"][1] < 0.85 * got["mean_distance_mm"][0]
    with pytest.raises(ValueError, match="loads"):
        R.register(lips, tg, organ=job / "organ.obj", unknown="forces", **opts)
    with pytest.raises(ValueError, match="distinct point"):
        R.assumed_cut(job / "organ.obj", [mid[0]], 10.0)
    # the CLI's run: the same cut, the same particles
    (job / "L2.json").write_text(json.dumps({"groups": [{"name": k, "points": v} for k, v in lips.items()]}))
    (job / "T2.json").write_text(json.dumps({"groups": tg}))
    cut_ply = job / "cut.ply"
    with open(cut_ply, "w") as fh:
        fh.write("ply\nformat ascii 1.0\nelement vertex 10\nproperty double x\nproperty double y\nproperty double z\n"
                 "element face 8\nproperty list uchar int vertex_indices\nend_header\n")
        fh.writelines(f"{float(v[0])!r} {float(v[1])!r} {float(v[2])!r}\n" for v in verts)
        fh.writelines(f"3 {a} {b} {c}\n" for a, b, c in faces)
    cli("register", "--organ", job / "organ.obj", "--landmarks", job / "L2.json", "--target", job / "T2.json",
        "--out", job / "cli_l3", "--crack", cut_ply, "--unknown", "loads", "--spacing-mm", "2", "--steps", "200",
        "--iterations", "6")
    ref = read_particles_ply(job / "cli_l3" / "particles_registered.ply")
    np.testing.assert_array_equal(got["positions"], ref[:, :3])
