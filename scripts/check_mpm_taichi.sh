#!/usr/bin/env bash
# Cross-check laparo-mpm against the DiffTaichi reference scripts (../shared/bench/taichi_mpm/).
#
# Runs the reference (f64) from a non-trivial initial velocity field, dumps the initial particles,
# the final positions after T steps, the landmark loss and its gradient with respect to the initial
# velocities (Taichi autodiff) as a JSON fixture, then lets `laparo mpm taichi-compare` rerun the same
# scene and report the max position difference (in cell widths) and the gradient relative error.
#
# usage: scripts/check_mpm_taichi.sh [OUTDIR]      (default /tmp/mpm-taichi-check)
#   env: VENV=/tmp/venv-mpm  BENCH=../shared/bench/taichi_mpm  FULL=1 (also 2D 6.4k and 3D thesis config)
#   UPDATE_FIXTURE=1 copies the small 2D fixture into crates/laparo-mpm/tests/fixtures/.
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
OUT="${1:-/tmp/mpm-taichi-check}"
VENV="${VENV:-/tmp/venv-mpm}"
BENCH="${BENCH:-$ROOT/../shared/bench/taichi_mpm}"
mkdir -p "$OUT"
if [ ! -x "$VENV/bin/python" ]; then
  python3 -m venv "$VENV" && "$VENV/bin/pip" install -q taichi numpy
fi
cat > "$OUT/dump_taichi.py" <<'PY'
"""Run a DiffTaichi reference script's kernels from a given initial velocity field; dump a fixture."""
import json, runpy, sys
import numpy as np
script, out, vscale = sys.argv[1], sys.argv[2], float(sys.argv[3])
sys.argv = [script] + sys.argv[4:] + ["--iters", "0", "--fwd-reps", "0", "--f64"]
g = runpy.run_path(script, run_name="__main__")
pos0, T, ti = g["pos0"], g["T"], g["ti"]
dim = pos0.shape[1]
c = pos0.mean(axis=0)
r = pos0 - c
# pull apart along x, shear and a smooth wobble: large, non-uniform deformation
v0 = np.zeros_like(pos0)
v0[:, 0] = vscale * (8.0 * r[:, 0] + 2.0 * r[:, 1])
v0[:, 1] = vscale * (-3.0 * r[:, 0] + 0.3 * np.sin(40.0 * r[:, 0]))
if dim == 3:
    v0[:, 2] = vscale * (1.5 * r[:, 1] - 2.0 * r[:, 2])
g["init_v"].from_numpy(v0)
loss = g["forward_only"]()
xT = g["x"].to_numpy()[T]
with ti.ad.Tape(loss=g["loss"]):
    g["forward"]()
grad = g["init_v"].grad.to_numpy()
loss_tape = float(g["loss"][None])
fx = {
    "source": script.split("/")[-1], "dim": dim, "n_grid": g["n_grid"], "dt": g["dt"], "steps": T,
    "youngs_modulus": g["E"], "poisson_ratio": g["nu"], "density": g["args"].rho, "gravity": g["args"].gravity,
    "particle_volume": g["p_vol"], "particle_mass": g["p_mass"], "bound": g["bound"],
    "positions": pos0.tolist(), "velocities": v0.tolist(),
    "landmarks": [int(i) for i in g["lm"]], "targets": g["tgt"].tolist(),
    "final_positions": xT.tolist(), "loss": loss_tape, "loss_forward_only": loss, "grad_velocities": grad.tolist(),
}
json.dump(fx, open(out, "w"))
print(f"wrote {out}: {len(pos0)} particles, loss {loss:.9g}, |grad| {np.linalg.norm(grad):.6g}")
PY
run() {  # name script vscale args...
  local name="$1" script="$2" vs="$3"; shift 3
  echo "== $name: DiffTaichi ($script $*)"
  "$VENV/bin/python" "$OUT/dump_taichi.py" "$BENCH/$script" "$OUT/$name.json" "$vs" "$@"
  echo "== $name: laparo"
  "$ROOT/target/release/laparo" mpm taichi-compare --fixture "$OUT/$name.json"
}
cargo build --release -p laparo -q --manifest-path "$ROOT/Cargo.toml"
run small2d mpm2d_rods.py 1.0 --n-grid 64 --steps 200 --nx 24 --ny 20 --n-landmarks-per-lip 10
run small3d mpm3d_rods.py 1.0 --n-grid 48 --steps 200 --nx 8 --ny 10 --nz 8 --n-landmarks-per-lip 5
if [ "${FULL:-0}" = 1 ]; then
  run full2d mpm2d_rods.py 1.0 --n-grid 120 --steps 200
  run full3d mpm3d_rods.py 1.0 --n-grid 120 --steps 200
fi
if [ "${UPDATE_FIXTURE:-0}" = 1 ]; then
  mkdir -p "$ROOT/crates/laparo-mpm/tests/fixtures"
  cp "$OUT/small2d.json" "$ROOT/crates/laparo-mpm/tests/fixtures/taichi_small2d.json"
  cp "$OUT/small3d.json" "$ROOT/crates/laparo-mpm/tests/fixtures/taichi_small3d.json"
  echo "fixtures updated"
fi
