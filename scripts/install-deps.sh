#!/usr/bin/env bash
# Installs the Debian 12 packages cslam needs to build, test and run.
# Safe to run repeatedly: it only calls apt-get when a package is missing.
set -euo pipefail

PKGS=(
  build-essential cmake pkg-config git ca-certificates
  libopencv-dev libeigen3-dev libceres-dev libpcl-dev
  libzmq3-dev cppzmq-dev libprotobuf-dev protobuf-compiler
  libcpp-httplib-dev libgtest-dev libspdlog-dev nlohmann-json3-dev libzstd-dev zlib1g-dev
  nodejs chromium curl
)
# nodejs: the web viewer's npm packages (scripts/install-web.sh); chromium: its browser test.

missing=()
for p in "${PKGS[@]}"; do
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
