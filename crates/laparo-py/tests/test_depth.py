"""laparo.depth against the CLI (`laparo depth eval-pair --json`, `laparo depth perturb`) and
closed forms; argument errors."""
import json

import numpy as np
import pytest

import laparo
from conftest import cli_json, read_png, write_png_gray_or_rgb

H, W = 24, 32


def scene(seed=0):
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:H, 0:W]
    gt_mm = 50.0 + 100.0 * xx / W + 20.0 * yy / H
    gt_mm[:2, :3] = 0.0  # invalid
    gt_mm[5, 7] = np.nan
    with np.errstate(divide="ignore"):
        pred = 3.0 / (gt_mm / 1000.0) * (1.0 + 0.05 * rng.standard_normal((H, W)))
    pred[0, 10] = np.nan  # an invalid prediction
    mask = np.ones((H, W), dtype=bool)
    mask[:, -4:] = False
    return pred, gt_mm, mask


def assert_same_json(a, b):
    """Exact equality of nested JSON-like values (floats bit-identical)."""
    assert json.dumps(a, sort_keys=True) == json.dumps(b, sort_keys=True)


@pytest.mark.parametrize("kind", ["disparity", "depth"])
@pytest.mark.parametrize("use_mask", [False, True])
def test_evaluate_pair_equals_cli(cli, tmp_path, kind, use_mask):
    pred, gt, mask = scene()
    if kind == "depth":
        pred = 1.0 / pred
    np.save(tmp_path / "pred.npy", pred)
    np.save(tmp_path / "gt.npy", gt)
    args = ["depth", "eval-pair", "--pred", tmp_path / "pred.npy", "--gt", tmp_path / "gt.npy", "--pred-kind", kind]
    if use_mask:
        np.save(tmp_path / "mask.npy", mask.astype(np.float64))
        args += ["--mask", tmp_path / "mask.npy"]
    ref = cli_json(cli, *args, "--json")
    got = laparo.depth.evaluate_pair(pred, gt, mask if use_mask else None, pred_kind=kind)
    assert_same_json(got, ref)
    assert set(got) == {"n_valid", "n_invalid_pred", "none", "scale", "scale_shift"}
    assert got["n_invalid_pred"] == 1


def test_evaluate_pair_options_equal_cli(cli, tmp_path):
    pred, gt, _ = scene(1)
    np.save(tmp_path / "pred.npy", pred)
    np.save(tmp_path / "gt.npy", gt / 1000.0)
    ref = cli_json(
        cli, "depth", "eval-pair", "--pred", tmp_path / "pred.npy", "--gt", tmp_path / "gt.npy", "--gt-unit", "m",
        "--alignment", "none,st", "--depth-min-m", "0.02", "--depth-max-m", "0.3", "--invalid-pred", "exclude", "--json",
    )
    got = laparo.depth.evaluate_pair(
        pred, gt / 1000.0, gt_unit="m", alignments="none,st", depth_min_m=0.02, depth_max_m=0.3, invalid_pred="exclude"
    )
    assert_same_json(got, ref)
    assert "scale" not in got


def test_closed_form_scale():
    # Twice the disparity halves every depth: Abs Rel = 0.5 without alignment, 0 once s is fitted.
    gt = np.array([[0.05, 0.1], [0.2, 0.25]])
    r = laparo.depth.evaluate_pair(2.0 / gt, gt, gt_unit="m")
    assert abs(r["none"]["abs_rel"] - 0.5) < 1e-15
    assert abs(r["scale"]["abs_rel"]) < 1e-15
    assert abs(r["scale"]["scale"] - 0.5) < 1e-15


def test_float32_and_batch_equal_single():
    preds, gts = [], []
    for s in range(5):
        p, g, _ = scene(s)
        preds.append(p)
        gts.append(g)
    single = [laparo.depth.evaluate_pair(p, g) for p, g in zip(preds, gts)]
    assert laparo.depth.evaluate_batch(preds, gts) == single
    assert laparo.depth.evaluate_batch(np.stack(preds), np.stack(gts)) == single
    assert laparo.depth.evaluate_batch(preds, gts, shard="1/3") == [single[1], single[4]]
    p32 = preds[0].astype(np.float32)
    assert laparo.depth.evaluate_pair(p32, gts[0]) == laparo.depth.evaluate_pair(p32.astype(np.float64), gts[0])


