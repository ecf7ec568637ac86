#!/usr/bin/env bash
# Cross-builds AERIS-rs for an aarch64 board (Jetson-class) on an x86_64 Debian machine and
# checks what it built under qemu-aarch64: the libraries' unit tests and one short default
# flight (built-in vehicle, geometric perception, planner), with the aarch64 ONNX Runtime
# from the PyPI wheel pinned in scripts/models/onnxruntime.lock. Not part of the test command
# (a release cross build of the workspace, llama.cpp included, takes tens of minutes on 2
# cores); README.md gives its figures.
#
# Usage: scripts/build-aarch64.sh [--board orin|generic] [--build-only] [--dry-run]
#   --board orin     Jetson Orin (Cortex-A78AE): the Armv8.2-A extensions it has (dot product,
#                    fp16, RCpc, LSE atomics, RDM, CRC, AES, SHA2; the default)
#   --board generic  any Armv8-A board
#   --build-only     cross-build only; run nothing under qemu
#   --dry-run        print the build environment and the commands, change nothing
#
# The CPU flags come from the board profile only: `-C target-cpu=native` belongs to host
# builds (.cargo/config.toml sets it for x86_64 targets only), and a binary built for this
# machine's CPU may die of an illegal instruction on the board. The profile is given as
# target features, not `-C target-cpu=cortex-a78ae`: llama-cpp-sys-2 hands a target-cpu to the
# C++ compiler as `-march=CPU`, which gcc refuses for a CPU name; it builds llama.cpp for
# Armv8-A on every non-native aarch64 build.
set -euo pipefail
cd "$(dirname "$0")/.."

TARGET=aarch64-unknown-linux-gnu
board=orin
dry_run=0
run_checks=1
while [ $# -gt 0 ]; do
    case "$1" in
        --board) board="${2:?--board needs orin or generic}"; shift 2 ;;
        --board=*) board="${1#--board=}"; shift ;;
        --build-only) run_checks=0; shift ;;
        --dry-run) dry_run=1; shift ;;
        -h|--help) sed -n '2,/^set -euo/p' "$0" | sed '$d' | sed 's/^# \{0,1\}//'; exit 0 ;;
        *) echo "build-aarch64: unknown argument \`$1\` (see --help)" >&2; exit 2 ;;
    esac
done

case "$board" in
    orin) board_flags="-C target-feature=+neon,+fp16,+dotprod,+rcpc,+lse,+rdm,+crc,+aes,+sha2" ;;
    generic) board_flags="" ;;
    *) echo "build-aarch64: unknown board \`$board\`: use orin or generic" >&2; exit 2 ;;
esac

# RUSTFLAGS and CARGO_ENCODED_RUSTFLAGS replace every other flag source for every target: they
# would drop the board profile (and hand a host's `-C target-cpu=native` to the board).
for var in RUSTFLAGS CARGO_ENCODED_RUSTFLAGS; do
    if [ -n "${!var:-}" ]; then
        echo "build-aarch64: $var is set (\`${!var}\`): it would replace the board's CPU flags; unset it" >&2
        exit 2
    fi
done

# Everything the cross build reads, for this target only: the host's own builds (build
# scripts, proc macros) keep the host's flags.
export CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_LINKER=aarch64-linux-gnu-gcc
export CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_RUSTFLAGS="$board_flags"
export CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_RUNNER=qemu-aarch64
export CC_aarch64_unknown_linux_gnu=aarch64-linux-gnu-gcc
export CXX_aarch64_unknown_linux_gnu=aarch64-linux-gnu-g++
export AR_aarch64_unknown_linux_gnu=aarch64-linux-gnu-ar
# GStreamer's aarch64 libraries come from Debian's multiarch packages. Its base plugins'
# development package cannot be installed beside the host's (Debian replaces one by the
# other), so its pkg-config files and link names are unpacked into a folder of their own.
armdev="${AERIS_AARCH64_DEV:-$HOME/.cache/aeris/aarch64-dev}"
# (the pkg-config crate reads these for the target only; host build scripts keep the host's)
export PKG_CONFIG_ALLOW_CROSS_aarch64_unknown_linux_gnu=1
export PKG_CONFIG_LIBDIR_aarch64_unknown_linux_gnu="$armdev/pkgconfig:/usr/lib/aarch64-linux-gnu/pkgconfig:/usr/share/pkgconfig"
export CMAKE_C_COMPILER_LAUNCHER=ccache CMAKE_CXX_COMPILER_LAUNCHER=ccache
export CCACHE_DIR="${CCACHE_DIR:-$HOME/.cache/aeris/ccache}" CCACHE_NOHASHDIR=1 CCACHE_BASEDIR="$PWD"
models="${AERIS_MODELS_AARCH64:-$HOME/.cache/aeris/models-aarch64}"

