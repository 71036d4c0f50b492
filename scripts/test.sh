#!/usr/bin/env bash
# The whole test suite: installs missing Debian packages, builds in Release, runs every test.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
bash scripts/install-web.sh
bash scripts/build.sh
cd build
ctest --output-on-failure --timeout 900 -j"${CSLAM_TEST_JOBS:-2}"
