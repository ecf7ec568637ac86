#!/usr/bin/env bash
# Installs what the test suite needs beyond the Rust toolchain, idempotently:
# - python3 with venv (Debian packages, only if missing);
# - a virtual environment at .venv with pymavlink, the independent MAVLink decoder the
#   tests check the controller's stream against (from PyPI, pinned).
# Nothing is downloaded from anywhere but the Debian archive and PyPI.
set -euo pipefail
cd "$(dirname "$0")/.."

PYMAVLINK_VERSION=2.4.50

as_root() {
    if [ "$(id -u)" = 0 ]; then "$@"; elif command -v sudo >/dev/null; then sudo "$@"; else
        echo "setup: need root (or sudo) to run: $*" >&2; exit 1; fi
}

if ! command -v python3 >/dev/null || ! python3 -c 'import venv, ensurepip' >/dev/null 2>&1; then
    echo "setup: installing python3 and python3-venv from Debian" >&2
    as_root apt-get update -qq
    as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq python3 python3-venv python3-pip >/dev/null
fi

if [ ! -x .venv/bin/python ]; then
    echo "setup: creating .venv" >&2
    python3 -m venv .venv
fi
if ! .venv/bin/python -c "import pymavlink, sys; sys.exit(0 if pymavlink.__version__ == '$PYMAVLINK_VERSION' else 1)" >/dev/null 2>&1; then
    echo "setup: installing pymavlink==$PYMAVLINK_VERSION into .venv" >&2
    .venv/bin/python -m pip install --quiet --disable-pip-version-check "pymavlink==$PYMAVLINK_VERSION"
fi
