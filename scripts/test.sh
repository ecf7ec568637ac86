#!/usr/bin/env bash
# The test command (README.md, and exactly what CI runs via .ci/run):
# installs the build and test dependencies and the models (scripts/provision-models.sh), checks
# formatting, builds the workspace and the `aeris` binary the end-to-end tests spawn under
# clippy's lints, and runs every test of the workspace.
set -euo pipefail
cd "$(dirname "$0")/.."

scripts/setup-build-deps.sh
scripts/setup-test-deps.sh
scripts/provision-models.sh
export AERIS_PYTHON="$PWD/.venv/bin/python"

# The build and the test run resolve the build-dependencies' features differently, so cargo
# runs llama-cpp-sys-2's build script more than once; ccache turns the later compilations of
# llama.cpp into cache hits (~6 min each on 2 cores otherwise).
export CMAKE_C_COMPILER_LAUNCHER=ccache CMAKE_CXX_COMPILER_LAUNCHER=ccache
# A clean clone gains nothing from incremental state (~1 GB in target/): keep the disk small.
export CARGO_INCREMENTAL=0
export CCACHE_DIR="${CCACHE_DIR:-$HOME/.cache/aeris/ccache}" CCACHE_NOHASHDIR=1 CCACHE_BASEDIR="$PWD"

# Lints and build in one compilation: clippy-driver is rustc with clippy's lints added (what
# `cargo clippy` runs, in check mode), so it compiles our crates as it lints them, and the
# dependencies are compiled once instead of checked for clippy and compiled again for the
# build (on a fresh 2-core Xeon: lints and build 681 s, against 575 s of clippy and 284 s of
# build when apart; their build scripts, proc macros and C libraries were shared already).
# CLIPPY_ARGS carries `-D warnings` to it, as `cargo clippy -- -D warnings` does; dependencies
# are not linted (cargo caps their lints).
# Every cargo command below shares these settings, so `cargo test` builds nothing again.
CLIPPY_DRIVER="$(dirname "$(rustup which cargo-clippy 2>/dev/null || command -v cargo-clippy)")/clippy-driver"
if [ ! -x "$CLIPPY_DRIVER" ]; then
    echo "test: clippy is not installed (rustup component add clippy)" >&2
    exit 1
fi
export RUSTC_WORKSPACE_WRAPPER="$CLIPPY_DRIVER" CLIPPY_ARGS="-D__CLIPPY_HACKERY__warnings__CLIPPY_HACKERY__"

# Each step says what it does; cargo shows its own progress (the first build compiles
# llama.cpp, iceoryx2 and zenoh: ~6 min on 2 cores).
echo "test: 1/3 formatting (cargo fmt --check)" >&2
cargo fmt --all -- --check
echo "test: 2/3 building and linting (clippy -D warnings) the workspace and the aeris binary the end-to-end tests spawn" >&2
# the vehicle build (no simulator, no renderer) must keep compiling, lint-free; built first,
# since the workspace build after it leaves target/debug/aeris the full binary the tests spawn
cargo build -p aeris --no-default-features
cargo build --workspace --all-targets
echo "test: 3/3 every test of the workspace" >&2
cargo test --workspace --no-fail-fast -- --test-threads=2
