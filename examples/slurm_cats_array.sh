#!/usr/bin/env bash
# CATS augmentation of a large stereo dataset as a Slurm job array: task I of N runs
# `laparo cats augment --shard I/N`; all tasks write into the same --out (a shared file
# system), and together produce exactly the files of one unsharded run.
#
#   sbatch --array=0-15 examples/slurm_cats_array.sh /data/sceneflow /scratch/sceneflow_cats
#
# Then the same for `laparo depth perturb --shard I/N`, or for `laparo depth eval --shard I/N`
# followed by one `laparo depth eval <same options> --merge-shards N` (see the README).
#SBATCH --job-name=laparo-cats
#SBATCH --cpus-per-task=8
#SBATCH --mem=8G
#SBATCH --time=02:00:00
#SBATCH --output=laparo-cats-%A_%a.log
set -euo pipefail
INPUT=${1:?input dataset root}
OUT=${2:?output root}
LAYOUT=${LAYOUT:-sceneflow}
SEED=${SEED:-0}
N=${SLURM_ARRAY_TASK_COUNT:?run with sbatch --array=0-(N-1)}
I=${SLURM_ARRAY_TASK_ID:?run with sbatch --array}
export RAYON_NUM_THREADS=${SLURM_CPUS_PER_TASK:-1}
exec laparo cats augment --input "$INPUT" --layout "$LAYOUT" --out "$OUT" --seed "$SEED" \
    ${CONFIG:+--config "$CONFIG"} --shard "$I/$N"
