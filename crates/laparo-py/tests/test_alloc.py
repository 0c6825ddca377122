"""The extension's large-buffer cache: reused buffers never leak the previous call's data (same
results with the cache on and off, across different inputs of the same size), and memory handed
to NumPy stays valid after later calls."""
import numpy as np

import laparo


def run(seed):
    rng = np.random.default_rng(seed)
    h, w = 512, 640  # ≥ 1 MiB buffers
    left = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    right = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    disp = rng.uniform(5, 30, (h, w)).astype(np.float32)
    disp[rng.random((h, w)) < 0.2] = np.inf
    k = np.array([[500.0, 0, (w - 1) / 2], [0, 500.0, (h - 1) / 2], [0, 0, 1.0]])
    return laparo.cats.augment(left, right, disp, seed=seed, sample_id="s", k_left=k)


KEYS = ["left", "right", "valid_left", "valid_right", "disp_left", "disp_left_valid", "disp_left_vertical_residual"]


def test_cache_on_and_off_give_identical_results():
    try:
        laparo.set_buffer_cache_mb(0)
        ref = [run(s) for s in (1, 2, 3)]
        laparo.set_buffer_cache_mb(256)
        kept = run(1)  # stays alive while later calls reuse freed buffers
        got = [run(s) for s in (1, 2, 3, 2, 1)]
    finally:
        laparo.set_buffer_cache_mb(256)
    for g, r in zip(got, ref + ref[1::-1]):
        for k in KEYS:
            np.testing.assert_array_equal(g[k], r[k], err_msg=k)
    for k in KEYS:
        np.testing.assert_array_equal(kept[k], ref[0][k], err_msg=k)
