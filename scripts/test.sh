#!/usr/bin/env bash
# Sets up the machine, then runs the whole test suite: the fast tier (what a
# plain `cargo test` runs) and the full tier (tests that need ../shared/data,
# pdflatex or Chromium, or run whole experiments; `#[ignore]`d with their reason).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
source scripts/env.sh
cargo test --no-fail-fast "$@" -- --include-ignored
