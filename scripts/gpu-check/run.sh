#!/usr/bin/env bash
# The GPU check of the accelerator executors, on a machine with an NVIDIA GPU:
#   1. `aeris bench models` on the CPU and with --accelerator cuda:0 (ONNX Runtime's CUDA
#      provider), idle and beside busy threads;
#   2. the default flight (workflows/default.toml) with a YOLO detector on a `cuda:0`
#      executor (OUT_DIR/gpu-flight.toml) and the same flight with the detector on CPUs
#      (OUT_DIR/cpu-flight.toml), flown side by side;
#   3. llama.cpp's offload: llama_offload.cpp (the llama.cpp aeris links, the model the
#      reasoning role loads) with no layer and every layer on the GPU, idle and loaded.
#
# Usage: scripts/gpu-check/run.sh OUT_DIR
# Environment:
#   AERIS             the aeris binary (default: target/release/aeris)
#   AERIS_ONNXRUNTIME an ONNX Runtime with the CUDA provider (onnxruntime-gpu's libonnxruntime.so,
#                     its provider libraries beside it; CUDA and cuDNN libraries on LD_LIBRARY_PATH)
#   AERIS_MODELS      the model cache (default: ~/.cache/aeris/models)
#   LLAMA_OFFLOAD     a built llama_offload (build-llama.sh); without it step 3 is skipped
#   LOAD              busy threads for the loaded runs (default: the machine's CPUs)
set -uo pipefail
out=${1:?usage: scripts/gpu-check/run.sh OUT_DIR}
mkdir -p "$out"
here=$(cd "$(dirname "$0")" && pwd)
aeris=${AERIS:-target/release/aeris}
load=${LOAD:-$(nproc)}
models=${AERIS_MODELS:-$HOME/.cache/aeris/models}
onnx=ppocr,yolov3-tiny,yolov8-320n
step() { printf '\n== %s (%s)\n' "$*" "$(date +%T)"; }

step "machine"
nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader
grep -m1 'model name' /proc/cpuinfo
echo "CPUs: $(nproc); busy threads for the loaded runs: $load"
# the default flight, and a YOLO detector on the GPU (or, for the comparison, on CPUs)
workflows=$(cd "$here/../../workflows" && pwd)
flight() {
    cat "$workflows/default.toml"
    printf '\n[executors.gpu]\ncpus = "auto"\naccelerator = "cuda:0"\n\n'
    printf '[[roles]]\nname = "detector"\nkind = "detector"\nvariant = "yolo"\nexecutor = "%s"\n' "$1"
}
flight gpu >"$out/gpu-flight.toml"
flight perception >"$out/cpu-flight.toml"
"$aeris" validate "$out/gpu-flight.toml" 2>&1 | tail -4

step "models on the CPU, idle"
"$aeris" bench models --only "$onnx" --runs 20 --json | tee "$out/models-cpu.txt"
step "models on cuda:0, idle"
"$aeris" bench models --only "$onnx,smollm2" --runs 20 --accelerator cuda:0 --json 2>&1 | tee "$out/models-cuda.txt"
step "models on the CPU, $load busy threads"
"$aeris" bench models --only "$onnx" --runs 20 --outside-load "$load" --json | tee "$out/models-cpu-load.txt"
step "models on cuda:0, $load busy threads"
"$aeris" bench models --only "$onnx" --runs 20 --accelerator cuda:0 --outside-load "$load" --json | tee "$out/models-cuda-load.txt"

step "flights: the detector on cuda:0 and on CPUs, side by side"
"$aeris" run "$out/gpu-flight.toml" --json --flight gpu-check-gpu >"$out/flight-gpu.txt" 2>"$out/flight-gpu.err" &
gpu_pid=$!
"$aeris" run "$out/cpu-flight.toml" --json --flight gpu-check-cpu >"$out/flight-cpu.txt" 2>"$out/flight-cpu.err"
echo "detector on CPUs: exit $?"
wait "$gpu_pid"
echo "detector on cuda:0: exit $?"
for f in gpu cpu; do
    tail -1 "$out/flight-$f.txt" | python3 -c 'import json,sys; s=json.load(sys.stdin); print(sys.argv[1], {k: s[k] for k in ("reached_goal","duration_s","cycles","ct_mean_s","ct_p95_s","eer","controller_missed_ticks")}, "PSS MiB", s["memory"].get("total_pss_peak_mib"))' "$f" || tail -5 "$out/flight-$f.err"
done

if [[ -n "${LLAMA_OFFLOAD:-}" ]]; then
    gguf=$models/llm/smollm2-135m-instruct-q8_0.gguf
    # a decision: ~400 prompt tokens, ~48 generated; the role's 2 threads
    for ngl in 0 99; do
        step "llama.cpp, $ngl layers on the GPU, idle"
        "$LLAMA_OFFLOAD" "$gguf" "$ngl" 2 400 48 10 | tee -a "$out/llama.txt"
    done
    busy=()
    for _ in $(seq "$load"); do
        (while :; do :; done) &
        busy+=($!)
    done
    for ngl in 0 99; do
        step "llama.cpp, $ngl layers on the GPU, $load busy processes"
        "$LLAMA_OFFLOAD" "$gguf" "$ngl" 2 400 48 10 | sed 's/$/ loaded=1/' | tee -a "$out/llama.txt"
    done
    kill "${busy[@]}" 2>/dev/null
fi
step "done"
