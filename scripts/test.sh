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

# Each step says what it does; cargo shows its own progress (the first clippy and build
# compile llama.cpp and iceoryx2: ~10 min on 2 cores).
echo "test: 1/4 formatting (cargo fmt --check)" >&2
cargo fmt --all -- --check
echo "test: 2/4 lints (cargo clippy -D warnings)" >&2
cargo clippy --workspace --all-targets -- -D warnings
# the vehicle build (no simulator, no renderer) must keep compiling
cargo clippy -p aeris --no-default-features -- -D warnings
echo "test: 3/4 building the workspace and the aeris binary the end-to-end tests spawn" >&2
cargo build --workspace --all-targets
echo "test: 4/4 every test of the workspace" >&2
cargo test --workspace --no-fail-fast -- --test-threads=2
