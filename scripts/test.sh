#!/usr/bin/env bash
# The test command (README.md, and exactly what CI runs via .ci/run):
# installs the build and test dependencies and the models (scripts/provision-models.sh), checks formatting and lints, builds the `aeris` binary the
# end-to-end tests spawn, and runs every test of the workspace.
set -euo pipefail
cd "$(dirname "$0")/.."

scripts/setup-build-deps.sh
scripts/setup-test-deps.sh
scripts/provision-models.sh
export AERIS_PYTHON="$PWD/.venv/bin/python"

cargo fmt --all -- --check
cargo clippy --workspace --all-targets --quiet -- -D warnings
cargo build --workspace --bins --quiet
cargo test --workspace --no-fail-fast -- --test-threads=2
