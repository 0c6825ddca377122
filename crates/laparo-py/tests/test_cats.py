"""laparo.cats against the CLI (`cats augment`, `cats apply`, `--shard`), determinism, errors,
and the PyTorch Dataset in DataLoader workers."""
import json
from pathlib import Path

import numpy as np
import pytest

import laparo
from conftest import needs_torch, read_pfm, read_png, write_pfm, write_png_gray_or_rgb

W, H, F = 48, 32, 40.0
CFG = f"""source = "test"
[camera]
fx = {F}
fy = {F}
[left.euler_deg]
x = {{ dist = "normal", mean = 0.0, std = 0.5 }}
y = {{ dist = "normal", mean = 0.0, std = 1.0 }}
z = {{ dist = "normal", mean = 0.0, std = 1.0 }}
[right.euler_deg]
x = {{ dist = "normal", mean = 0.0, std = 0.5 }}
y = {{ dist = "normal", mean = 0.0, std = 1.0 }}
z = {{ dist = "normal", mean = 0.0, std = 1.0 }}
[disparity_offset]
dx_right_px = {{ dist = "uniform", min = -10.0, max = 0.0 }}
"""


def sample(i):
    """A textured stereo pair whose right view is the left shifted by a smooth disparity."""
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float64)
    disp = 3.0 + 2.0 * xx / W + 0.3 * i
    tex = lambda x, y: 127.5 + 60 * np.sin(0.7 * x + 0.3 * i) * np.cos(0.5 * y) + 40 * np.sin(0.23 * x * y / 7.0)
    left = np.stack([tex(xx, yy), tex(xx + 3, yy), tex(xx, yy + 2)], axis=-1)
    right = np.stack([tex(xx + disp, yy), tex(xx + disp + 3, yy), tex(xx + disp, yy + 2)], axis=-1)
    return left.clip(0, 255).astype(np.uint8), right.clip(0, 255).astype(np.uint8), disp.astype(np.float32)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    root = tmp_path_factory.mktemp("cats") / "in"
    for i in range(5):
        l, r, d = sample(i)
        write_png_gray_or_rgb(root / "left" / f"{i:04d}.png", l)
        write_png_gray_or_rgb(root / "right" / f"{i:04d}.png", r)
        write_pfm(root / "disp" / f"{i:04d}.pfm", d)
    (root / "cats.toml").write_text(CFG)
    return root


def check_against_cli_outputs(got, out, sid, euler_derived=False):
    np.testing.assert_array_equal(got["left"], read_png(out / "left" / f"{sid}.png"))
    np.testing.assert_array_equal(got["right"], read_png(out / "right" / f"{sid}.png"))
    ref = read_pfm(out / "disp" / f"{sid}.pfm")
    assert got["disp_left"].dtype == np.float32
    np.testing.assert_array_equal(got["disp_left"], ref)
    side = json.loads((out / f"left/{sid}.cats.json").read_text())
    for k in ["left", "right", "dx_right_px"]:
        a, b = got["params"][k], side["params"][k]
        if euler_derived and k != "dx_right_px":
            # Parameters given as a rotation: the Euler angles are re-derived from R (last bits).
            np.testing.assert_allclose(a.pop("euler_deg"), b.pop("euler_deg"), rtol=1e-12, atol=1e-14)
        assert json.dumps(a, sort_keys=True) == json.dumps(b, sort_keys=True), k
    assert got["params"]["homography_left"] == side["homography_left"]
    if not euler_derived:
        assert got["params"]["sample_seed"] == side["sample_seed"]


def test_folder_sample_epoch0_equals_cli_augment(cli, dataset, tmp_path):
    out = tmp_path / "out"
    cli("cats", "augment", "--input", dataset, "--layout", "generic", "--out", out, "--config", dataset / "cats.toml",
        "--seed", "7")
    cfg = laparo.cats.CatsConfig.from_file(dataset / "cats.toml")
    files = laparo.cats.discover(dataset, "generic")
    assert [f["id"] for f in files] == [f"left/{i:04d}" for i in range(5)]
    for i, f in enumerate(files):
        got = laparo.cats.augment_folder_sample(dataset, "generic", i, cfg, seed=7)
        check_against_cli_outputs(got, out, f"{i:04d}")
        # The same from arrays, with the id of the folder sample.
        l, r, d = sample(i)
        k = np.array([[F, 0, (W - 1) / 2], [0, F, (H - 1) / 2], [0, 0, 1.0]])
        arr = laparo.cats.augment(l, r, d, config=cfg, seed=7, sample_id=f["id"], k_left=k)
        for key in ["left", "right", "disp_left", "valid_left"]:
            np.testing.assert_array_equal(arr[key], got[key])
        # Epoch 1 draws other parameters.
        e1 = laparo.cats.augment_folder_sample(dataset, "generic", i, cfg, seed=7, epoch=1)
        assert e1["params"]["left"]["euler_deg"] != got["params"]["left"]["euler_deg"]


