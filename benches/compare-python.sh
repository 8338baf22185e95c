#!/usr/bin/env bash
# Times probecal's default run against benches/opencv_reference.py (a plain
# OpenCV-Python pipeline of the same stages on the same cached frames), the two
# interleaved, ROUNDS rounds each, wall time and peak memory by /usr/bin/time.
# Needs: the rendered
# dataset (scripts/main-job.sh renders it), and `pip install
# opencv-python-headless numpy`.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
# `cargo bench` leaves its own build of the binary in the release folder: time
# the release profile's.
cargo build --release --quiet --bin probecal
rounds="${ROUNDS:-3}"
dataset=datasets/hemisphere_checkerboard__dataset3
out="$(mktemp -d)"
times="$out/times.txt"
for round in $(seq "$rounds"); do
  /usr/bin/time -a -o "$times" -f "probecal round $round: %e s wall, %U s user, %M KB peak" \
    "$CARGO_TARGET_DIR/release/probecal" run experiments/hemisphere_checkerboard.yaml --out "$out" --force --quiet
  /usr/bin/time -a -o "$times" -f "opencv-python round $round: %e s wall, %U s user, %M KB peak" \
    python3 benches/opencv_reference.py "$dataset" > "$out/python.txt"
done
cat "$times" "$out/python.txt"
# The medians of the rounds' wall times and their ratio.
python3 - "$times" <<'PY'
import statistics, sys
walls = {}
for line in open(sys.argv[1]):
    tool, rest = line.split(" round ", 1)
    walls.setdefault(tool, []).append(float(rest.split(": ", 1)[1].split(" s wall")[0]))
ours, theirs = statistics.median(walls["probecal"]), statistics.median(walls["opencv-python"])
print(f"median wall: probecal {ours:.2f} s, opencv-python {theirs:.2f} s: "
      f"probecal is {theirs / ours:.2f} times as fast ({len(walls['probecal'])} rounds)")
PY
rm -rf "$out"
