#!/usr/bin/env bash
# The main job: installs missing Debian packages, builds in Release and runs the most complete
# pipeline that exists on the embedded synthetic scene. Pass --exit to stop at the end instead
# of keeping the viewer up (for scripts).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
bash scripts/install-web.sh
bash scripts/build.sh
exec bash scripts/run-demo.sh "$@"
