#!/usr/bin/env bash
# Installs what building AERIS-rs needs beyond the Rust toolchain, idempotently, from the
# Debian archive: cmake and a C/C++ compiler (llama.cpp is built from the sources the
# llama-cpp-sys-2 crate ships), libclang (bindgen generates its Rust bindings) and ccache
# (scripts/test.sh compiles llama.cpp once, not once per cargo command: see there), and
# GStreamer's development files (the `gstreamer` camera and `aeris scene video` link to it)
# with the base plugins (videoconvert, videoscale, appsink, appsrc).
set -euo pipefail

missing=()
command -v cmake >/dev/null 2>&1 || missing+=(cmake)
command -v c++ >/dev/null 2>&1 || missing+=(g++)
command -v ccache >/dev/null 2>&1 || missing+=(ccache)
# bindgen (clang-sys) needs libclang itself; libclang-cpp, which some images carry without
# it, does not count.
if ! ls /usr/lib/llvm-*/lib/libclang.so* >/dev/null 2>&1 \
    && ! ls /usr/lib/*/libclang-[0-9]*.so* >/dev/null 2>&1; then
    missing+=(libclang-dev)
fi
pkg-config --exists gstreamer-1.0 gstreamer-app-1.0 gstreamer-video-1.0 2>/dev/null \
    || missing+=(pkg-config libgstreamer1.0-dev libgstreamer-plugins-base1.0-dev)
[ -n "$(find /usr/lib -path '*gstreamer-1.0/libgstvideoconvertscale.so' -o -path '*gstreamer-1.0/libgstvideoconvert.so' 2>/dev/null | head -1)" ] \
    || missing+=(gstreamer1.0-plugins-base)
if [ ${#missing[@]} -eq 0 ]; then
    exit 0
fi
echo "setup: installing ${missing[*]} (Debian packages)" >&2
SUDO=""
if [ "$(id -u)" -ne 0 ]; then
    SUDO="sudo"
fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq "${missing[@]}" >/dev/null
