#!/usr/bin/env bash
# Configures and builds cslam in Release into build/ (executables in build/bin).
set -euo pipefail
cd "$(dirname "$0")/.."
JOBS="${CSLAM_JOBS:-2}"
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release "$@" > build-configure.log 2>&1 || { cat build-configure.log; exit 1; }
cmake --build build -j"$JOBS"
