#!/usr/bin/env bash
# Installs the Debian 12 packages cslam needs to build, test and run.
# Safe to run repeatedly: it only calls apt-get when a package is missing.
# --build-only: only what building the programs needs (the container's build stage).
set -euo pipefail
BUILD_ONLY=0
[ "${1:-}" = "--build-only" ] && BUILD_ONLY=1

PKGS=(
  build-essential cmake pkg-config git ca-certificates ccache
  libopencv-dev libeigen3-dev libceres-dev libsuitesparse-dev libpcl-dev libboost-dev
  libzmq3-dev cppzmq-dev libprotobuf-dev protobuf-compiler
  libcpp-httplib-dev libgtest-dev libspdlog-dev nlohmann-json3-dev libzstd-dev libsqlite3-dev liboctomap-dev zlib1g-dev libturbojpeg0-dev libdeflate-dev libgoogle-perftools-dev libavcodec-dev
  nodejs chromium curl
)
# liboctomap-dev: 3D occupancy maps in OctoMap's .bt format (src/navmap).
# libsqlite3-dev: the keyframe image store (server/dense/keyframe_store.h; WAL commits survive kill -9).
# libturbojpeg0-dev: JPEG decoded straight to BGR (src/codec/jpeg_decode.cpp).
# libdeflate-dev: 16-bit depth PNGs inflated in one call, ~3.7x faster than zlib (src/codec/png16_decode.cpp).
# libavcodec-dev: inter-frame H.264 colour with libx264 (src/codec/video_codec.cpp).
# libgoogle-perftools-dev: tcmalloc, the programs' allocator (cmake/Dependencies.cmake).
# nodejs: the web viewer's npm packages (scripts/install-web.sh); chromium: its browser test.
TEST_PKGS=(
  python3-zmq python3-protobuf python3-opencv python3-zstandard python3-av python3-numpy python3-rosbag python3-sensor-msgs
  clang-format
)
# python3-*: the Python client (client/python), tools/cslam-bag-replay and their tests (sensor-msgs: test bags;
# av: PyAV on Debian's libavcodec/libx264, the lean stream's H.264 colour, byte-identical to C++).
# clang-format: the suite checks that the C++ tree is formatted (.clang-format, tests/layout).
if [ "$BUILD_ONLY" = 1 ]; then
  PKGS=("${PKGS[@]/chromium}")
else
  PKGS+=("${TEST_PKGS[@]}")
fi

missing=()
for p in "${PKGS[@]}"; do
  [ -n "$p" ] || continue
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "[install-deps] all ${#PKGS[@]} packages present"
  exit 0
fi

SUDO=""
if [ "$(id -u)" != "0" ]; then SUDO="sudo"; fi
echo "[install-deps] installing: ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
