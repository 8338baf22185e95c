#!/usr/bin/env bash
# Runs the main job's command into a copy of the committed reports/ and fails
# when any committed file differs from what it writes (provenance.json, which
# records times and machine facts, is not committed), then runs the accuracy
# gate on the fresh runs. Expects a built binary (scripts/test.sh builds it).
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
probecal="$CARGO_TARGET_DIR/debug/probecal"
fresh="$(mktemp -d)/reports"
cp -r reports "$fresh"
"$probecal" compare experiments/*.yaml --out "$fresh" --force --quiet
bash scripts/reconstructions.sh "$fresh"
bash scripts/selfcal.sh "$fresh"
if ! diff -r --exclude=provenance.json --exclude=.probecal.lock --exclude=volume.mha reports "$fresh"; then
  echo "reports/ differs from what the main job writes now: regenerate it with scripts/main-job.sh and commit" >&2
  exit 1
fi
echo "reports/: every committed file regenerates byte-identical"
"$probecal" check "$fresh"
