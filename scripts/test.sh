#!/usr/bin/env bash
# The README's test command. Sets up the machine, then runs the fast tier (what a
# plain `cargo test` runs) and the full tier (tests that need ../shared/data or run
# experiments; `#[ignore]`d with their reason), except the long reproductions of
# scripts/long-tests, which scripts/reproduce.sh runs. A test whose input is
# absent says so and skips. Formatting and clippy (warnings denied) run first.
# Extra arguments go to cargo test.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
source scripts/env.sh
mapfile -t long < <(grep -v '^#' scripts/long-tests | grep .)
targets=(--lib --bins)
for file in tests/*.rs; do
  name=$(basename "$file" .rs)
  [[ " ${long[*]} " == *" $name "* ]] || targets+=(--test "$name")
done
started=$(date +%s)
# The build and the checks: the test binaries and the probecal binary they run,
# as the tests below use them (a `cargo build` first compiled the crate twice).
cargo test --no-run "${targets[@]}" "$@"
# The code's shape: formatted, no lint (functions over 100 lines among them, see clippy.toml).
cargo fmt --check
cargo clippy --all-targets -- -D warnings
built=$(date +%s)
cargo test --no-fail-fast "${targets[@]}" "$@" -- --include-ignored
cargo test --no-fail-fast --doc "$@"
echo "tests: $(( $(date +%s) - built )) s after $(( built - started )) s of build, format and lint checks"
