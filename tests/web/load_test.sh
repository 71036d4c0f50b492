#!/usr/bin/env bash
# Loopback load test of the HTTP API (not part of CTest: it measures speed). Runs the demo
# pipeline (cslam-server + 3 cslam-client at --rate 30 on a cslam-synth --preset demo scene) once
# without and once with GET /api/status at 50 requests/s, and prints the status latency
# (median, p90, p99, max), the SLAM throughput (frames per second, wall time) and the server's CPU
# time per frame (less sensitive than wall time to other processes on the machine).
# Usage: load_test.sh BIN_DIR SCENE_DIR [RUNS=1] [RATE=50]
set -euo pipefail
BIN="$1"; SCENE="$2"; RUNS="${3:-1}"; RATE="${4:-50}"
HERE="$(cd "$(dirname "$0")" && pwd)"
run() {  # $1: 0 = no HTTP load, 1 = status load
  local out; out=$(mktemp -d)
  /usr/bin/time -f "%U %S" -o "$out/cpu" "$BIN/cslam-server" --bind 'tcp://127.0.0.1:*' --endpoint-file "$out/endpoint" --clients 3 --exit-when-done \
    --out-dir "$out/run" --http 0 --http-port-file "$out/port" --log-level warn > "$out/server.log" 2>&1 &
  local server=$!
  for _ in $(seq 1 100); do [ -s "$out/endpoint" ] && [ -s "$out/port" ] && break; sleep 0.1; done
  local clients=()
  for k in 1 2 3; do
    "$BIN/cslam-client" --server "$(cat "$out/endpoint")" --id "$k" --name "robot$k" --dataset "$SCENE/robot_$k" \
      --rate 30 --log-level warn > "$out/client_$k.log" 2>&1 &
    clients+=($!)
  done
  if [ "$1" = 1 ]; then
    sleep 1
    node "$HERE/status_load.mjs" "http://127.0.0.1:$(cat "$out/port")/api/status" "$RATE" 8
  fi
  for p in "${clients[@]}"; do wait "$p"; done
  wait "$server"
  python3 - "$out/run/network_stats.json" "$1" "$out/cpu" <<'PY'
import json, sys
j = json.load(open(sys.argv[1]))
user, system = map(float, open(sys.argv[3]).read().split()[-2:])
proc = sum(c.get("frames_processed", 0) for c in j["clients"])
print(json.dumps({"http_load": sys.argv[2] == "1", "wall_s": round(j["wall_s"], 2), "frames_accepted": j["frames_accepted"],
                  "frames_processed": proc, "throughput_fps": round(j["throughput_fps"], 2),
                  "server_cpu_s": round(user + system, 2), "cpu_ms_per_frame": round(1000 * (user + system) / max(1, proc), 1)}))
PY
  rm -rf "$out"
}
for _ in $(seq 1 "$RUNS"); do run 0; run 1; done
