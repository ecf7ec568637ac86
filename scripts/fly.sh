#!/usr/bin/env bash
# The main job (README.md): build and fly the built-in default mission in the built-in sim,
# every role its own process. Extra arguments go to `aeris run` (e.g. --json, a workflow file).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup-build-deps.sh
# The first build compiles iceoryx2, zenoh, GStreamer's and ONNX Runtime's bindings and
# llama.cpp: 18 min 25 s on a fresh 2-core VM (issue 35's measurement; 19 min 49 s with the
# Debian packages), seconds after. Cargo's own progress (a bar on a terminal, a line per
# crate otherwise) shows it is working.
if [ ! -x target/release/aeris ]; then
    echo "fly: building aeris in release mode (first build: ~20 min on 2 cores; later: seconds)" >&2
fi
cargo build --release --bin aeris
echo "fly: starting the flight" >&2
exec target/release/aeris run "$@"
