#!/usr/bin/env bash
# Not CI. Render a synthetic orbit (bumpy organ-like surface, real texture, yaw −24°…+24°),
# export SIFT features + exhaustive matches to a COLMAP database with `laparo features colmap`,
# and run Debian's `colmap mapper` (3.8, CPU) on it. Usage: scripts/colmap_orbit.sh [OUT_DIR]
# Needs: cargo build --release -p laparo; apt-get install colmap.
set -euo pipefail
OUT=${1:-/tmp/laparo_colmap_orbit}
LAPARO=${LAPARO:-target/release/laparo}
TEX=${TEX:-gravel.png}
command -v colmap >/dev/null || { echo "colmap not found (apt-get install colmap)"; exit 2; }
rm -rf "$OUT"; mkdir -p "$OUT/images" "$OUT/render" "$OUT/sparse"
for yaw in -24 -18 -12 -6 0 6 12 18 24; do
  "$LAPARO" cpc scene --surface bumpy --tilt 20 --yaw="$yaw" --texture "$TEX" --out "$OUT/render/$yaw" >/dev/null
  cp "$OUT/render/$yaw/image.png" "$OUT/images/$(printf 'yaw_%+03d.png' "$yaw")"
done
# The renderer's pinhole intrinsics (same for every view).
K=$(python3 -c "import json,sys; k=json.load(open(sys.argv[1])); print(f\"{k['fx']},{k['fy']},{k['cx']},{k['cy']}\")" "$OUT/render/0/intrinsics.json")
"$LAPARO" features colmap --images "$OUT/images" --detector sift --intrinsics "$K" --colmap-db "$OUT/database.db"
colmap mapper --database_path "$OUT/database.db" --image_path "$OUT/images" --output_path "$OUT/sparse" \
  --Mapper.ba_refine_focal_length 0 --Mapper.ba_refine_principal_point 0 --Mapper.ba_refine_extra_params 0 \
  --Mapper.num_threads 2 > "$OUT/mapper.log" 2>&1 || { tail -20 "$OUT/mapper.log"; exit 1; }
MODEL=$(ls -d "$OUT"/sparse/*/ | head -1)
colmap model_analyzer --path "$MODEL" 2>&1 | tee "$OUT/model_analyzer.txt"
