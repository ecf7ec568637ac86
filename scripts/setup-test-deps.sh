#!/usr/bin/env bash
# Installs what the test suite needs beyond the Rust toolchain, idempotently:
# - python3 with venv (Debian packages, only if missing);
# - a virtual environment at .venv with pymavlink, the independent MAVLink decoder the
#   tests check the controller's stream against, and MAVProxy, the MAVLink router a test
#   flies through (from PyPI, pinned; MAVProxy without its optional GUI dependencies —
#   matplotlib, OpenCV, VTK —, which a headless router never imports), mcap, the
#   independent MCAP reader the flight-recording tests read the recorder's files with, and
#   eclipse-zenoh, the independent zenoh peers the agent's security tests get in with (or
#   try to), and ray, the cluster engine scripts/eval-ray.py runs evaluation shards on (a
#   test runs it on a local cluster).
# - GStreamer's plugins the video tests run real pipelines with (Debian packages, only if
#   missing): H.264 encode (x264enc, plugins-ugly) and decode (avdec_h264, libav), MP4 and
#   RTP (plugins-good), and gst-launch-1.0 (tools) for the second-process RTP sender.
# - an ONNX Runtime too old for `ort` (PyPI wheel, pinned), for the refused-runtime test.
# Nothing is downloaded from anywhere but the Debian archive and PyPI.
set -euo pipefail
cd "$(dirname "$0")/.."

PYMAVLINK_VERSION=2.4.50
MAVPROXY_VERSION=1.8.75
PYSERIAL_VERSION=3.5
MCAP_VERSION=1.6.0
ZENOH_PY_VERSION=1.10.2
RAY_VERSION=2.60.0

gst_missing=()
gst_has() { gst-inspect-1.0 --exists "$1" 2>/dev/null; }
command -v gst-launch-1.0 >/dev/null 2>&1 || gst_missing+=(gstreamer1.0-tools)
if command -v gst-inspect-1.0 >/dev/null 2>&1; then
    gst_has x264enc || gst_missing+=(gstreamer1.0-plugins-ugly)
    gst_has avdec_h264 || gst_missing+=(gstreamer1.0-libav)
    gst_has mp4mux || gst_missing+=(gstreamer1.0-plugins-good)
    gst_has h264parse || gst_missing+=(gstreamer1.0-plugins-bad)
else
    gst_missing+=(gstreamer1.0-plugins-ugly gstreamer1.0-libav gstreamer1.0-plugins-good gstreamer1.0-plugins-bad)
fi
if [ ${#gst_missing[@]} -gt 0 ]; then
    echo "setup: installing ${gst_missing[*]} (Debian packages)" >&2
    SUDO=""
    [ "$(id -u)" -ne 0 ] && SUDO="sudo"
    export DEBIAN_FRONTEND=noninteractive
    $SUDO apt-get update -qq
    $SUDO apt-get install -y -qq "${gst_missing[@]}" >/dev/null
fi

. scripts/python-env.sh

if ! .venv/bin/python -c "import pymavlink, sys; sys.exit(0 if pymavlink.__version__ == '$PYMAVLINK_VERSION' else 1)" >/dev/null 2>&1; then
    echo "setup: installing pymavlink==$PYMAVLINK_VERSION into .venv" >&2
    .venv/bin/python -m pip install --quiet --disable-pip-version-check "pymavlink==$PYMAVLINK_VERSION"
fi
if ! .venv/bin/python -c "import mcap, sys; from importlib.metadata import version; sys.exit(0 if version('mcap') == '$MCAP_VERSION' else 1)" >/dev/null 2>&1; then
    echo "setup: installing mcap==$MCAP_VERSION into .venv" >&2
    .venv/bin/python -m pip install --quiet --disable-pip-version-check "mcap==$MCAP_VERSION"
fi
if ! .venv/bin/python -c "import zenoh, sys; from importlib.metadata import version; sys.exit(0 if version('eclipse-zenoh') == '$ZENOH_PY_VERSION' else 1)" >/dev/null 2>&1; then
    echo "setup: installing eclipse-zenoh==$ZENOH_PY_VERSION into .venv" >&2
    .venv/bin/python -m pip install --quiet --disable-pip-version-check "eclipse-zenoh==$ZENOH_PY_VERSION"
fi
if ! .venv/bin/python -c "import ray, sys; sys.exit(0 if ray.__version__ == '$RAY_VERSION' else 1)" >/dev/null 2>&1; then
    echo "setup: installing ray==$RAY_VERSION into .venv" >&2
    .venv/bin/python -m pip install --quiet --disable-pip-version-check "ray==$RAY_VERSION"
fi
if ! .venv/bin/python -c "import MAVProxy, serial, sys; from importlib.metadata import version; sys.exit(0 if version('MAVProxy') == '$MAVPROXY_VERSION' else 1)" >/dev/null 2>&1; then
    echo "setup: installing MAVProxy==$MAVPROXY_VERSION into .venv" >&2
    .venv/bin/python -m pip install --quiet --disable-pip-version-check "pyserial==$PYSERIAL_VERSION"
    .venv/bin/python -m pip install --quiet --disable-pip-version-check --no-deps "MAVProxy==$MAVPROXY_VERSION"
fi

# An ONNX Runtime older than the `ort` crate supports (1.21.1; it needs 1.22 or newer), for
# the test that a user's own runtime (AERIS_ONNXRUNTIME) of the wrong version is refused
# with a clear error. PyPI wheel, pinned by its sha256; x86_64 only.
OLD_ORT_DIR="${AERIS_TEST_DOWNLOADS:-$HOME/.cache/aeris/test-downloads}"
if [ "$(uname -m)" = x86_64 ] && [ ! -f "$OLD_ORT_DIR/libonnxruntime.so.1.21.1" ]; then
    echo "setup: downloading onnxruntime 1.21.1 from PyPI into $OLD_ORT_DIR (the too-old runtime test)" >&2
    mkdir -p "$OLD_ORT_DIR"
    .venv/bin/python -m pip download --quiet --disable-pip-version-check --no-deps --require-hashes \
        --only-binary=:all: --platform manylinux_2_28_x86_64 --python-version 311 -d "$OLD_ORT_DIR" \
        -r <(echo "onnxruntime==1.21.1 --hash=sha256:982dcc04a6688e1af9e3da1d4ef2bdeb11417cf3f8dde81f8f721043c1919a4f")
    .venv/bin/python - "$OLD_ORT_DIR" <<'PY'
import glob, os, sys, zipfile
folder = sys.argv[1]
wheel = glob.glob(os.path.join(folder, "onnxruntime-1.21.1-*.whl"))[0]
with zipfile.ZipFile(wheel) as z:
    member = next(n for n in z.namelist() if n.endswith("/libonnxruntime.so.1.21.1"))
    with z.open(member) as src, open(os.path.join(folder, "libonnxruntime.so.1.21.1.part"), "wb") as out:
        out.write(src.read())
os.replace(os.path.join(folder, "libonnxruntime.so.1.21.1.part"), os.path.join(folder, "libonnxruntime.so.1.21.1"))
os.remove(wheel)
PY
fi
