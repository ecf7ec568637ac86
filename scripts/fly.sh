#!/usr/bin/env bash
# The main job (README.md): build and fly the built-in default mission in the built-in sim,
# every role its own process. Extra arguments go to `aeris run` (e.g. --json, a workflow file).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup-build-deps.sh
cargo build --release --bin aeris --quiet
exec target/release/aeris run "$@"
