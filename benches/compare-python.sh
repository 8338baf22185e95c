#!/usr/bin/env bash
# Times probecal's default run against benches/opencv_reference.py (a plain
# OpenCV-Python pipeline of the same stages on the same cached frames),
# interleaved, ROUNDS rounds each, wall time and peak memory by /usr/bin/time.
# The script runs under `python3` with the OpenCV it finds there (PyPI's:
# `pip install opencv-python-headless numpy`) and, when SAME_OPENCV_PYTHON
# (default /usr/bin/python3) imports Debian's python3-opencv, under that too:
# the same libopencv build probecal links, so that comparison is of the
# pipelines alone. Needs the rendered dataset (scripts/main-job.sh renders it).
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
# Each Python with its OpenCV's version, named by it.
declare -A pythons
pythons["opencv-python $(python3 -c 'import cv2; print(cv2.__version__)')"]=python3
same="${SAME_OPENCV_PYTHON:-/usr/bin/python3}"
if version="$("$same" -c 'import cv2; print(cv2.__version__)' 2>/dev/null)"; then
  pythons["opencv-python $version (system)"]="$same"
fi
for round in $(seq "$rounds"); do
  /usr/bin/time -a -o "$times" -f "probecal round $round: %e s wall, %U s user, %M KB peak" \
    "$CARGO_TARGET_DIR/release/probecal" run experiments/hemisphere_checkerboard.yaml --out "$out" --force --quiet
  for name in "${!pythons[@]}"; do
    /usr/bin/time -a -o "$times" -f "$name round $round: %e s wall, %U s user, %M KB peak" \
      "${pythons[$name]}" benches/opencv_reference.py "$dataset" > "$out/python.txt"
  done
done
cat "$times" "$out/python.txt"
# The medians of the rounds' wall times and their ratio.
python3 - "$times" <<'PY'
import statistics, sys
walls = {}
for line in open(sys.argv[1]):
    tool, rest = line.split(" round ", 1)
    walls.setdefault(tool, []).append(float(rest.split(": ", 1)[1].split(" s wall")[0]))
ours = statistics.median(walls.pop("probecal"))
for tool, runs in sorted(walls.items()):
    theirs = statistics.median(runs)
    print(f"median wall: probecal {ours:.2f} s, {tool} {theirs:.2f} s: "
          f"probecal is {theirs / ours:.2f} times as fast ({len(runs)} rounds)")
PY
rm -rf "$out"
