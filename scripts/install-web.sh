#!/usr/bin/env bash
# Installs the web viewer's npm packages (three.js, playwright-core for the browser test) into
# web/node_modules exactly as pinned by web/package-lock.json (npm ci). Skips the work when they
# were installed from the same lockfile. Needs node + npm (Debian: nodejs npm).
# If npm fails (e.g. offline) it warns and the viewer serves the client table without the 3D view;
# under CI=true it fails instead.
set -euo pipefail
cd "$(dirname "$0")/../web"
stamp=node_modules/.cslam-lock.sha256
want=$(sha256sum package-lock.json | cut -d' ' -f1)
if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ] && [ -f node_modules/three/build/three.module.js ]; then
  echo "[install-web] web/node_modules up to date"
  exit 0
fi
if ! command -v npm > /dev/null; then
  SUDO=""; [ "$(id -u)" != "0" ] && SUDO="sudo"
  echo "[install-web] installing Debian nodejs + npm"
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends nodejs npm
fi
echo "[install-web] npm ci in web/"
if npm ci --no-audit --no-fund --loglevel=error; then
  echo "$want" > "$stamp"
else
  echo "[install-web] WARNING: npm ci failed; the viewer will show the client table without the 3D view" >&2
  [ "${CI:-}" = "true" ] && exit 1
fi
