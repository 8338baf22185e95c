#!/usr/bin/env bash
# Sets up the machine, then runs every default experiment end to end into reports/
# (one folder per experiment, index.html, and compare.md/compare.html side by side),
# then the volume reconstructions of PLUS's data (reports/reconstruction/) and the
# refinements from the images of the fCal recording (reports/selfcal/).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
source scripts/env.sh
cargo build --bin probecal
"$CARGO_TARGET_DIR/debug/probecal" compare experiments/*.yaml --out reports --force
bash scripts/reconstructions.sh reports
bash scripts/selfcal.sh reports
