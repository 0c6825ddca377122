"""A NumPy/OpenCV implementation of the CATS augmentation of one stereo sample (thesis §3.3.5,
eqs. 3.6–3.9), written as a user of NumPy + OpenCV would: the peer of `laparo.cats.augment`
in `crates/laparo-py/bench/bench_cats.py` (same work: both views warped bilinearly by their homographies
H = K_rel K R K⁻¹ with inverse mapping, validity masks, and the left disparity by the exact
rule — p = H_L⁻¹ p', d sampled at p, p_R = (x − d, y), d' = x' − (H_R p_R)_x).

The camera parameters are drawn with NumPy's generator from the same distributions (not the
same stream as laparo's ChaCha8), so images agree with laparo's statistically, not pixel for
pixel; `check_against_laparo` compares both on the *same* parameters.
"""
from __future__ import annotations

import numpy as np

try:
    import cv2
except ImportError as e:  # pragma: no cover
    raise SystemExit("cats_reference.py needs OpenCV: pip install opencv-python-headless") from e


def rot_zyx(deg):
    x, y, z = np.radians(deg)
    rx = np.array([[1, 0, 0], [0, np.cos(x), -np.sin(x)], [0, np.sin(x), np.cos(x)]])
    ry = np.array([[np.cos(y), 0, np.sin(y)], [0, 1, 0], [-np.sin(y), 0, np.cos(y)]])
    rz = np.array([[np.cos(z), -np.sin(z), 0], [np.sin(z), np.cos(z), 0], [0, 0, 1]])
    return rz @ ry @ rx


# Table 3.6, SCARED+StMIS row (μ, σ in degrees): left x, y, z, right x, y, z.
TABLE_3_6 = [(-0.0001, 0.0004), (0.0564, 0.1666), (0.0280, 0.3487), (-0.0016, 0.0047), (0.0854, 0.1594), (0.0289, 0.3489)]


def sample_homographies(rng: np.random.Generator, k: np.ndarray):
    """H_L, H_R and Δx_right of one sample (eqs. 3.7–3.9)."""
    e = [rng.normal(m, s) for m, s in TABLE_3_6]
    dx = rng.uniform(-100.0, 0.0)
    kinv = np.linalg.inv(k)
    hl = k @ rot_zyx(e[:3]) @ kinv
    krel_r = np.array([[1.0, 0.0, -dx], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    hr = krel_r @ k @ rot_zyx(e[3:]) @ kinv
    return hl, hr, dx


def augment_thesis(left, right, disp, hl, hr, dx):
    """The thesis rule (§3.3.5): the left disparity warped by H_L (nearest), plus Δx_right."""
    h, w = left.shape[:2]
    flags_l = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
    hl_inv, hr_inv = np.linalg.inv(hl), np.linalg.inv(hr)
    out_l = cv2.warpPerspective(left, hl_inv, (w, h), flags=flags_l, borderMode=cv2.BORDER_CONSTANT)
    out_r = cv2.warpPerspective(right, hr_inv, (w, h), flags=flags_l, borderMode=cv2.BORDER_CONSTANT)
    d = cv2.warpPerspective(disp, hl_inv, (w, h), flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP,
                            borderMode=cv2.BORDER_CONSTANT, borderValue=np.inf)
    ok = np.isfinite(d)
    d[ok] += dx
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float64)
    q = np.stack([xs, ys, np.ones_like(xs)], axis=-1) @ hr_inv.T
    rx, ry = q[..., 0] / q[..., 2], q[..., 1] / q[..., 2]
    valid_r = (rx >= -0.5) & (ry >= -0.5) & (rx < w - 0.5) & (ry < h - 0.5) & (q[..., 2] > 0)
    return {"left": out_l, "right": out_r, "valid_left": ok, "valid_right": valid_r, "disp_left": d,
            "disp_left_valid": ok}


def augment(left, right, disp, hl, hr):
    """Augment (left, right, left disparity) with homographies hl, hr (exact disparity rule)."""
    h, w = left.shape[:2]
    flags = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
    hl_inv, hr_inv = np.linalg.inv(hl), np.linalg.inv(hr)
    out_l = cv2.warpPerspective(left, hl_inv, (w, h), flags=flags, borderMode=cv2.BORDER_CONSTANT)
    out_r = cv2.warpPerspective(right, hr_inv, (w, h), flags=flags, borderMode=cv2.BORDER_CONSTANT)
    # Source coordinates of every augmented pixel, for the masks and the disparity.
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float64)
    p = np.stack([xs, ys, np.ones_like(xs)], axis=-1) @ hl_inv.T
    sx, sy = p[..., 0] / p[..., 2], p[..., 1] / p[..., 2]
    valid_l = (sx >= -0.5) & (sy >= -0.5) & (sx < w - 0.5) & (sy < h - 0.5) & (p[..., 2] > 0)
    q = np.stack([xs, ys, np.ones_like(xs)], axis=-1) @ hr_inv.T
    rx, ry = q[..., 0] / q[..., 2], q[..., 1] / q[..., 2]
    valid_r = (rx >= -0.5) & (ry >= -0.5) & (rx < w - 0.5) & (ry < h - 0.5) & (q[..., 2] > 0)
    # Exact rule: disparity at the source position (bilinear), through the right camera.
    d = cv2.remap(disp, sx.astype(np.float32), sy.astype(np.float32), cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                  borderValue=np.nan)
    xr = sx - d
    pr = np.stack([xr, sy, np.ones_like(xr)], axis=-1) @ hr.T
    d_out = (xs - pr[..., 0] / pr[..., 2]).astype(np.float32)
    ok = valid_l & np.isfinite(d_out)
    d_out[~ok] = np.inf
    return {"left": out_l, "right": out_r, "valid_left": valid_l, "valid_right": valid_r, "disp_left": d_out,
            "disp_left_valid": ok}
