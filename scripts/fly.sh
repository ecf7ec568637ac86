#!/usr/bin/env bash
# The main job (README.md): build and fly the built-in default mission in the built-in sim,
# every role its own process. Extra arguments go to `aeris run` (e.g. --json, a workflow file).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup-build-deps.sh
# The first build compiles iceoryx2, ONNX Runtime's bindings and llama.cpp: ~10 minutes on a
# fresh 2-core machine, seconds after. Cargo's own progress (a bar on a terminal, a line per
# crate otherwise) shows it is working.
if [ ! -x target/release/aeris ]; then
    echo "fly: building aeris in release mode (first build: ~10 min on 2 cores; later: seconds)" >&2
fi
cargo build --release --bin aeris
echo "fly: starting the flight" >&2
exec target/release/aeris run "$@"
