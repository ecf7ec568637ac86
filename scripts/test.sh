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

# clippy, build and test each resolve the build-dependencies' features differently, so cargo
# runs llama-cpp-sys-2's build script three times; ccache turns the second and third
# compilations of llama.cpp into cache hits (~6 min each on 2 cores otherwise).
export CMAKE_C_COMPILER_LAUNCHER=ccache CMAKE_CXX_COMPILER_LAUNCHER=ccache
# A clean clone gains nothing from incremental state (~1 GB in target/): keep the disk small.
export CARGO_INCREMENTAL=0
export CCACHE_DIR="${CCACHE_DIR:-$HOME/.cache/aeris/ccache}" CCACHE_NOHASHDIR=1 CCACHE_BASEDIR="$PWD"

cargo fmt --all -- --check
cargo clippy --workspace --all-targets --quiet -- -D warnings
cargo build --workspace --all-targets --quiet
cargo test --workspace --no-fail-fast -- --test-threads=2
