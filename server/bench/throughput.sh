#!/usr/bin/env bash
# Loopback throughput of cslam-server with SLAM stubbed (--no-slam): K clients replaying the
# same dataset range with --preload --rate max. Prints one JSON summary line per run.
# Usage: server/bench/throughput.sh [BIN_DIR] [DATASET] [CLIENTS] [RANGE] [RUNS] [extra client args...]
set -euo pipefail
BIN=${1:-build/bin}
DATA=${2:-../shared/data/tum_fr1_rpy}
CLIENTS=${3:-3}
RANGE=${4:-1:300}
RUNS=${5:-3}
shift $(( $# < 5 ? $# : 5 ))
for run in $(seq 1 "$RUNS"); do
  TMP=$(mktemp -d)
  "$BIN/cslam-server" --bind 'tcp://127.0.0.1:*' --endpoint-file "$TMP/endpoint" --clients "$CLIENTS" \
    --exit-when-done --no-slam --out-dir "$TMP/out" --log-level warn --http off &
  SERVER=$!
  for _ in $(seq 100); do [ -s "$TMP/endpoint" ] && break; sleep 0.1; done
  EP=$(cat "$TMP/endpoint")
  PIDS=()
  for id in $(seq 1 "$CLIENTS"); do
    "$BIN/cslam-client" --server "$EP" --id "$id" --dataset "$DATA" --range "$RANGE" --rate max --preload \
      --log-level warn "$@" &
    PIDS+=($!)
  done
  for p in "${PIDS[@]}"; do wait "$p"; done
  wait "$SERVER"
  python3 -c "
import json,sys
j=json.load(open('$TMP/out/network_stats.json'))
d=j['decode_dispatch_ms']
print(json.dumps({'run':$run,'clients':$CLIENTS,'frames':j['frames_accepted'],'throughput_fps':round(j['throughput_fps'],1),
  'MB_s':round(j['throughput_mb_s'],1),'decode_dispatch_ms_median':round(d['median'],2),'min':round(d['min'],2),
  'max':round(d['max'],2),'p95':round(d['p95'],2),'dropped':sum(c['dropped_total'] for c in j['clients'])}))"
  rm -rf "$TMP"
done