def test_params_from_sidecar_equal_cli_apply(cli, dataset, tmp_path):
    out = tmp_path / "aug"
    cli("cats", "augment", "--input", dataset, "--layout", "generic", "--out", out, "--config", dataset / "cats.toml",
        "--seed", "3", "--gt-rule", "thesis")
    side = json.loads((out / "left" / "0002.cats.json").read_text())
    l, r, d = sample(2)
    got = laparo.cats.augment(l, r, d, params=side["params"], gt_rule="thesis")
    check_against_cli_outputs(got, out, "0002", euler_derived=True)
    # cats apply with the sidecar writes the same arrays.
    cli("cats", "apply", "--params", out / "left" / "0002.cats.json", "--left", dataset / "left/0002.png", "--right",
        dataset / "right/0002.png", "--disp", dataset / "disp/0002.pfm", "--out", tmp_path / "apply", "--gt-rule", "thesis")
    np.testing.assert_array_equal(got["left"], read_png(tmp_path / "apply" / "left.png"))
    np.testing.assert_array_equal(got["disp_left"], read_pfm(tmp_path / "apply" / "disp_left.pfm"))
    # Thesis rule: d' = d(nearest source) + dx_right on valid pixels.
    assert "disp_left_vertical_residual" not in got


def test_identity_params_and_thesis_config():
    l, r, d = sample(0)
    k = [[F, 0, (W - 1) / 2], [0, F, (H - 1) / 2], [0, 0, 1]]
    ident = {"k": k, "left": {"euler_deg": [0, 0, 0]}, "right": {"euler_deg": [0, 0, 0]}, "dx_right_px": 0.0}
    got = laparo.cats.augment(l, r, d, params=ident)
    np.testing.assert_array_equal(got["left"], l)
    np.testing.assert_array_equal(got["right"], r)
    assert got["valid_left"].all()
    cfg = laparo.cats.thesis_config()
    assert "Table 3.6" in cfg.to_dict()["source"]
    assert laparo.cats.CatsConfig.from_toml(cfg.to_toml()).to_toml() == cfg.to_toml()
    p = laparo.cats.sample_params(cfg, 960, 540, seed=1, sample_id="a")
    assert -100.0 <= p["dx_right_px"] <= 0.0
    assert p == laparo.cats.sample_params(cfg, 960, 540, seed=1, sample_id="a")
    assert p != laparo.cats.sample_params(cfg, 960, 540, seed=1, sample_id="b")
    assert p["sample_seed"] == laparo.cats.sample_seed(1, "a")


def test_python_shards_write_the_files_of_one_cli_run(cli, dataset, tmp_path):
    cli("cats", "augment", "--input", dataset, "--layout", "generic", "--out", tmp_path / "full", "--config",
        dataset / "cats.toml", "--seed", "5")
    cfg = laparo.cats.CatsConfig.from_file(dataset / "cats.toml")
    n = sum(laparo.cats.augment_dataset(dataset, "generic", tmp_path / "sh", cfg, seed=5, shard=f"{i}/3") for i in range(3))
    assert n == 5
    files = lambda root: {p.relative_to(root): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}
    assert files(tmp_path / "sh") == files(tmp_path / "full")


def test_errors_name_the_argument():
    l, r, d = sample(0)
    with pytest.raises(TypeError, match="left"):
        laparo.cats.augment(l.astype(np.float32), r, d)
    with pytest.raises(ValueError, match="right"):
        laparo.cats.augment(l, r[:, :-1].copy(), d)
    with pytest.raises(ValueError, match="disp_left"):
        laparo.cats.augment(l, r, d[:-1].copy())
    with pytest.raises(ValueError, match="left.*contiguous"):
        laparo.cats.augment(l[:, ::2], r[:, ::2], None)
    with pytest.raises(ValueError, match="k_left"):
        laparo.cats.augment(l, r, d, k_left=np.full((3, 3), np.nan))
    with pytest.raises(ValueError, match="k_left"):
        laparo.cats.augment(l, r, d, k_left=np.eye(2))
    with pytest.raises(ValueError, match="gt_rule"):
        laparo.cats.augment(l, r, d, gt_rule="approx")
    with pytest.raises(ValueError, match="params"):
        laparo.cats.augment(l, r, d, params={"left": {}})
    with pytest.raises(ValueError, match="text"):
        laparo.cats.CatsConfig.from_toml("[left.euler_deg]\nx = 3")
    with pytest.raises(ValueError, match="shard"):
        laparo.cats.augment_dataset("/nonexistent", "generic", "/tmp/x", shard="3/3")


def _collate(batch):
    return batch


def _stream(ds, workers, epochs):
    import torch

    out = []
    for e in range(epochs):
        ds.set_epoch(e)
        dl = torch.utils.data.DataLoader(ds, batch_size=2, num_workers=workers, collate_fn=_collate, shuffle=False)
        for batch in dl:
            for item in batch:
                out.append((item["epoch"], item["index"], item["left"].tobytes(), item["disp_left"].tobytes()))
    return out


@needs_torch
@pytest.mark.filterwarnings("ignore:This DataLoader will create")
def test_dataloader_workers_equal_serial(dataset):
    cfg = laparo.cats.CatsConfig.from_file(dataset / "cats.toml")
    ds = laparo.cats.CatsDataset(root=dataset, layout="generic", config=cfg, seed=9)
    assert len(ds) == 5
    serial = _stream(ds, 0, 2)
    parallel = _stream(ds, 4, 2)
    assert len(serial) == 10
    assert serial == parallel
    # Epochs differ, and epoch 0 equals the folder sample of the CLI's generator.
    assert serial[0][2] != serial[5][2]
    assert serial[0][2] == laparo.cats.augment_folder_sample(dataset, "generic", 0, cfg, seed=9)["left"].tobytes()
    # In-memory samples and a shard.
    k = np.array([[F, 0, (W - 1) / 2], [0, F, (H - 1) / 2], [0, 0, 1.0]])
    mem = laparo.cats.CatsDataset(samples=[sample(i) for i in range(5)], config=cfg, seed=9, k_left=k, shard="1/2")
    assert len(mem) == 2 and mem[1]["id"] == "3"
