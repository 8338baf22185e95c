#!/usr/bin/env bash
# Sets up the machine, then runs the whole test suite (unit, integration, real
# OpenCV data from ../shared/data).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
source scripts/env.sh
cargo test "$@"
