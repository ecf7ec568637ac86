#!/usr/bin/env bash
# Installs what the test suite needs beyond the Rust toolchain, idempotently:
# - python3 with venv (Debian packages, only if missing);
# - a virtual environment at .venv with pymavlink, the independent MAVLink decoder the
#   tests check the controller's stream against (from PyPI, pinned).
# Nothing is downloaded from anywhere but the Debian archive and PyPI.
set -euo pipefail
cd "$(dirname "$0")/.."

PYMAVLINK_VERSION=2.4.50

. scripts/python-env.sh

if ! .venv/bin/python -c "import pymavlink, sys; sys.exit(0 if pymavlink.__version__ == '$PYMAVLINK_VERSION' else 1)" >/dev/null 2>&1; then
    echo "setup: installing pymavlink==$PYMAVLINK_VERSION into .venv" >&2
    .venv/bin/python -m pip install --quiet --disable-pip-version-check "pymavlink==$PYMAVLINK_VERSION"
fi
