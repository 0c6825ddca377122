"""laparo.stereo.match / self_rectify against the CLI (`stereo match`, `--self-rectify`) and
independent checks: SGM on synthetic pairs with a known disparity (either sign) and a known
vertical offset; self-rectification of a pair with a known small rotation."""
import json

import numpy as np
import pytest

import laparo
from conftest import read_pfm, write_png_gray_or_rgb

S = laparo.stereo


def texture(w, h, seed=0):
    """Random blocky texture with some smoothing (census-friendly, no repetition)."""
    rng = np.random.default_rng(seed)
    a = rng.random((h // 2 + 2, w // 2 + 2))
    a = np.kron(a, np.ones((2, 2)))
    k = np.ones(3) / 3
    a = np.apply_along_axis(lambda r: np.convolve(r, k, "same"), 1, a)
    return (30 + 200 * a).astype(np.uint8)


def shifted_pair(w=120, h=80, d=6, dy=0, seed=0):
    """left(x, y) = big(x + m, y + m), right(x, y) = big(x + m + d, y + m + dy): x_R = x_L − d."""
    m = 20
    big = texture(w + 2 * m, h + 2 * m, seed)
    left = big[m:m + h, m:m + w]
    right = big[m + dy:m + dy + h, m + d:m + d + w]
    return np.ascontiguousarray(left), np.ascontiguousarray(right)


@pytest.mark.parametrize("d", [6, -9])
def test_known_constant_disparity(d):
    left, right = shifted_pair(d=d)
    r = S.match(left, right, d_min=-16, d_max=16)
    disp = r["disparity"]
    assert disp.dtype == np.float32 and disp.shape == left.shape
    ok = np.isfinite(disp)
    assert ok.mean() > 0.7, ok.mean()
    inner = ok[:, 20:-20]
    assert np.median(np.abs(disp[:, 20:-20][inner] - d)) < 0.1
    assert (np.abs(disp[ok] - d) < 0.5).mean() > 0.95
    assert r["stats"]["n_valid"] == ok.sum()
    conf = r["confidence"]
    assert ((conf >= 0) & (conf <= 1)).all() and (conf[~ok] == 0).all()
    assert "dy" not in r


def test_vertical_tolerance_finds_the_row_offset():
    left, right = shifted_pair(d=5, dy=1, seed=2)
    r = S.match(left, right, d_min=0, d_max=16, vertical_tol=1)
    ok = np.isfinite(r["disparity"])
    assert ok.mean() > 0.6
    # right(x, y) = left(x + d, y + 1) → the match of left (x, y) is right (x − d, y − 1)
    assert (r["dy"][ok] == -1).mean() > 0.9, np.unique(r["dy"][ok], return_counts=True)
    assert (np.abs(r["disparity"][ok] - 5) < 0.5).mean() > 0.9
    assert np.isnan(r["dy"][~ok]).all()


def test_match_equals_cli(cli, tmp_path):
    left, right = shifted_pair(d=-7, dy=0, seed=4)
    rgb_l = np.stack([left, left // 2, 255 - left], -1)
    rgb_r = np.stack([right, right // 2, 255 - right], -1)
    write_png_gray_or_rgb(tmp_path / "l.png", rgb_l)
    write_png_gray_or_rgb(tmp_path / "r.png", rgb_r)
    cli("stereo", "match", "--left", tmp_path / "l.png", "--right", tmp_path / "r.png", "--range", "-12:4",
        "--mode", "accurate", "--vertical-tol", "1", "--p2", "80", "--uniqueness", "5", "--fill-holes",
        "--out", tmp_path / "o")
    got = S.match(rgb_l, rgb_r, -12, 4, mode="accurate", vertical_tol=1, p2=80, uniqueness=5, fill_holes=True)
    for name, key in [("disparity", "disparity"), ("confidence", "confidence"), ("dy", "dy")]:
        ref = read_pfm(tmp_path / "o" / f"{name}.pfm")
        np.testing.assert_array_equal(got[key], ref, err_msg=name)
    stats = json.loads((tmp_path / "o" / "stats.json").read_text())
    c = dict(stats["counts"])
    g = dict(got["stats"])
    assert g == c
    assert json.dumps(got["params"], sort_keys=True) == json.dumps(stats["params"], sort_keys=True)
    ok = np.isfinite(got["disparity_filled"])
    assert ok.sum() >= np.isfinite(got["disparity"]).sum()


def rotated_pair(w=256, h=192, d=8.0, angle_deg=0.8):
    """A non-planar scene seen by a near-rectified raw pair: right pixel (u, v) shows the left
    point R(u − c) + c + (d(u, v), 0) with a small in-plane rotation R and a smooth, non-affine
    disparity d = 8 ± 3 px (horizontal epipolar lines in the left image)."""
    big = texture(2 * w, 2 * h, seed=7).astype(np.float64)
    big = (big + np.roll(big, 1, 0) + np.roll(big, 1, 1)) / 3
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)

    def sample(x, y):
        x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
        ax, ay = x - x0, y - y0
        v = lambda i, j: big[np.clip(y0 + j, 0, 2 * h - 1), np.clip(x0 + i, 0, 2 * w - 1)]
        return (1 - ay) * ((1 - ax) * v(0, 0) + ax * v(1, 0)) + ay * ((1 - ax) * v(0, 1) + ax * v(1, 1))

    off = np.array([w / 2, h / 2])
    left = sample(xx + off[0], yy + off[1])
    a = np.radians(angle_deg)
    cx, cy = (w - 1) / 2, (h - 1) / 2
    # right pixel (u, v) shows the left scene point at R(u − c) + c + (d, 0)
    dd = d + 3.0 * np.sin(xx / 23.0) * np.cos(yy / 17.0)
    xr = np.cos(a) * (xx - cx) - np.sin(a) * (yy - cy) + cx + dd
    yr = np.sin(a) * (xx - cx) + np.cos(a) * (yy - cy) + cy
    right = sample(xr + off[0], yr + off[1])
    return left.clip(0, 255).astype(np.uint8), right.clip(0, 255).astype(np.uint8)


def test_self_rectify_reduces_vertical_offsets():
    left, right = rotated_pair()
    r = S.self_rectify(left, right)
    info = r["rectification"]
    assert info["n_inliers"] >= 20
    assert info["dy_rectified"]["median_abs"] < 0.5 < info["dy_raw"]["median_abs"] or info["dy_raw"]["median_abs"] < 0.5
    assert info["dy_rectified"]["median_abs"] < info["dy_raw"]["median_abs"]
    # The homographies map the inlier matches to equal rows (the definition of rectified).
    hl, hr = np.array(info["h_left"]), np.array(info["h_right"])
    inl = np.array(info["inliers"])
    pl = np.c_[r["points_left"][inl], np.ones(inl.sum())] @ hl.T
    pr = np.c_[r["points_right"][inl], np.ones(inl.sum())] @ hr.T
    dy = pr[:, 1] / pr[:, 2] - pl[:, 1] / pl[:, 2]
    assert np.median(np.abs(dy)) < 0.5
    # the canvas holds both rectified images whole: at least the input size, the size reported
    cw, ch = info["rectified_size"]
    assert r["left"].shape[:2] == (ch, cw) == r["right"].shape[:2] and r["valid_left"].dtype == np.bool_
    assert cw >= left.shape[1] and ch >= left.shape[0]
    assert r["valid_left"].sum() >= 0.99 * left.shape[0] * left.shape[1]
    # Given points instead of SIFT: same result.
    r2 = S.self_rectify(left, right, points_left=r["points_left"], points_right=r["points_right"])
    assert r2["rectification"] == info


def test_self_rectified_match_equals_cli(cli, tmp_path):
    left, right = rotated_pair()
    write_png_gray_or_rgb(tmp_path / "l.png", left)
    write_png_gray_or_rgb(tmp_path / "r.png", right)
    cli("stereo", "match", "--left", tmp_path / "l.png", "--right", tmp_path / "r.png", "--range", "-4:20",
        "--self-rectify", "--out", tmp_path / "o")
    got = S.match(left, right, -4, 20, self_rectify=True)
    for name in ["disparity", "confidence", "dy"]:
        np.testing.assert_array_equal(got[name], read_pfm(tmp_path / "o" / f"{name}.pfm"), err_msg=name)
    np.testing.assert_array_equal(got["disparity_rectified"], read_pfm(tmp_path / "o" / "disparity_rectified.pfm"))
    info = json.loads((tmp_path / "o" / "self_rectification.json").read_text())
    assert got["rectified_range_px"] == tuple(info["rectified_range_px"])
    assert json.dumps(got["rectification"], sort_keys=True) == json.dumps(info["rectification"], sort_keys=True)
    # Raw disparity against the scene: the right pixel u of left pixel x solves (to first order
    # in the 0.8° rotation a) x = u − a (y − c_y) + d(u, y), by fixed-point iteration.
    h, w = left.shape
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    a, cy = np.radians(0.8), (h - 1) / 2
    u = xx - 8.0
    for _ in range(20):
        u = xx + a * (yy - cy) - (8.0 + 3.0 * np.sin(u / 23.0) * np.cos(yy / 17.0))
    truth = xx - u
    d = got["disparity"]
    ok = np.isfinite(d)
    ok[:, :30] = False  # left border: no match in the right view
    assert ok.mean() > 0.5
    err = np.abs(d[ok] - truth[ok])
    assert np.median(err) < 0.5 and (err > 2.0).mean() < 0.05, (np.median(err), (err > 2.0).mean())


def test_match_errors_name_the_argument():
    l, r = shifted_pair()
    with pytest.raises(ValueError, match="d_max"):
        S.match(l, r, 5, 5)
    with pytest.raises(ValueError, match="mode"):
        S.match(l, r, 0, 16, mode="fast")
    with pytest.raises(ValueError, match="right"):
        S.match(l, r[:-1], 0, 16)
    with pytest.raises(TypeError, match="left"):
        S.match(l.astype(np.float32), r, 0, 16)
    with pytest.raises(ValueError, match="vertical"):
        S.match(l, r, 0, 16, vertical_tol=20)
    with pytest.raises(ValueError, match="points_left"):
        S.self_rectify(l, r, points_left=np.zeros((30, 2)))
    with pytest.raises(ValueError, match="method"):
        S.self_rectify(l, r, method="bouguet")
