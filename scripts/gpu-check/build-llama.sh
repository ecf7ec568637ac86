#!/usr/bin/env bash
# Build llama_offload (the llama.cpp half of the GPU check) with CUDA, against the llama.cpp
# sources aeris links (llama-cpp-sys-2's vendored copy).
#
# Usage: scripts/gpu-check/build-llama.sh LLAMA_SRC BUILD_DIR [CUDA_ARCH]
#   LLAMA_SRC  the vendored llama.cpp (~/.cargo/registry/src/*/llama-cpp-sys-2-*/llama.cpp)
#   CUDA_ARCH  the GPU's compute capability for nvcc (default: native, the GPU of this machine)
# Needs CMake and the CUDA toolkit (nvcc). Prints the harness's path last.
set -euo pipefail
src=${1:?usage: build-llama.sh LLAMA_SRC BUILD_DIR [CUDA_ARCH]}
build=${2:?usage: build-llama.sh LLAMA_SRC BUILD_DIR [CUDA_ARCH]}
arch=${3:-native}
here=$(cd "$(dirname "$0")" && pwd)
generator=()
command -v ninja >/dev/null && generator=(-G Ninja)
cmake -S "$here" -B "$build" "${generator[@]}" -DLLAMA_SRC="$src" -DCMAKE_BUILD_TYPE=Release \
    -DGGML_CUDA=ON -DGGML_CUDA_NCCL=OFF -DGGML_CUDA_FA=OFF -DCMAKE_CUDA_ARCHITECTURES="$arch" \
    -DGGML_NATIVE=ON
cmake --build "$build" --target llama_offload -j "$(nproc)"
echo "$build/llama_offload"
