#!/usr/bin/env bash
# Times probecal's default run against benches/opencv_reference.py (a plain
# OpenCV-Python pipeline of the same stages on the same cached frames), the two
# interleaved, ROUNDS rounds each, wall time and peak memory by /usr/bin/time.
# Needs: a release build (cargo build --release --bin probecal), the rendered
# dataset (scripts/main-job.sh renders it), and `pip install
# opencv-python-headless numpy`.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
rounds="${ROUNDS:-3}"
dataset=datasets/hemisphere_checkerboard__dataset3
out="$(mktemp -d)"
for round in $(seq "$rounds"); do
  /usr/bin/time -f "probecal round $round: %e s wall, %U s user, %M KB peak" \
    "$CARGO_TARGET_DIR/release/probecal" run experiments/hemisphere_checkerboard.yaml --out "$out" --force --quiet
  /usr/bin/time -f "opencv-python round $round: %e s wall, %U s user, %M KB peak" \
    python3 benches/opencv_reference.py "$dataset" > "$out/python.txt"
done
cat "$out/python.txt"
rm -rf "$out"
