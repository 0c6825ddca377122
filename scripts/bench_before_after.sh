#!/usr/bin/env bash
# Before/after speed check of issue 10 ("no bench slower by more than 5 %"): the five benches of an
# old `laparo` binary (`BEFORE_BIN <group> bench ...`, i.e. built from the commit before the
# benchmarks left the CLI) and of the new `laparo-bench <group> ...` run INTERLEAVED on the same
# inputs, ROUNDS times (order swapped every round, so both see the same machine load), then one
# table of after/before ratios of the per-round figures (median over the rounds; < 1 = faster).
#
# usage: scripts/bench_before_after.sh BEFORE_BIN AFTER_BENCH_BIN [OUT]
#   e.g. scripts/bench_before_after.sh /tmp/laparo-before target/release/laparo-bench
#   env: SHARED=../shared  ROUNDS=3  MPM3D=0 (1: also the 3D thesis configuration, ~10 s a round)
#        THREADS (rayon threads of the depth/cpc benches; default all cores)
#        BENCHES="cpc stereo" (a subset of: depth cats stereo cpc mpm_2d mpm_3d)
#        ANALYSE_ONLY=1 (only re-read the outputs already in OUT)
# Raw outputs are kept in OUT (default /tmp/laparo-bench-before-after). Exit 1 when a figure is more
# than 5 % slower (median ratio > 1.05).
set -euo pipefail
if [ $# -lt 2 ]; then
  sed -n '2,15p' "$0" | sed 's/^# \{0,1\}//'
  exit 2
fi
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
BEFORE="$1"
AFTER="$2"
OUT="${3:-/tmp/laparo-bench-before-after}"
SHARED="${SHARED:-$ROOT/../shared}"
ROUNDS="${ROUNDS:-3}"
for b in "$BEFORE" "$AFTER"; do
  [ -x "$b" ] || { echo "error: $b is not an executable" >&2; exit 2; }
done
IMG="$SHARED/data/textures/chelsea.png"
CAL="$SHARED/data/calib/scared_ds1-3_endoscope_calibration.yaml"
LEFT="$SHARED/data/surgical/scared_pair_ds1-3/Left_Image.png"
RIGHT="$SHARED/data/surgical/scared_pair_ds1-3/Right_Image.png"
for f in "$IMG" "$CAL" "$LEFT" "$RIGHT"; do
  [ -f "$f" ] || { echo "error: input $f not found (set SHARED=/path/to/shared)" >&2; exit 2; }
done
mkdir -p "$OUT"
[ -n "${ANALYSE_ONLY:-}" ] || rm -f "$OUT"/*.out "$OUT"/*.out.json "$OUT"/*.out.cpu

# run VARIANT NAME ROUND: one bench of one binary, output in $OUT/NAME_VARIANT_ROUND.out
run() {
  local v="$1" name="$2" r="$3" o
  o="$OUT/${name}_${v}_${r}.out"
  local cmd
  if [ "$v" = before ]; then cmd=("$BEFORE"); else cmd=("$AFTER"); fi
  # before: `laparo <group> bench ARGS`; after: `laparo-bench <group> ARGS`.
  local group="${name%%_*}"
  if [ "$v" = before ]; then cmd+=("$group" bench); else cmd+=("$group"); fi
  case "$name" in
    depth) cmd+=(--reps 20 --json "$o.json") ;;
    cats) cmd+=(--image "$IMG" --runs 50 --threads 1) ;;
    stereo) cmd+=(--calib "$CAL" --width 1280 --height 1024 --left "$LEFT" --right "$RIGHT" --repeat 10) ;;
    cpc) cmd+=(--steps 4 --repeats 9 --json "$o.json") ;;
    mpm_2d) cmd+=(--dim 2 --repeats 5 --json) ;;
    mpm_3d) cmd+=(--dim 3 --repeats 3 --json) ;;
  esac
  # Process CPU time (user + system, s) of the whole command beside its own wall-time figures:
  # the same work on both sides, and less sensitive than wall time to other jobs on the machine.
  local TIMEFORMAT='%U %S'
  if [ -n "${THREADS:-}" ]; then
    { time RAYON_NUM_THREADS="$THREADS" "${cmd[@]}" >"$o" 2>/dev/null; } 2>"$o.cpu"
  else
    { time "${cmd[@]}" >"$o" 2>/dev/null; } 2>"$o.cpu"
  fi
}

if [ -n "${BENCHES:-}" ]; then
  read -r -a BENCHES <<<"$BENCHES"
else
  BENCHES=(depth cats stereo cpc mpm_2d)
  [ "${MPM3D:-0}" = 1 ] && BENCHES+=(mpm_3d)
fi
for r in $(seq 1 "$ROUNDS"); do
  [ -n "${ANALYSE_ONLY:-}" ] && break
  echo "== round $r/$ROUNDS, $(date -u +%H:%M:%S) UTC, load $(cut -d' ' -f1-3 /proc/loadavg)"
  for name in "${BENCHES[@]}"; do
    if [ $((r % 2)) = 1 ]; then order=(before after); else order=(after before); fi
    for v in "${order[@]}"; do
      run "$v" "$name" "$r"
    done
  done
done

python3 - "$OUT" "$ROUNDS" "${BENCHES[@]}" <<'PY'
import json, re, statistics, sys
out, rounds, benches = sys.argv[1], int(sys.argv[2]), sys.argv[3:]

def figures(name, path):
    """The figures of one bench output (lower is better), by name."""
    txt = open(path).read()
    if name == "depth":
        j = json.load(open(path + ".json"))["laparo"]
        return {"depth 1-thread min ms": j["min_ms"], "depth all-threads min ms": j["parallel_min_ms"],
                "depth s/image (1/throughput)": 1.0 / j["images_per_s_parallel"]}
    if name == "cats":
        j = json.loads(txt)
        return {"cats rgb u8 bilinear min ms": j["rgb_u8_bilinear"]["min_ms"],
                "cats f32 nearest min ms": j["f32_nearest"]["min_ms"]}
    if name == "stereo":
        m = re.search(r"stereoRectify-like ([0-9.]+) ms, maps \(both cameras\) ([0-9.]+) ms, .*remap \(both images\) ([0-9.]+) ms", txt)
        return {"stereo rectify ms": float(m.group(1)), "stereo maps ms": float(m.group(2)),
                "stereo remap ms": float(m.group(3))}
    if name == "cpc":
        row = json.load(open(path + ".json"))["rows"][0]
        return {"cpc 4px first frame min ms": row["min_ms_total"], "cpc 4px next frame min ms": row["min_ms_total_next"],
                "cpc 4px sweep20 min ms": row["min_ms_sweep20"], "cpc 4px first frame median ms": row["ms_total"],
                "cpc 4px next frame median ms": row["ms_total_next"]}
    if name.startswith("mpm"):
        j = json.loads(txt.strip().splitlines()[-1])
        d = name.split("_")[1]
        return {f"mpm {d} forward s": j["forward_s"], f"mpm {d} forward+backward s": j["forward_backward_s"]}
    raise ValueError(name)

def figures_cpu(name, path):
    f = figures(name, path)
    try:
        u, s_ = open(path + ".cpu").read().split()[-2:]
        f[f"{name} process CPU s"] = float(u) + float(s_)
    except (OSError, ValueError):
        pass
    return f

rows, worst = [], 0.0
for name in benches:
    per = {}
    for r in range(1, rounds + 1):
        try:
            b = figures_cpu(name, f"{out}/{name}_before_{r}.out")
            a = figures_cpu(name, f"{out}/{name}_after_{r}.out")
        except Exception as e:  # a failed run: report, do not hide
            print(f"{name} round {r}: could not read the outputs ({e})")
            continue
        for k in b:
            per.setdefault(k, []).append((b[k], a[k]))
    for k, v in per.items():
        ratios = [a / b for b, a in v]
        med = statistics.median(ratios)
        worst = max(worst, med)
        best = min(a for _, a in v) / min(b for b, _ in v)
        rows.append((k, min(b for b, _ in v), min(a for _, a in v), med, min(ratios), max(ratios), best))
# Two estimators: the median over rounds of the per-round ratio, and the ratio of the best
# (lowest) figure of each side over all rounds, the less load-sensitive one on a shared machine.
print(f"{'figure':36} {'best before':>11} {'best after':>11} {'best ratio':>10} {'median ratio':>12} {'(range over rounds)':>20}")
worst_best = 0.0
for k, b, a, med, lo, hi, best in rows:
    worst_best = max(worst_best, best)
    flag = "  SLOWER > 5 %" if best > 1.05 else ""
    print(f"{k:36} {b:11.4g} {a:11.4g} {best:10.3f} {med:12.3f} {lo:9.3f} – {hi:<8.3f}{flag}")
print(f"worst best-of-rounds ratio {worst_best:.3f}, worst median ratio {worst:.3f} "
      f"({'within' if worst_best <= 1.05 else 'OUTSIDE'} the 5 % allowance by the best-of-rounds ratio)")
sys.exit(0 if worst_best <= 1.05 else 1)
PY
echo "raw outputs: $OUT"
