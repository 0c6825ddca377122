"""A PyTorch DataLoader that applies CATS camera augmentation on the fly (thesis §3.3.5).

    python examples/python/cats_dataloader.py [DATASET_ROOT --layout sceneflow|middlebury|generic]

Without arguments it writes a small generic-layout dataset under /tmp and loads it. Every
sample of epoch e is augmented with the generator of (seed, sample id, e): the same stream with
any number of workers; epoch 0 reproduces `laparo cats augment --seed SEED`.
"""
import argparse
import tempfile
from pathlib import Path

import numpy as np
import torch

import laparo


def write_demo_dataset(root: Path, n=8, h=120, w=160):
    """left/, right/ PNG and disp/ .npy (the generic layout), and a config with the camera."""
    import zlib, struct

    def png(path, img):
        raw = b"".join(b"\x00" + img[y].tobytes() for y in range(img.shape[0]))
        ch = lambda t, b: struct.pack(">I", len(b)) + t + b + struct.pack(">I", zlib.crc32(t + b) & 0xFFFFFFFF)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(b"\x89PNG\r\n\x1a\n" + ch(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
                         + ch(b"IDAT", zlib.compress(raw)) + ch(b"IEND", b""))

    yy, xx = np.mgrid[0:h, 0:w].astype(float)
    for i in range(n):
        d = 8.0 + 6.0 * xx / w
        tex = lambda x: (127 + 90 * np.sin(x / 5.0 + i) * np.cos(yy / 7.0)).clip(0, 255).astype(np.uint8)
        png(root / "left" / f"{i:04d}.png", np.stack([tex(xx)] * 3, -1))
        png(root / "right" / f"{i:04d}.png", np.stack([tex(xx + d)] * 3, -1))
        (root / "disp").mkdir(parents=True, exist_ok=True)
        np.save(root / "disp" / f"{i:04d}.npy", d.astype(np.float32))
    cfg = laparo.cats.thesis_config().to_toml() + f"\n[camera]\nfx = 150.0\nfy = 150.0\n"
    (root / "cats.toml").write_text(cfg)


def to_tensors(item):
    img = lambda a: torch.from_numpy(a).permute(2, 0, 1).float() / 255.0
    disp = torch.from_numpy(item["disp_left"])
    return img(item["left"]), img(item["right"]), disp, torch.from_numpy(item["disp_left_valid"])


def worker_init(_):
    laparo.set_num_threads(1)  # one laparo thread per DataLoader worker


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("root", nargs="?")
    ap.add_argument("--layout", default="generic")
    ap.add_argument("--config")
    ap.add_argument("--epochs", type=int, default=2)
    a = ap.parse_args()
    if a.root is None:
        root = Path(tempfile.mkdtemp()) / "stereo"
        write_demo_dataset(root)
        a.root, a.config = str(root), str(root / "cats.toml")
    cfg = laparo.cats.CatsConfig.from_file(a.config) if a.config else laparo.cats.thesis_config()
    ds = laparo.cats.CatsDataset(root=a.root, layout=a.layout, config=cfg, seed=0, transform=to_tensors)
    dl = torch.utils.data.DataLoader(ds, batch_size=4, shuffle=True, num_workers=2, worker_init_fn=worker_init,
                                     generator=torch.Generator().manual_seed(0))
    for epoch in range(a.epochs):
        ds.set_epoch(epoch)
        for left, right, disp, valid in dl:
            d = disp[valid]
            print(f"epoch {epoch}: batch {tuple(left.shape)}, disparity {d.min():.1f}..{d.max():.1f} px "
                  f"(negative values come from the principal-point offset Δx_right)")


if __name__ == "__main__":
    main()
