#!/usr/bin/env bash
# Browser test of the viewer's dense layer against a mock server (tests/web/mock_dense_server.mjs),
# no cslam binaries needed; see dense_viewer_mock.mjs.
# Usage: dense_viewer_mock.sh SOURCE_DIR ARTIFACT_DIR
# Exit 77 (CTest: skipped) if chromium or web/node_modules is missing, unless CI=true (then 1).
set -euo pipefail
SRC="$1"; ART="$2"
missing=""
[ -x /usr/bin/chromium ] || missing="Debian package chromium (/usr/bin/chromium)"
[ -d "$SRC/web/node_modules/playwright-core" ] || missing="$missing web/node_modules (run scripts/install-web.sh)"
[ -f "$SRC/web/node_modules/three/build/three.module.js" ] || missing="$missing web/node_modules/three (run scripts/install-web.sh)"
command -v node > /dev/null || missing="$missing node"
if [ -n "$missing" ]; then
  echo "dense viewer mock test needs: $missing"
  if [ "${CI:-}" = "true" ]; then exit 1; fi
  exit 77
fi
mkdir -p "$ART"
exec node "$SRC/tests/web/dense_viewer_mock.mjs" "$SRC/web" "$ART"
