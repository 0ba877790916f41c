#!/usr/bin/env bash
# The whole test suite: unit, integration, doc and CLI tests, and every bench
# run once in test mode. This is what CI (.ci/run) runs.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
# No two files of a crate import each other in a circle (issue 38).
for crate in crates/*/src src; do python3 scripts/module_cycles.py "$crate"; done
cargo test --workspace --locked --all-targets
cargo test --workspace --locked --doc
