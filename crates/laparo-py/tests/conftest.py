"""Shared helpers of the laparo pytest suite: the CLI binary, and readers for the files the CLI
writes (PNG 8-bit, PFM, npy) using only the standard library and NumPy."""
from __future__ import annotations

import json
import os
import shutil
import struct
import subprocess
import zlib
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[3]


def laparo_bin() -> Path:
    env = os.environ.get("LAPARO_BIN")
    if env:
        return Path(env)
    target = Path(os.environ.get("CARGO_TARGET_DIR", REPO / "target"))
    return target / "release" / "laparo"


@pytest.fixture(scope="session")
def cli():
    """Run the laparo CLI (target/release/laparo or $LAPARO_BIN); skips when it is not built."""
    b = laparo_bin()
    if not b.is_file():
        pytest.skip(f"SKIP: the laparo CLI is not built at {b} (cargo build --release -p laparo)")

    def run(*args: str, check: bool = True) -> subprocess.CompletedProcess:
        r = subprocess.run([str(b), *map(str, args)], capture_output=True, text=True)
        if check and r.returncode != 0:
            raise AssertionError(f"laparo {' '.join(map(str, args))} failed:\n{r.stderr}")
        return r

    return run


def cli_json(run, *args: str):
    return json.loads(run(*args).stdout)


def read_png(path) -> np.ndarray:
    """Decode an 8-bit, non-interlaced PNG (grey, grey+alpha, RGB, RGBA) into (H, W[, C]) uint8."""
    data = Path(path).read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", path
    pos, idat, w = 8, b"", None
    while pos < len(data):
        (n,) = struct.unpack(">I", data[pos : pos + 4])
        kind, body = data[pos + 4 : pos + 8], data[pos + 8 : pos + 8 + n]
        pos += 12 + n
        if kind == b"IHDR":
            w, h, depth, ctype, _, _, interlace = struct.unpack(">IIBBBBB", body)
            assert depth == 8 and interlace == 0, (path, depth, interlace)
            ch = {0: 1, 2: 3, 4: 2, 6: 4}[ctype]
        elif kind == b"IDAT":
            idat += body
    raw = zlib.decompress(idat)
    stride = w * ch
    out = np.zeros((h, stride), dtype=np.uint8)
    prev = np.zeros(stride, dtype=np.int32)
    for y in range(h):
        f = raw[y * (stride + 1)]
        line = np.frombuffer(raw, dtype=np.uint8, count=stride, offset=y * (stride + 1) + 1).astype(np.int32)
        cur = np.zeros(stride, dtype=np.int32)
        for x in range(stride):
            a = cur[x - ch] if x >= ch else 0
            b = prev[x]
            c = prev[x - ch] if x >= ch else 0
            if f == 0:
                p = 0
            elif f == 1:
                p = a
            elif f == 2:
                p = b
            elif f == 3:
                p = (a + b) // 2
            else:
                pa, pb, pc = abs(b - c), abs(a - c), abs(a + b - 2 * c)
                p = a if (pa <= pb and pa <= pc) else (b if pb <= pc else c)
            cur[x] = (line[x] + p) & 0xFF
        out[y] = cur
        prev = cur
    img = out.reshape(h, w, ch)
    return img[:, :, 0] if ch == 1 else img


def read_pfm(path) -> np.ndarray:
    """A PFM file as (H, W) or (H, W, 3) float32, top row first."""
    data = Path(path).read_bytes()
    parts = data.split(b"\n", 3)
    kind, dims, scale = parts[0].strip(), parts[1].split(), float(parts[2])
    w, h = int(dims[0]), int(dims[1])
    ch = 3 if kind == b"PF" else 1
    dt = "<f4" if scale < 0 else ">f4"
    a = np.frombuffer(parts[3], dtype=dt, count=w * h * ch).reshape(h, w, ch)[::-1]
    return np.ascontiguousarray(a[:, :, 0] if ch == 1 else a).astype(np.float32)


def write_png_gray_or_rgb(path, img: np.ndarray) -> None:
    """Write an 8-bit PNG (no filtering) for CLI inputs."""
    img = np.ascontiguousarray(img, dtype=np.uint8)
    h, w = img.shape[:2]
    ch = 1 if img.ndim == 2 else img.shape[2]
    ctype = {1: 0, 3: 2, 4: 6}[ch]
    raw = b"".join(b"\x00" + img[y].tobytes() for y in range(h))

    def chunk(t: bytes, b: bytes) -> bytes:
        return struct.pack(">I", len(b)) + t + b + struct.pack(">I", zlib.crc32(t + b) & 0xFFFFFFFF)

    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, ctype, 0, 0, 0))
    png += chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b"")
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    Path(path).write_bytes(png)


def write_pfm(path, a: np.ndarray) -> None:
    a = np.asarray(a, dtype="<f4")
    h, w = a.shape
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    Path(path).write_bytes(f"Pf\n{w} {h}\n-1.0\n".encode() + a[::-1].tobytes())


def assert_rel(a, b, rel=1e-12, what=""):
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    assert a.shape == b.shape, (what, a.shape, b.shape)
    both_nan = np.isnan(a) & np.isnan(b)
    d = np.abs(a - b)
    tol = rel * np.maximum(np.abs(a), np.abs(b)) + 1e-300
    bad = ~both_nan & ~(d <= tol)
    assert not bad.any(), f"{what}: max rel diff {np.nanmax(d / np.maximum(tol / rel, 1e-300))}"


try:
    import torch  # noqa: F401

    HAVE_TORCH = True
except Exception:
    HAVE_TORCH = False

needs_torch = pytest.mark.skipif(not HAVE_TORCH, reason="SKIP: PyTorch is not installed (pip install torch)")
