#!/usr/bin/env bash
# Installs the web viewer's npm packages (three.js, playwright-core for the browser test) into
# web/node_modules exactly as pinned by web/package-lock.json. Skips the work when they are
# already installed from the same lockfile. Needs node + npm (Debian: nodejs npm).
set -euo pipefail
cd "$(dirname "$0")/../web"
if ! command -v npm > /dev/null; then
  SUDO=""; [ "$(id -u)" != "0" ] && SUDO="sudo"
  echo "[install-web] installing Debian nodejs + npm"
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends nodejs npm
fi
if [ -f node_modules/.package-lock.json ] && [ node_modules/.package-lock.json -nt package-lock.json ] \
   && [ -f node_modules/three/build/three.module.js ] && [ -d node_modules/playwright-core ]; then
  echo "[install-web] web/node_modules up to date"
  exit 0
fi
echo "[install-web] npm ci in web/"
npm ci --no-audit --no-fund --loglevel=error
