#!/usr/bin/env bash
# Same-session speed comparison of laparo (the `laparo-bench` binary) against the peer scripts of ../shared/bench/ for the two
# issue goals measured per iteration / frame: CPC (numpy/scipy `cpc_ref/bench.py`, 4 px) and MPM 2D
# and 3D (DiffTaichi `taichi_mpm/mpm{2,3}d_rods.py`). Peer and laparo alternate, ROUNDS times, so
# that both see the same machine load; every raw output is kept in OUT.
#
# usage: scripts/bench_vs_peers.sh [OUT]          (default /tmp/laparo-bench-vs-peers)
#   env: VENV=/tmp/venv  SHARED=../shared  ROUNDS=2  MPM3D=1 (also the 3D thesis configuration;
#        DiffTaichi compiles its 3D gradient kernels for minutes)
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
OUT="${1:-/tmp/laparo-bench-vs-peers}"
VENV="${VENV:-/tmp/venv}"
SHARED="${SHARED:-$ROOT/../shared}"
ROUNDS="${ROUNDS:-2}"
mkdir -p "$OUT"
if [ ! -x "$VENV/bin/python" ]; then
  python3 -m venv "$VENV" && "$VENV/bin/pip" install -q numpy scipy libigl taichi
fi
(cd "$ROOT" && cargo build --release -q -p laparo-bench)
BENCH="$ROOT/target/release/laparo-bench"
# CPC peer scripts run from a copy (scene.py writes scene.npz next to itself).
mkdir -p "$OUT/cpc_ref"
cp "$SHARED"/bench/cpc_ref/*.py "$OUT/cpc_ref/"
(cd "$OUT/cpc_ref" && [ -f scene.npz ] || "$VENV/bin/python" scene.py >/dev/null)
TM="$SHARED/bench/taichi_mpm"
for r in $(seq 1 "$ROUNDS"); do
  echo "== round $r, $(date -u +%H:%M:%S) UTC, load $(cut -d' ' -f1-3 /proc/loadavg)"
  (cd "$OUT/cpc_ref" && "$VENV/bin/python" bench.py 4 >"$OUT/cpc_peer_$r.json" 2>&1)
  "$BENCH" cpc --scene-npz "$OUT/cpc_ref/scene.npz" --steps 4 --repeats 15 --json "$OUT/cpc_laparo_$r.json" \
    >"$OUT/cpc_laparo_$r.txt"
  "$VENV/bin/python" "$TM/mpm2d_rods.py" --n-grid 120 --steps 200 --iters 10 --fwd-reps 5 --lr 1e4 \
    >"$OUT/mpm2d_peer_$r.txt" 2>&1
  "$BENCH" mpm --dim 2 --repeats 7 --json >"$OUT/mpm2d_laparo_$r.json"
  "$BENCH" mpm --dim 2 --repeats 7 --threads 1 --json >"$OUT/mpm2d_laparo_t1_$r.json"
  if [ "${MPM3D:-0}" = 1 ]; then
    "$VENV/bin/python" "$TM/mpm3d_rods.py" --n-grid 120 --steps 200 --iters 4 --fwd-reps 2 --lr 4e4 \
      >"$OUT/mpm3d_peer_$r.txt" 2>&1
    "$BENCH" mpm --dim 3 --repeats 3 --json >"$OUT/mpm3d_laparo_$r.json"
  fi
  "$VENV/bin/python" - "$OUT" "$r" <<'PY'
import json, sys, re
out, r = sys.argv[1], sys.argv[2]
def result(path):
    for line in open(path):
        if line.startswith("RESULT "):
            return json.loads(line[7:])
txt = open(f"{out}/cpc_peer_{r}.json").read()
m = re.search(r'"t_total_spsolve":\s*([0-9.e-]+)', txt)
py_total = float(m.group(1)) * 1e3 if m else float("nan")
rs = json.load(open(f"{out}/cpc_laparo_{r}.json"))
row = rs["rows"][0]
def g(k):
    return row.get(k, float("nan"))
mas_first = g("ms_mesh") + g("ms_assemble") + g("ms_solve")
mas_next = g("ms_mesh_next") + g("ms_assemble_next") + g("ms_solve_next")
print(f"cpc 4 px: laparo frame (mesh+asm+solve+warp) first {g('ms_total'):.2f} ms, next {g('ms_total_next'):.2f} ms; "
      f"mesh+asm+solve first {mas_first:.2f} / next {mas_next:.2f} ms vs bench.py {py_total:.1f} ms "
      f"({py_total / mas_first:.1f}x / {py_total / mas_next:.1f}x)")
t2 = result(f"{out}/mpm2d_peer_{r}.txt")
l2 = json.load(open(f"{out}/mpm2d_laparo_{r}.json"))
l1 = json.load(open(f"{out}/mpm2d_laparo_t1_{r}.json"))
print(f"mpm 2D: DiffTaichi median {t2['iter_median_s']:.3f} s (min {t2['iter_min_s']:.3f}), {t2['peak_rss_mb']:.0f} MiB; "
      f"laparo {l2['forward_backward_s']:.4f} s on 2 threads ({t2['iter_median_s'] / l2['forward_backward_s']:.2f}x), "
      f"{l1['forward_backward_s']:.4f} s on 1 ({t2['iter_median_s'] / l1['forward_backward_s']:.2f}x), {l2['peak_rss_mb']:.0f} MiB")
try:
    t3 = result(f"{out}/mpm3d_peer_{r}.txt")
    l3 = json.load(open(f"{out}/mpm3d_laparo_{r}.json"))
    print(f"mpm 3D: DiffTaichi median {t3['iter_median_s']:.2f} s, compile bwd {t3.get('compile_bwd_s', float('nan')):.0f} s; "
          f"laparo {l3['forward_backward_s']:.3f} s ({t3['iter_median_s'] / l3['forward_backward_s']:.1f}x)")
except (FileNotFoundError, TypeError):
    pass
PY
done
echo "raw outputs: $OUT"
