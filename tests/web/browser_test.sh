#!/usr/bin/env bash
# Browser test of the web viewer: cslam-server (behind --http-token, no --datasets-dir: the dense map
# comes from the images the robots send) + two cslam-client streaming a small synthetic run at
# 15 frames/s, the page opened in headless Chromium (playwright-core), see browser_test.mjs.
# Usage: browser_test.sh BIN_DIR SOURCE_DIR ARTIFACT_DIR [tls]
# With `tls` the server speaks HTTPS (--http-cert/--http-key, a self-signed certificate made here
# with the openssl program) and the page is opened at https://: the viewer uses relative URLs only.
# Exit 77 (CTest: skipped) if chromium or web/node_modules is missing, unless CI=true (then 1).
set -euo pipefail
BIN="$1"; SRC="$2"; ART="$3"; MODE="${4:-plain}"
missing=""
[ "$MODE" != tls ] || command -v openssl > /dev/null || missing="the openssl program"
[ -x /usr/bin/chromium ] || missing="Debian package chromium (/usr/bin/chromium)"
[ -d "$SRC/web/node_modules/playwright-core" ] || missing="$missing web/node_modules (run scripts/install-web.sh)"
command -v node > /dev/null || missing="$missing node"
if [ -n "$missing" ]; then
  echo "browser test needs: $missing"
  if [ "${CI:-}" = "true" ]; then exit 1; fi
  exit 77
fi
mkdir -p "$ART"
WORK=$(mktemp -d)
SERVER=""; CLIENTS=()
cleanup() {
  for p in "${CLIENTS[@]}"; do kill "$p" 2> /dev/null || true; done
  if [ -n "$SERVER" ]; then kill "$SERVER" 2> /dev/null || true; wait "$SERVER" 2> /dev/null || true; fi
  rm -rf "$WORK"
}
trap cleanup EXIT

TOKEN="browser-test-$RANDOM$RANDOM"
SCHEME=http; TLS_ARGS=()
if [ "$MODE" = tls ]; then
  openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes -days 2 -subj /CN=localhost \
    -addext subjectAltName=IP:127.0.0.1,DNS:localhost -keyout "$WORK/http.key" -out "$WORK/http.crt" 2> /dev/null
  SCHEME=https; TLS_ARGS=(--http-cert "$WORK/http.crt" --http-key "$WORK/http.key")
  export NODE_EXTRA_CA_CERTS="$WORK/http.crt"  # the test's own requests verify the server
fi
"$BIN/cslam-synth" --preset test-small --out "$WORK/scene" --log-level warn > /dev/null
"$BIN/cslam-server" --bind 'tcp://127.0.0.1:*' --endpoint-file "$WORK/endpoint" --clients 2 --out-dir "$WORK/run" \
  --http 0 --http-port-file "$WORK/http_port" --http-token "$TOKEN" --web-root "$SRC/web" "${TLS_ARGS[@]}" \
  --log-interval 2 > "$WORK/server.log" 2>&1 &
SERVER=$!
for _ in $(seq 1 100); do [ -s "$WORK/endpoint" ] && [ -s "$WORK/http_port" ] && break; sleep 0.1; done
if [ ! -s "$WORK/http_port" ]; then echo "server did not start:"; cat "$WORK/server.log"; exit 1; fi
PORT=$(cat "$WORK/http_port")
for k in 1 2; do
  "$BIN/cslam-client" --server "$(cat "$WORK/endpoint")" --id "$k" --name "robot$k" --dataset "$WORK/scene/robot_$k" \
    --rate 15 > "$WORK/client_$k.log" 2>&1 &
  CLIENTS+=($!)
done
status=0
node "$SRC/tests/web/browser_test.mjs" "$SCHEME://127.0.0.1:$PORT/" "$SRC/web" "$ART" "$TOKEN" || status=$?
if [ $status -ne 0 ]; then echo "--- server log"; tail -30 "$WORK/server.log"; fi
exit $status