def test_perturb_equals_cli(cli, tmp_path):
    rng = np.random.default_rng(3)
    img = rng.integers(0, 256, size=(20, 28, 3), dtype=np.uint8)
    write_png_gray_or_rgb(tmp_path / "in" / "frame7.png", img)
    cli("depth", "perturb", "--input", tmp_path / "in", "--out", tmp_path / "out", "--kinds", "smoke,blood,dark,motion,dirt",
        "--severities", "1,3", "--seed", "42")
    for kind in ["smoke", "blood", "dark", "motion", "dirt"]:
        seed = laparo.depth.item_seed(42, "frame7", kind)
        for sev in [1, 3]:
            ref = read_png(tmp_path / "out" / kind / f"s{sev}" / "frame7.png")
            got = laparo.depth.perturb(img, kind, sev, seed)
            assert got.dtype == np.uint8 and got.shape == (20, 28, 3)
            np.testing.assert_array_equal(got, ref, err_msg=f"{kind} s{sev}")
    # Deterministic, and the seed matters.
    a = laparo.depth.perturb(img, "smoke", 2, 1)
    assert np.array_equal(a, laparo.depth.perturb(img, "smoke", 2, 1))
    assert not np.array_equal(a, laparo.depth.perturb(img, "smoke", 2, 2))
    assert set(laparo.depth.KINDS) == {"smoke", "blood", "bright", "dark", "defocus", "motion", "dirt"}


def test_errors_name_the_argument():
    pred, gt, mask = scene()
    with pytest.raises(TypeError, match="pred"):
        laparo.depth.evaluate_pair(np.ones((H, W), dtype=np.int32), gt)
    with pytest.raises(TypeError, match="gt"):
        laparo.depth.evaluate_pair(pred, gt.tolist())
    with pytest.raises(ValueError, match="pred.*shape"):
        laparo.depth.evaluate_pair(pred[:, :-1].copy(), gt)
    with pytest.raises(ValueError, match="pred.*contiguous"):
        laparo.depth.evaluate_pair(np.asfortranarray(pred), gt)
    with pytest.raises(ValueError, match="mask"):
        laparo.depth.evaluate_pair(pred, gt, mask[:, :-1].copy())
    with pytest.raises(TypeError, match="mask"):
        laparo.depth.evaluate_pair(pred, gt, mask.astype(np.float32))
    with pytest.raises(ValueError, match="pred_kind"):
        laparo.depth.evaluate_pair(pred, gt, pred_kind="inverse")
    with pytest.raises(ValueError, match="depth_min_m"):
        laparo.depth.evaluate_pair(pred, gt, depth_min_m=float("nan"))
    with pytest.raises(ValueError, match="invalid_pred"):
        laparo.depth.evaluate_pair(pred, gt, invalid_pred="ignore")
    with pytest.raises(ValueError, match="prediction"):
        laparo.depth.evaluate_pair(pred, gt, invalid_pred="error")  # the NaN prediction
    with pytest.raises(ValueError, match="pred"):
        laparo.depth.evaluate_pair(np.zeros((0, 3)), np.zeros((0, 3)))
    img = np.zeros((8, 8, 3), dtype=np.uint8)
    with pytest.raises(ValueError, match="severity"):
        laparo.depth.perturb(img, "smoke", 4, 0)
    with pytest.raises(ValueError, match="kind"):
        laparo.depth.perturb(img, "rain", 1, 0)
    with pytest.raises(TypeError, match="image"):
        laparo.depth.perturb(img.astype(np.float32), "smoke", 1, 0)
    with pytest.raises(ValueError, match="image"):
        laparo.depth.perturb(np.zeros((8, 8, 2), dtype=np.uint8), "smoke", 1, 0)
    with pytest.raises(ValueError, match="image"):
        laparo.depth.perturb(np.zeros((1, 1, 3), dtype=np.uint8), "smoke", 1, 0)