build=(cargo build --release --target "$TARGET" --workspace --bins --lib)
tests=(cargo test --release --target "$TARGET" --workspace --lib --no-fail-fast)
bin="target/$TARGET/release/aeris"
flight=("$bin" run --json --run-dir "target/$TARGET/flight")

if [ "$dry_run" -eq 1 ]; then
    echo "board: $board"
    env | grep -E '^(CARGO_TARGET_AARCH64|CC_aarch64|CXX_aarch64|AR_aarch64|PKG_CONFIG_[A-Z_]*aarch64)' | sort
    echo "build: ${build[*]}"
    [ "$run_checks" -eq 1 ] && echo "tests: ${tests[*]}" && echo "flight: AERIS_MODELS=$models ${flight[*]}"
    exit 0
fi

step() { echo "build-aarch64: $*" >&2; }
SUDO=""
[ "$(id -u)" -ne 0 ] && SUDO="sudo"

step "1/5 cross toolchain, qemu-user and the aarch64 GStreamer development files (Debian)"
missing=()
command -v aarch64-linux-gnu-gcc >/dev/null || missing+=(gcc-aarch64-linux-gnu)
command -v aarch64-linux-gnu-g++ >/dev/null || missing+=(g++-aarch64-linux-gnu)
command -v qemu-aarch64 >/dev/null || missing+=(qemu-user)
for p in libc6:arm64 libstdc++6:arm64 libgstreamer1.0-dev:arm64 \
    libgstreamer-plugins-base1.0-0:arm64 gstreamer1.0-plugins-base:arm64; do
    dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
    step "installing ${missing[*]}"
    export DEBIAN_FRONTEND=noninteractive
    dpkg --print-foreign-architectures | grep -qx arm64 || $SUDO dpkg --add-architecture arm64
    $SUDO apt-get update -qq
    $SUDO apt-get install -y -qq "${missing[@]}" >/dev/null
