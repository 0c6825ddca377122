"""OpenCV peer of laparo's grey bicubic homography warp (`laparo-bench cats`, the self-rectified
matcher's warp): cv2.warpPerspective(INTER_CUBIC) of the grey image, with the camera and homography
of ../shared/bench/warp_ref.py (H = K_rel K R K^-1, Euler Z-Y-X 0.3, 0.2, 0.02 deg, principal-point
shift -60 px). OpenCV's cubic uses a = -0.75, laparo's Keys a = -0.5: the same work per pixel
(4x4 taps), not the same values. Prints min/median ms as JSON.

Usage: python3 warp_grey_cubic_opencv.py IMAGE [--width 960 --height 540] [--runs 20] [--threads 1]
"""
import argparse, json, time
import numpy as np
import cv2

ap = argparse.ArgumentParser()
ap.add_argument("image")
ap.add_argument("--width", type=int, default=960)
ap.add_argument("--height", type=int, default=540)
ap.add_argument("--runs", type=int, default=20)
ap.add_argument("--threads", type=int, default=1)
a = ap.parse_args()
cv2.setNumThreads(a.threads)
img = cv2.resize(cv2.imread(a.image, cv2.IMREAD_GRAYSCALE), (a.width, a.height), interpolation=cv2.INTER_AREA)
f = 0.9 * a.width
K = np.array([[f, 0, a.width / 2], [0, f, a.height / 2], [0, 0, 1.0]])
def rot(axis, deg):
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return {"x": np.array([[1, 0, 0], [0, c, -s], [0, s, c]]),
            "y": np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]),
            "z": np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])}[axis]
R = rot("z", 0.3) @ rot("y", 0.2) @ rot("x", 0.02)
H = np.array([[1, 0, -60.0], [0, 1, 0], [0, 0, 1]]) @ K @ R @ np.linalg.inv(K)

def tmin(fn):
    fn(); ts = []
    for _ in range(a.runs):
        t0 = time.perf_counter(); fn(); ts.append(time.perf_counter() - t0)
    return {"min_ms": min(ts) * 1e3, "median_ms": float(np.median(ts)) * 1e3}

out = {"opencv": cv2.__version__, "threads": a.threads, "size": [a.width, a.height], "H": H.tolist(),
       "grey_u8_bicubic": tmin(lambda: cv2.warpPerspective(img, H, (a.width, a.height), flags=cv2.INTER_CUBIC))}
print(json.dumps(out, indent=1))
