"""laparo.features against the CLI (`features detect`, `features match`) and independent checks:
RANSAC homography / fundamental / essential on synthetic correspondences with known models,
matching of permuted descriptors, transfer errors by hand, keypoints of a shifted image."""
import json

import numpy as np
import pytest

import laparo
from conftest import write_png_gray_or_rgb

F = laparo.features


def blobs(w=160, h=120, dx=0.0):
    """A smooth texture (shifted right by dx px)."""
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    u = x - dx
    s = np.sin(u * 0.21) * np.cos(y * 0.17) + np.sin(u * 0.05 + y * 0.11)
    return (128.0 + 60.0 * s).astype(np.uint8)


def texture(w, h, seed=0):
    """Random smoothed texture with corners (for ORB)."""
    rng = np.random.default_rng(seed)
    a = rng.random((h // 4 + 1, w // 4 + 1))
    a = np.kron(a, np.ones((4, 4)))[:h, :w]
    k = np.ones(3) / 3
    a = np.apply_along_axis(lambda r: np.convolve(r, k, "same"), 1, a)
    return (40 + 180 * a).astype(np.uint8)


@pytest.mark.parametrize("det", ["sift", "orb"])
def test_detect_equals_cli(cli, tmp_path, det):
    img = blobs() if det == "sift" else texture(200, 160)
    write_png_gray_or_rgb(tmp_path / "a.png", img)
    cli("features", "detect", "--image", tmp_path / "a.png", "--detector", det, "--out", tmp_path / "f.json")
    ref = json.loads((tmp_path / "f.json").read_text())
    got = F.detect(img, det)
    kp = got["keypoints"]
    assert kp.shape == (ref["n_keypoints"], 6) and kp.dtype == np.float64
    cols = ["x", "y", "size_px", "angle_rad", "response", "octave"]
    np.testing.assert_array_equal(kp, np.array([[k[c] for c in cols] for k in ref["keypoints"]]).reshape(-1, 6))
    (kind, body), = ref["descriptors"].items()
    if det == "sift":
        assert kind == "Float" and got["descriptors"].dtype == np.float32 and got["descriptors"].shape[1] == 128
        np.testing.assert_array_equal(got["descriptors"].ravel(), np.array(body["data"], dtype=np.float32))
    else:
        assert kind == "Binary" and got["descriptors"].dtype == np.uint8 and got["descriptors"].shape[1] == 32
        np.testing.assert_array_equal(got["descriptors"].ravel(), np.array(body["data"], dtype=np.uint8))
    assert json.dumps(got["detector"], sort_keys=True) == json.dumps(ref["detector"], sort_keys=True)


def test_match_images_equals_cli_with_homography(cli, tmp_path):
    a, b = blobs(), blobs(dx=7.0)
    h = np.array([[1.0, 0.0, 7.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    write_png_gray_or_rgb(tmp_path / "a.png", a)
    write_png_gray_or_rgb(tmp_path / "b.png", b)
    (tmp_path / "h.json").write_text(json.dumps(h.tolist()))
    cli("features", "match", "--image1", tmp_path / "a.png", "--image2", tmp_path / "b.png", "--ratio", "ubc:1.5",
        "--homography", tmp_path / "h.json", "--out", tmp_path / "m")
    ref = json.loads((tmp_path / "m" / "matches.json").read_text())
    got = F.match_images(a, b, ratio="ubc:1.5", homography=h)
    for k in ["n_keypoints1", "n_keypoints2", "n_matches", "n_correct", "precision", "eps_px"]:
        assert got[k] == ref[k], k
    rows = ref["matches"]
    np.testing.assert_array_equal(got["matches"], np.array([[m["i1"], m["i2"]] for m in rows]).reshape(-1, 2))
    np.testing.assert_array_equal(got["points1"], np.array([[m["x1"], m["y1"]] for m in rows]).reshape(-1, 2))
    np.testing.assert_array_equal(got["points2"], np.array([[m["x2"], m["y2"]] for m in rows]).reshape(-1, 2))
    np.testing.assert_array_equal(got["distances"], np.array([m["distance"] for m in rows], dtype=np.float32))
    np.testing.assert_array_equal(got["transfer_error_px"], np.array([m["transfer_error_px"] for m in rows]))
    np.testing.assert_array_equal(got["correct"], np.array([m["correct"] for m in rows]))
    # Independently: the 7 px shift explains most matches (doc-test of laparo-features).
    assert got["n_matches"] > 10 and got["precision"] >= 0.8
    # match() on the returned descriptors is the same matching.
    idx, dist = F.match(got["features1"]["descriptors"], got["features2"]["descriptors"], ratio="ubc:1.5")
    np.testing.assert_array_equal(idx, got["matches"])
    np.testing.assert_array_equal(dist, got["distances"])


def test_shifted_image_keypoints_shift():
    a, b = F.detect(blobs()), F.detect(blobs(dx=7.0))
    idx, _ = F.match(a["descriptors"], b["descriptors"])
    d = b["keypoints"][idx[:, 1], :2] - a["keypoints"][idx[:, 0], :2]
    good = (np.abs(d[:, 0] - 7.0) < 1.0) & (np.abs(d[:, 1]) < 1.0)
    assert len(idx) > 10 and good.mean() >= 0.8


def test_match_permuted_descriptors_float_and_binary():
    rng = np.random.default_rng(3)
    d1 = rng.random((50, 16)).astype(np.float32)
    perm = rng.permutation(50)
    d2 = d1[perm] + rng.normal(0, 1e-3, (50, 16)).astype(np.float32)
    idx, dist = F.match(d1, d2, ratio="lowe:0.8", mutual=True)
    inv = np.argsort(perm)
    assert len(idx) == 50
    np.testing.assert_array_equal(idx[:, 0], np.arange(50))
    np.testing.assert_array_equal(idx[:, 1], inv)
    np.testing.assert_allclose(dist, np.linalg.norm(d1 - d2[inv], axis=1), rtol=1e-4)
    # Binary: Hamming distances by hand.
    b1 = np.array([[0b00001111, 0], [0b11110000, 0xFF]], dtype=np.uint8)
    b2 = np.array([[0b11110001, 0xFF], [0b00001110, 0]], dtype=np.uint8)
    idx, dist = F.match(b1, b2, ratio="none", mutual=False)
    np.testing.assert_array_equal(idx, [[0, 1], [1, 0]])
    np.testing.assert_array_equal(dist, [1.0, 1.0])


def test_transfer_error_by_hand():
    h = np.array([[2.0, 0.0, 1.0], [0.0, 2.0, -1.0], [0.0, 0.0, 1.0]])
    p1 = np.array([[0.0, 0.0], [1.0, 1.0]])
    p2 = np.array([[1.0, -1.0], [3.0, 4.0]])  # exact; off by (0, 3)
    e = F.transfer_error(h, p1, p2)
    # second: ‖H p1 − p2‖ = 3, ‖H⁻¹ p2 − p1‖ = ‖((3−1)/2, (4+1)/2) − (1, 1)‖ = 1.5 → 2.25
    np.testing.assert_allclose(e, [0.0, 2.25], rtol=0, atol=1e-15)


def test_ransac_homography_known_h_with_outliers():
    rng = np.random.default_rng(0)
    h = np.array([[1.02, 0.05, 12.0], [-0.03, 0.98, -7.0], [1e-4, -2e-4, 1.0]])
    p1 = rng.uniform(0, 640, (200, 2))
    q = np.c_[p1, np.ones(200)] @ h.T
    p2 = q[:, :2] / q[:, 2:]
    out = rng.random(200) < 0.3
    p2[out] += rng.uniform(-80, 80, (out.sum(), 2))
    r = F.find_homography(p1, p2, threshold_px=1.0, seed=5)
    m = r["model"] / r["model"][2, 2]
    np.testing.assert_allclose(m, h, rtol=1e-7, atol=1e-9)
    big = np.linalg.norm(p2 - (np.c_[p1, np.ones(200)] @ h.T)[:, :2] / (np.c_[p1, np.ones(200)] @ h.T)[:, 2:], axis=1) > 2
    np.testing.assert_array_equal(r["inliers"], ~big)
    assert r["n_inliers"] == (~big).sum() and r["rms_px"] < 1e-6
    # Deterministic for a seed, whatever the thread count.
    laparo.set_num_threads(1)
    try:
        r1 = F.find_homography(p1, p2, threshold_px=1.0, seed=5)
    finally:
        laparo.set_num_threads(0)
    np.testing.assert_array_equal(r1["model"], r["model"])


def two_view(n=150, seed=1):
    rng = np.random.default_rng(seed)
    x = np.c_[rng.uniform(-1, 1, n), rng.uniform(-1, 1, n), rng.uniform(4, 8, n)]
    a = 0.1
    r = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
    t = np.array([-1.0, 0.1, 0.05])
    x2 = x @ r.T + t
    return x[:, :2] / x[:, 2:], x2[:, :2] / x2[:, 2:], r, t


def test_ransac_essential_and_fundamental_epipolar_constraint():
    n1, n2, r, t = two_view()
    tx = np.array([[0, -t[2], t[1]], [t[2], 0, -t[0]], [-t[1], t[0], 0]])
    e_true = tx @ r
    e_true /= np.linalg.norm(e_true)
    res = F.find_essential(n1, n2, threshold=1e-4, seed=2)
    e = res["model"] / np.linalg.norm(res["model"])
    e *= np.sign(np.sum(e * e_true))
    np.testing.assert_allclose(e, e_true, atol=1e-6)
    assert res["n_inliers"] == len(n1)
    k = np.array([[500.0, 0, 320], [0, 500, 240], [0, 0, 1]])
    p1 = n1 * 500 + [320, 240]
    p2 = n2 * 500 + [320, 240]
    p2[:20] += 25.0  # outliers
    f = F.find_fundamental(p1, p2, threshold_px=0.5, seed=0)
    f_true = np.linalg.inv(k).T @ e_true @ np.linalg.inv(k)
    fm = f["model"] / np.linalg.norm(f["model"])
    fm *= np.sign(np.sum(fm * f_true))
    np.testing.assert_allclose(fm, f_true / np.linalg.norm(f_true), atol=1e-6)
    assert not f["inliers"][:20].any() and f["inliers"][20:].all()


def test_errors_name_the_argument():
    with pytest.raises(TypeError, match="image"):
        F.detect(np.zeros((10, 10), dtype=np.float32))
    with pytest.raises(ValueError, match="detector"):
        F.detect(np.zeros((10, 10), dtype=np.uint8), "surf")
    with pytest.raises(ValueError, match="ratio"):
        F.match(np.zeros((2, 4), np.float32), np.zeros((2, 4), np.float32), ratio="lowe:1.5")
    with pytest.raises(ValueError, match="ratio"):
        F.match(np.zeros((2, 4), np.float32), np.zeros((2, 4), np.float32), ratio="best")
    with pytest.raises(TypeError, match="descriptors2"):
        F.match(np.zeros((2, 4), np.float32), np.zeros((2, 4), np.uint8))
    with pytest.raises(ValueError, match="descriptors1"):
        F.match(np.full((2, 4), np.nan, np.float32), np.zeros((2, 4), np.float32))
    with pytest.raises(ValueError, match="p1"):
        F.find_homography(np.full((10, 2), np.nan), np.zeros((10, 2)))
    with pytest.raises(ValueError, match="p2"):
        F.find_homography(np.zeros((10, 2)), np.zeros((9, 2)))
    with pytest.raises(ValueError, match="too few"):
        F.find_homography(np.zeros((3, 2)), np.zeros((3, 2)))
    with pytest.raises(ValueError, match="threshold_px"):
        F.find_fundamental(np.zeros((10, 2)), np.zeros((10, 2)), threshold_px=-1)
    with pytest.raises(ValueError, match="homography"):
        F.transfer_error(np.zeros((3, 3)), np.zeros((1, 2)), np.zeros((1, 2)))
    with pytest.raises(ValueError, match="mask"):
        F.detect(np.zeros((10, 10), np.uint8), mask=np.ones((5, 5), bool))