fi
scripts/setup-build-deps.sh
if [ ! -e "$armdev/pkgconfig/gstreamer-video-1.0.pc" ]; then
    step "unpacking the aarch64 GStreamer base plugins' pkg-config files into $armdev"
    rm -rf "$armdev.new" && mkdir -p "$armdev.new/deb"
    (cd "$armdev.new/deb" && apt-get download -q libgstreamer-plugins-base1.0-dev:arm64 2>/dev/null)
    dpkg-deb -x "$armdev.new"/deb/*.deb "$armdev.new/root"
    mkdir -p "$armdev.new/pkgconfig" "$armdev.new/lib"
    # the link names point at the multiarch libraries; the .pc files at the link names
    for link in "$armdev.new"/root/usr/lib/aarch64-linux-gnu/lib*.so; do
        ln -s "/usr/lib/aarch64-linux-gnu/$(readlink "$link")" "$armdev.new/lib/$(basename "$link")"
    done
    for pc in "$armdev.new"/root/usr/lib/aarch64-linux-gnu/pkgconfig/*.pc; do
        sed "s|^libdir=.*|libdir=$armdev/lib|" "$pc" > "$armdev.new/pkgconfig/$(basename "$pc")"
    done
    rm -rf "$armdev.new/deb" "$armdev.new/root" "$armdev"
    mv "$armdev.new" "$armdev"
fi

step "2/5 the Rust standard library for $TARGET (rustup)"
rustup target list --installed | grep -qx "$TARGET" || rustup target add "$TARGET"

step "3/5 building the workspace for $TARGET, board $board (first build: tens of minutes)"
start=$(date +%s)
"${build[@]}"
step "built in $(( $(date +%s) - start )) s: $(file -b "$bin" | cut -d, -f1-2)"
if [ "$run_checks" -eq 0 ]; then
    exit 0
fi

step "4/5 the library unit tests under qemu-aarch64 (cargo runs them through it)"
start=$(date +%s)
"${tests[@]}"
step "unit tests passed under qemu in $(( $(date +%s) - start )) s"

step "5/5 one default flight under qemu-aarch64 with the aarch64 ONNX Runtime"
# Role processes are spawned as the aeris binary itself: the kernel must hand aarch64 ELF
# files to qemu (binfmt_misc) for a flight's roles to start.
if [ ! -e /proc/sys/fs/binfmt_misc/status ]; then
    $SUDO mount -t binfmt_misc binfmt_misc /proc/sys/fs/binfmt_misc \
        || { echo "build-aarch64: cannot mount binfmt_misc (qemu cannot start the flight's role processes)" >&2; exit 1; }
fi
if ! grep -qs "^interpreter $(command -v qemu-aarch64)" /proc/sys/fs/binfmt_misc/*aarch64* 2>/dev/null; then
    [ -e /proc/sys/fs/binfmt_misc/aeris-qemu-aarch64 ] && echo -1 | $SUDO tee /proc/sys/fs/binfmt_misc/aeris-qemu-aarch64 >/dev/null
    printf '%s' ':aeris-qemu-aarch64:M::\x7f\x45\x4c\x46\x02\x01\x01\x00\x00\x00\x00\x00\x00\x00\x00\x00\x02\x00\xb7\x00:\xff\xff\xff\xff\xff\xff\xff\x00\xff\xff\xff\xff\xff\xff\xff\xff\xfe\xff\xff\xff:'"$(command -v qemu-aarch64)"':' \
        | $SUDO tee /proc/sys/fs/binfmt_misc/register >/dev/null
fi
AERIS_MODELS="$models" AERIS_MODELS_ARCH=aarch64 scripts/provision-models.sh
# qemu-user 7.2 (Debian 12) shows the emulated processes this machine's x86 /proc/cpuinfo,
# on which ONNX Runtime's CPU detection (pytorch/cpuinfo) dereferences NULL: they see an
# aarch64 one instead (the board's cores, as qemu 8 does itself), bound over it in a mount
# namespace of their own
cpuinfo="target/$TARGET/cpuinfo"
: > "$cpuinfo"
for i in $(seq 0 $(( $(nproc) - 1 ))); do
    printf 'processor\t: %d\nBogoMIPS\t: 62.50\nFeatures\t: fp asimd evtstrm aes pmull sha1 sha2 crc32 atomics fphp asimdhp cpuid asimdrdm lrcpc dcpop asimddp\nCPU implementer\t: 0x41\nCPU architecture: 8\nCPU variant\t: 0x0\nCPU part\t: 0xd42\nCPU revision\t: 1\n\n' "$i" >> "$cpuinfo"
done
as_board() {
    $SUDO unshare --mount --propagation private \
        sh -c 'mount --bind "$0" /proc/cpuinfo && exec "$@"' "$PWD/$cpuinfo" env AERIS_MODELS="$models" "$@"
}
# `aeris validate` loads the ONNX Runtime and names its execution providers
as_board "$bin" validate workflows/default.toml | grep -E "^accelerators" >&2
start=$(date +%s)
as_board "${flight[@]}" | tee "target/$TARGET/flight.log"
step "flight done under qemu in $(( $(date +%s) - start )) s"
