"""laparo.cpc against `laparo cpc warp` (images, maps, stats), point mapping round trips, errors."""
import json

import numpy as np
import pytest

import laparo
from conftest import read_png, write_png_gray_or_rgb

W, H = 64, 48
K = np.array([[70.0, 0.0, 31.5], [0.0, 70.0, 23.5], [0.0, 0.0, 1.0]])


def frame():
    """A textured plane tilted by 50° about the x axis plus a bump, seen by K (depth in mm)."""
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float64)
    yn = (yy - K[1, 2]) / K[1, 1]
    t = np.tan(np.radians(50.0))
    z = 60.0 / (1.0 - t * yn)  # plane z = 60 + t·y  (y = yn z)
    z *= 1.0 + 0.03 * np.exp(-((xx - 40) ** 2 + (yy - 20) ** 2) / 60.0)
    img = (127 + 80 * np.sin(xx / 3.0) * np.cos(yy / 2.5)).clip(0, 255).astype(np.uint8)
    img = np.stack([img, img[:, ::-1], 255 - img], axis=-1)
    mask = np.ones((H, W), dtype=bool)
    mask[:3] = False
    return np.ascontiguousarray(img), z, mask


def run_cli(cli, tmp_path, img, z, mask, extra=()):
    write_png_gray_or_rgb(tmp_path / "img.png", img)
    np.save(tmp_path / "depth.npy", z)
    write_png_gray_or_rgb(tmp_path / "mask.png", mask.astype(np.uint8) * 255)
    (tmp_path / "k.json").write_text(json.dumps({"fx": K[0, 0], "fy": K[1, 1], "cx": K[0, 2], "cy": K[1, 2]}))
    out = tmp_path / "out"
    cli("cpc", "warp", "--image", tmp_path / "img.png", "--depth", tmp_path / "depth.npy", "--depth-unit", "mm",
        "--intrinsics", tmp_path / "k.json", "--mask", tmp_path / "mask.png", "--out", out, *extra)
    return out


def compare_stats(got, ref):
    for k in ["inputs", "maps", "timings_ms"]:
        ref.pop(k, None)
        got.pop(k, None)
    assert json.dumps(got, sort_keys=True) == json.dumps(ref, sort_keys=True)


@pytest.mark.parametrize("lam", [None, 0.8, "auto"])
def test_warp_equals_cli(cli, tmp_path, lam):
    img, z, mask = frame()
    extra = () if lam is None else (("--auto-lambda",) if lam == "auto" else ("--lambda", str(lam)))
    out = run_cli(cli, tmp_path, img, z, mask, extra)
    r = laparo.cpc.warp(img, z, K, mask, lam=lam)
    np.testing.assert_array_equal(r.warped, read_png(out / "warped.png"))
    np.testing.assert_array_equal(r.mask, read_png(out / "mask.png") > 0)
    back, fwd = r.maps()
    np.testing.assert_array_equal(back.astype(np.float32), np.load(out / "map_backward.npy"))
    np.testing.assert_array_equal(fwd.astype(np.float32), np.load(out / "map_forward.npy"))
    compare_stats(dict(r.stats), json.loads((out / "stats.json").read_text()))
    if lam == "auto":
        assert r.sweep is not None and 0.0 <= r.lam < 1.0
    elif lam is not None:
        assert r.lam == lam


def test_point_mapping_round_trip_and_maps():
    img, z, mask = frame()
    r = laparo.cpc.warp(img, z, K, mask)
    back, fwd = r.maps()
    pts = np.array([[10.0, 10.0], [32.5, 24.25], [50.0, 40.0], [-5.0, 3.0]])
    w = r.original_to_warped(pts)
    assert np.isnan(w[3]).all()  # outside the image
    o = r.warped_to_original(w[:3])
    np.testing.assert_allclose(o, pts[:3], atol=1e-9)
    # Dense forward map at integer pixels = point mapping.
    np.testing.assert_array_equal(r.original_to_warped(np.array([[20.0, 30.0]]))[0], fwd[30, 20])
    # A single point (2,) works too.
    assert r.original_to_warped(np.array([20.0, 30.0])).shape == (2,)
    assert r.warp.canvas_size == (r.warped.shape[1], r.warped.shape[0])


def test_errors_name_the_argument():
    img, z, mask = frame()
    with pytest.raises(ValueError, match="k"):
        laparo.cpc.warp(img, z, np.full((3, 3), np.nan), mask)
    with pytest.raises(ValueError, match="k"):
        laparo.cpc.warp(img, z, np.eye(4), mask)
    with pytest.raises(ValueError, match="depth"):
        laparo.cpc.warp(img, z[:-1].copy(), K, mask)
    with pytest.raises(ValueError, match="depth"):
        zz = z.copy()
        zz[0, 0] = np.inf
        laparo.cpc.warp(img, zz, K, mask)
    with pytest.raises(TypeError, match="image"):
        laparo.cpc.warp(img.astype(np.float64), z, K, mask)
    with pytest.raises(ValueError, match="lam"):
        laparo.cpc.warp(img, z, K, mask, lam=1.5)
    with pytest.raises(ValueError, match="lam"):
        laparo.cpc.warp(img, z, K, mask, lam="best")
    with pytest.raises(ValueError, match="mask"):
        laparo.cpc.warp(img, z, K, mask[:, 1:].copy())
    with pytest.raises(ValueError, match="depth_unit"):
        laparo.cpc.warp(img, z, K, mask, depth_unit="cm")
    r = laparo.cpc.warp(img, z, K, mask)
    with pytest.raises(ValueError, match="points"):
        r.warp.original_to_warped(np.zeros((3, 3)))
