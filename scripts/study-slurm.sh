#!/usr/bin/env bash
# A Monte Carlo study as a Slurm job array: one array task per shard, then the
# merge once every task has finished. Run from the checkout on a login node:
#
#   scripts/study-slurm.sh experiments/hemisphere_checkerboard.yaml 50 5 reports/study
#
# (manifest, seeds, shards, output folder). Each task runs
# `probecal study --shard K/N` into <out>/shards/; the dependent job runs
# `probecal study merge`, which writes the same study.json and pages as one
# unsharded run (it refuses shards that are not the N slices of one study).
# The binary must be built first (cargo build --release --bin probecal) on a
# file system the nodes share.
set -euo pipefail
cd "$(dirname "$0")/.."
manifest="${1:?manifest}"
seeds="${2:-50}"
shards="${3:-5}"
out="${4:-reports/study}"
probecal="${PROBECAL:-$(pwd)/target/release/probecal}"
[ -x "$probecal" ] || { echo "no probecal binary at $probecal (set PROBECAL)" >&2; exit 2; }
mkdir -p "$out/shards"
array=$(sbatch --parsable --array=1-"$shards" --cpus-per-task=2 --job-name=probecal-study \
  --output="$out/shards/slurm-%A_%a.log" \
  --wrap="'$probecal' study '$manifest' --seeds $seeds --shard \${SLURM_ARRAY_TASK_ID}/$shards --out '$out/shards' --datasets \"\${TMPDIR:-/tmp}/probecal-datasets-\${SLURM_ARRAY_JOB_ID}-\${SLURM_ARRAY_TASK_ID}\"")
sbatch --parsable --dependency=afterok:"$array" --job-name=probecal-study-merge \
  --output="$out/shards/slurm-merge-%j.log" \
  --wrap="'$probecal' study merge '$out'/shards/shard_*_of_${shards}.yaml --out '$out'"
echo "submitted array job $array ($shards shards) and its merge"
