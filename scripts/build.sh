#!/usr/bin/env bash
# Configures and builds cslam in Release into build/ (executables in build/bin).
set -euo pipefail
cd "$(dirname "$0")/.."
JOBS="${CSLAM_JOBS:-2}"
# ccache (installed by install-deps.sh) makes rebuilds and fresh clones on the same machine fast;
# paths are taken relative to the clone so that clones in other folders share the cache.
launcher=()
if command -v ccache > /dev/null; then
  export CCACHE_BASEDIR="$PWD"
  launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
fi
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release "${launcher[@]}" "$@" > build-configure.log 2>&1 || { cat build-configure.log; exit 1; }
cmake --build build -j"$JOBS"
