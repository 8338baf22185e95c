#!/usr/bin/env bash
# The long reproductions, after scripts/test.sh: the first seed of every committed
# study, the sharded study, the reports in pdflatex and Chromium, the measured constants (the test files
# of scripts/long-tests), then the main job into a copy of reports/ (every
# committed file must regenerate byte-identical) and the accuracy gate against
# the committed baselines (scripts/check-reports.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
source scripts/env.sh
started=$(date +%s)
cargo build --all-targets
targets=()
while read -r name; do
  targets+=(--test "$name")
done < <(grep -v '^#' scripts/long-tests | grep .)
cargo test --no-fail-fast "${targets[@]}" "$@" -- --include-ignored
bash scripts/check-reports.sh
echo "reproductions: $(( $(date +%s) - started )) s"
