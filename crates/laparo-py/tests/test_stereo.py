"""laparo.stereo against the CLI (`stereo rectify`, `stereo eval --json`) and closed forms."""
import json

import numpy as np
import pytest

import laparo
from conftest import cli_json, read_png, write_png_gray_or_rgb

W, H = 40, 30


def calib_dict():
    k = np.array([[60.0, 0.0, 19.5], [0.0, 61.0, 14.2], [0.0, 0.0, 1.0]])
    kr = np.array([[60.5, 0.0, 21.0], [0.0, 61.2, 14.9], [0.0, 0.0, 1.0]])
    c, s = np.cos(0.01), np.sin(0.01)
    r = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]]) @ np.array([[1, 0, 0], [0, np.cos(0.005), -np.sin(0.005)], [0, np.sin(0.005), np.cos(0.005)]])
    return {
        "width": W, "height": H, "k_left": k, "k_right": kr, "dist_left": np.array([0.01, -0.002, 0.0, 0.0, 0.0]),
        "dist_right": np.zeros(5), "r": np.ascontiguousarray(r), "t_mm": np.array([-4.5, 0.05, 0.1]),
    }


def write_calib(path, c):
    path.write_text(json.dumps({
        "width": c["width"], "height": c["height"],
        "left": {"K": c["k_left"].tolist(), "dist": c["dist_left"].tolist()},
        "right": {"K": c["k_right"].tolist(), "dist": c["dist_right"].tolist()},
        "R": c["r"].tolist(), "T_mm": c["t_mm"].tolist(),
    }))


def test_read_calibration_round_trip(tmp_path):
    c = calib_dict()
    write_calib(tmp_path / "c.json", c)
    r = laparo.stereo.read_calibration(tmp_path / "c.json")
    for k in ["k_left", "k_right", "dist_left", "dist_right", "r", "t_mm"]:
        np.testing.assert_array_equal(r[k], c[k], err_msg=k)


def test_rectify_equals_cli(cli, tmp_path):
    c = calib_dict()
    write_calib(tmp_path / "c.json", c)
    rng = np.random.default_rng(0)
    left = rng.integers(0, 256, size=(H, W, 3), dtype=np.uint8)
    right = rng.integers(0, 256, size=(H, W, 3), dtype=np.uint8)
    write_png_gray_or_rgb(tmp_path / "l.png", left)
    write_png_gray_or_rgb(tmp_path / "r.png", right)
    cli("stereo", "rectify", "--calib", tmp_path / "c.json", "--left", tmp_path / "l.png", "--right", tmp_path / "r.png",
        "--out", tmp_path / "out")
    got = laparo.stereo.rectify(left, right, c)
    np.testing.assert_array_equal(got["left"], read_png(tmp_path / "out" / "left_rectified.png"))
    np.testing.assert_array_equal(got["right"], read_png(tmp_path / "out" / "right_rectified.png"))
    np.testing.assert_array_equal(got["valid_left"], read_png(tmp_path / "out" / "left_valid.png") > 0)
    info = json.loads((tmp_path / "out" / "rectification.json").read_text())
    assert json.dumps(got["info"], sort_keys=True) == json.dumps(info, sort_keys=True)


def test_disparity_depth_closed_form_and_round_trip():
    d = np.array([[10.0, 20.0], [-5.0, np.nan]])
    z = laparo.stereo.disparity_to_depth(d, f_px=500.0, baseline_mm=4.0, cx_left=300.0, cx_right=310.0)
    # z = f b / (d - (cxL - cxR)) = 2000 / (d + 10)
    np.testing.assert_array_equal(z[0], [2000.0 / 20.0, 2000.0 / 30.0])
    assert z[1, 0] == 2000.0 / 5.0 and np.isnan(z[1, 1])
    back = laparo.stereo.depth_to_disparity(z, f_px=500.0, baseline_mm=4.0, cx_left=300.0, cx_right=310.0)
    np.testing.assert_allclose(back[:1], d[:1], rtol=1e-14)
    assert np.isnan(laparo.stereo.disparity_to_depth(np.array([-10.0]), 500.0, 4.0, 300.0, 310.0)[0])
    with pytest.raises(ValueError, match="f_px"):
        laparo.stereo.disparity_to_depth(d, f_px=float("nan"), baseline_mm=4.0)
    with pytest.raises(TypeError, match="disparity"):
        laparo.stereo.disparity_to_depth([1.0, 2.0], 500.0, 4.0)


def test_evaluate_equals_cli(cli, tmp_path):
    c = calib_dict()
    write_calib(tmp_path / "c.json", c)
    rng = np.random.default_rng(1)
    gt = 20.0 + 5.0 * rng.random((H, W))
    gt[3, 4] = np.inf
    pred = gt + rng.normal(0.0, 2.0, (H, W))
    pred[7, 8] = np.nan
    np.save(tmp_path / "gt.npy", gt)
    np.save(tmp_path / "pred.npy", pred)
    ref = cli_json(cli, "stereo", "eval", "--pred", tmp_path / "pred.npy", "--gt", tmp_path / "gt.npy", "--calib",
                   tmp_path / "c.json", "--out", tmp_path / "out", "--json")["metrics"]
    got = laparo.stereo.evaluate(pred, gt, f_px=c["k_left"][0, 0], baseline_mm=float(np.linalg.norm(c["t_mm"])),
                                 cx_left=c["k_left"][0, 2], cx_right=c["k_right"][0, 2])
    # The CLI's geometry also records fy and cy (unused by the metrics).
    for k in ["fy_px", "cy"]:
        got["depth"]["geometry"].pop(k)
        ref["depth"]["geometry"].pop(k)
    assert json.dumps(got, sort_keys=True) == json.dumps(ref, sort_keys=True)
    assert got["n_pred_missing"] == 1
