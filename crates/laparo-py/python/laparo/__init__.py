"""laparo — vision-based surgical guidance (the methods of the thesis *Contributions to 3D
Reconstruction and Deformable Registration from Images with Application to Minimally Invasive
Surgery*) for NumPy and PyTorch pipelines.

Submodules:

* :mod:`laparo.depth` — RoDEM: monocular depth metrics (eqs. 3.1–3.2), batched, and the
  seeded surgical perturbations (§3.2.6);
* :mod:`laparo.cats` — CATS camera augmentation of stereo samples (eqs. 3.5–3.9), dataset
  jobs with sharding, and a PyTorch ``Dataset`` applying CATS on the fly;
* :mod:`laparo.stereo` — rectification, disparity ↔ depth (§3.3.8), stereo evaluation,
  semi-global matching and self-rectification;
* :mod:`laparo.features` — SIFT / ORB, matching, RANSAC H / F / E (§4.2, §4.5);
* :mod:`laparo.register` — RODS-MPM deformable registration (Ch. 5) and the mesh baselines
  ARAP, DRBC and LDDMM (§5.4.2);
* :mod:`laparo.fem` — tetrahedral meshing and the Neo-Hookean TET10 FEM (§5.4.2);
* :mod:`laparo.cpc` — Conformal Perspective Correction of a frame (Ch. 4), point mapping;
* :mod:`laparo.mpm` — differentiable MLS-MPM (§5.2) and a ``torch.autograd.Function``.

Every function takes NumPy arrays (C-contiguous; float64 is used without a copy where the
Rust side reads slices) and raises ``TypeError`` / ``ValueError`` naming the bad argument.

Parallelism: heavy calls release the GIL and run on laparo's own rayon pool, which is
re-created in forked processes (DataLoader workers), so forking after using laparo is safe.
``set_num_threads(n)`` sets its size (0 = ``RAYON_NUM_THREADS`` or one thread per core); use
``set_num_threads(1)`` in a DataLoader's ``worker_init_fn`` to keep one thread per worker.

Memory: the extension keeps up to 256 MiB of freed large buffers (≥ 1 MiB) for reuse by the
next call on same-sized data (no page faults on warm buffers); ``set_buffer_cache_mb(n)``
changes the limit (0 = off).
"""
from ._laparo import __version__, get_num_threads, set_buffer_cache_mb, set_num_threads
from . import depth, cats, stereo, cpc, mpm, shard, features, register, fem

__all__ = ["__version__", "depth", "cats", "stereo", "cpc", "mpm", "shard", "features", "register", "fem", "set_num_threads", "get_num_threads", "set_buffer_cache_mb"]
