#!/usr/bin/env bash
# Server memory over a long run: N synthetic robots (320x240, 10 % of each path shared, circling
# their rooms) stream lossless at 30 frames/s to one cslam-server, once with the live dense map and
# once with --no-dense, back to back. Reports the server's peak RSS (/usr/bin/time), CPU, frames
# processed, and samples of resident memory, the allocator's held/free bytes and the dense map's
# mesh/volume bytes every 30 s (the server's own progress lines).
# Usage: scripts/bench-memory.sh [ROBOTS=4] [FRAMES=18000 (10 min at 30 Hz)] [OUT=bench_out/memory] [RUNS=1]
#        [CASES="dense nodense"]
set -euo pipefail
cd "$(dirname "$0")/.."
ROBOTS="${1:-4}"
FRAMES="${2:-18000}"
OUT="${3:-bench_out/memory}"
RUNS="${4:-1}"
CASES="${5:-dense nodense}"
BIN="$PWD/build/bin"
SCENE="$OUT/scene_${ROBOTS}x${FRAMES}"
mkdir -p "$OUT"
echo "== machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), load $(cut -d' ' -f1-3 /proc/loadavg)"
echo "== revision $(git rev-parse --short HEAD)$(git diff --quiet || echo '+dirty'), $ROBOTS robots x $FRAMES frames, $RUNS run(s)"
if [ ! -f "$SCENE/robot_${ROBOTS}/groundtruth.txt" ]; then
  echo "-- rendering the scene (cslam-synth, $(( ROBOTS * FRAMES )) frames of 320x240: minutes)"
  "$BIN/cslam-synth" --robots "$ROBOTS" --frames "$FRAMES" --width 320 --height 240 --overlap 0.1 --seed 21 \
    --out "$SCENE" --force --log-level warn > /dev/null
fi

# run_case NAME [server options...]
run_case() {
  local name="$1"; shift
  local dir="$OUT/$name"
  rm -rf "$dir" && mkdir -p "$dir"
  /usr/bin/time -f "%M %U %S %e" -o "$dir/time.txt" \
    "$BIN/cslam-server" --bind 'tcp://127.0.0.1:*' --endpoint-file "$dir/endpoint" --clients "$ROBOTS" --exit-when-done \
    --out-dir "$dir/out" --http 0 --http-port-file "$dir/http_port" --log-interval 30 "$@" > "$dir/server.log" 2>&1 &
  local server=$!
  for _ in $(seq 1 100); do [ -s "$dir/endpoint" ] && break; sleep 0.1; done
  [ -s "$dir/endpoint" ] || { echo "server did not start: $dir/server.log" >&2; exit 1; }
  local pids=()
  for k in $(seq 1 "$ROBOTS"); do
    "$BIN/cslam-client" --server "$(cat "$dir/endpoint")" --id "$k" --dataset "$SCENE/robot_$k" --rate 30 \
      --progress-interval 60 > "$dir/client_$k.log" 2>&1 &
    pids+=($!)
  done
  for p in "${pids[@]}"; do wait "$p" || { echo "a client failed: $dir/client_*.log" >&2; exit 1; }; done
  wait "$server" || { echo "server failed: $dir/server.log" >&2; exit 1; }
  read -r kb user sys wall < "$dir/time.txt"
  local processed
  processed=$(grep -o 'total client [0-9]*: received [0-9]* processed [0-9]*' "$dir/server.log" | awk '{s += $NF} END {print s + 0}')
  printf '%-10s peak RSS %6.0f MB | CPU user %5.0f s sys %4.0f s | wall %4.0f s | frames processed %d of %d\n' \
    "$name" "$(echo "$kb / 1024" | bc -l)" "$user" "$sys" "$wall" "$processed" $(( ROBOTS * FRAMES ))
  echo "           samples (every 60 s):"
  grep 'process: resident' "$dir/server.log" | awk 'NR % 2 == 0' | sed 's/.*process: /             /'
  grep 'dense: ' "$dir/server.log" | tail -1 | sed 's/.*dense: /           dense at the end: /' || true
}

for r in $(seq 1 "$RUNS"); do
  echo "-- run $r"
  for c in $CASES; do
    case "$c" in
      dense) run_case "dense_r$r" ;;
      nodense) run_case "nodense_r$r" --no-dense ;;
      *) echo "bench-memory.sh: unknown case $c (dense, nodense)" >&2; exit 2 ;;
    esac
  done
done
