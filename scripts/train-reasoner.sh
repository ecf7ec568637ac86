#!/usr/bin/env bash
# LoRA-tunes a provisioned language model on `aeris distill` training pairs and exports a
# llama.cpp adapter (scripts/train_reasoner.py says what it does and writes; --help lists its
# options). Example, the committed SmolLM2 adapter:
#
#   target/release/aeris distill --episodes 12 --out runs/distill-train-12
#   scripts/train-reasoner.sh --base smollm2 --pairs runs/distill-train-12/pairs.jsonl \
#       --out runs/train-smollm2 --lr 4e-4 --epochs 2
#
# The training environment is its own virtual environment (.venv-train: torch, transformers,
# peft, gguf), installed from PyPI with every package pinned in scripts/train-requirements.lock
# (PyPI's torch is its CUDA build: about 4 GB with NVIDIA's libraries, which it runs without
# on a CPU). The test suite does not need it. Nothing is downloaded from anywhere else; the
# base model comes from the provisioned cache (scripts/provision-models.sh).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"
# python3 with venv (Debian packages, only if missing)
source scripts/python-env.sh
venv="$root/.venv-train"
lock="$root/scripts/train-requirements.lock"
stamp="$venv/.lock.sha256"
want="$(sha256sum "$lock" | cut -d' ' -f1)"
if [ ! -x "$venv/bin/python" ] || [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
    echo "train-reasoner: installing the training environment into $venv (PyPI, pinned by $lock)" >&2
    python3 -m venv "$venv"
    "$venv/bin/pip" install --quiet --disable-pip-version-check --no-deps -r "$lock"
    echo "$want" > "$stamp"
fi
exec "$venv/bin/python" "$root/scripts/train_reasoner.py" "$@"
