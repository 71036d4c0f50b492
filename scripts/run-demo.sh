#!/usr/bin/env bash
# The demo pipeline with already-built programs (scripts/demo.sh installs and builds first):
# synthetic 3-robot scene -> cslam-server + 3 cslam-client over loopback -> per-client SLAM ->
# map fusion -> dense reconstruction -> per-client and fused ATE, cloud accuracy.
# The web viewer (http://127.0.0.1:8080/, CSLAM_HTTP_PORT to change) stays up until Ctrl-C.
# Options: --exit    stop at the end instead of serving the viewer (for scripts)
#          --rate R  client send rate (frames/s or 'max', default max; 30 = real time)
#          --depth-every K  lean stream: full frames every K-th frame and on request, light frames
#                   (H.264 colour, 1/4 depth) between (default 1: every frame full, the default pair)
#          --adapt  the robots adapt their stream to the link (cslam-client --adapt; use with --rate 30)
#          --byte-budget MB  each robot's byte budget, spent on finer full frames (cslam-client --byte-budget)
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=build/bin
OUT="${CSLAM_DEMO_OUT:-demo_out}"
RATE=max
DEPTH_EVERY=1
ADAPT=()
BUDGET=0
EXIT=0
FUSED=""
HTTP_PORT="${CSLAM_HTTP_PORT:-8080}"
while [ $# -gt 0 ]; do
  case "$1" in
    --exit) EXIT=1; shift ;;
    --rate) RATE="$2"; shift 2 ;;
    --depth-every) DEPTH_EVERY="$2"; shift 2 ;;
    --adapt) ADAPT=(--adapt); shift ;;
    --byte-budget) BUDGET="$2"; shift 2 ;;
    *) echo "run-demo.sh: unknown option $1 (use --exit, --rate R, --depth-every K, --adapt, --byte-budget MB)" >&2; exit 2 ;;
  esac
done
SCENE="$OUT/scene"
RUN="$OUT/run"
mkdir -p "$OUT"

if [ ! -f "$SCENE/scene.ply" ]; then
  echo "== generating the synthetic 3-robot scene in $SCENE"
  rm -rf "$SCENE"
  "$BIN/cslam-synth" --preset demo --out "$SCENE" --log-level warn
fi

echo "== starting cslam-server and 3 clients over loopback"
rm -rf "$RUN" && mkdir -p "$RUN"
EXIT_FLAG=()
[ "$EXIT" = 1 ] && EXIT_FLAG=(--exit-when-done)
"$BIN/cslam-server" --bind 'tcp://127.0.0.1:*' --endpoint-file "$RUN/endpoint" --clients 3 "${EXIT_FLAG[@]}" \
  --out-dir "$RUN" --log-interval 10 --http "$HTTP_PORT" --http-port-file "$RUN/http_port" \
  > "$RUN/server.log" 2>&1 &
SERVER=$!
trap 'kill $SERVER 2>/dev/null || true' EXIT
for _ in $(seq 1 100); do [ -s "$RUN/endpoint" ] && break; sleep 0.1; done
[ -s "$RUN/endpoint" ] || { echo "server did not start; see $RUN/server.log" >&2; cat "$RUN/server.log" >&2; exit 1; }
ENDPOINT=$(cat "$RUN/endpoint")
CLIENTS=()
for k in 1 2 3; do
  "$BIN/cslam-client" --server "$ENDPOINT" --id "$k" --name "robot$k" --dataset "$SCENE/robot_$k" --rate "$RATE" \
    --depth-every "$DEPTH_EVERY" "${ADAPT[@]}" --byte-budget "$BUDGET" --summary-out "$RUN/client_${k}_summary.json" --progress-interval 5 > "$RUN/client_$k.log" 2>&1 &
  CLIENTS+=($!)
done
for pid in "${CLIENTS[@]}"; do wait "$pid" || { echo "a client failed; see $RUN/client_*.log" >&2; exit 1; }; done
if [ "$EXIT" = 1 ]; then
  wait $SERVER || { echo "server failed; see $RUN/server.log" >&2; exit 1; }
  trap - EXIT
else
  # The server keeps running for the viewer: take the trajectories from its HTTP API.
  sleep 2  # let the fusion and loop threads look at the last keyframes
  PORT=$(cat "$RUN/http_port" 2>/dev/null || echo "$HTTP_PORT")
  for k in 1 2 3; do
    curl -sf "http://127.0.0.1:$PORT/api/trajectories?client=$k&format=tum" > "$RUN/client_$k.txt" \
      || { echo "cannot fetch trajectories from the HTTP API on port $PORT; see $RUN/server.log" >&2; exit 1; }
  done
  curl -sf "http://127.0.0.1:$PORT/api/status" > "$RUN/status.json" || true
  # The live dense map as the server holds it (built from the keyframes the robots sent), once it
  # is settled: every keyframe integrated and meshed at the current poses (up to 30 s).
  for _ in $(seq 150); do
    curl -sf "http://127.0.0.1:$PORT/api/dense/status" -o "$RUN/dense_status.json" &&
      python3 -c 'import json,sys; sys.exit(0 if json.load(open(sys.argv[1])).get("settled") else 1)' \
        "$RUN/dense_status.json" && break
    sleep 0.2
  done
  curl -sf "http://127.0.0.1:$PORT/api/dense/cloud.ply" -o "$RUN/dense_cloud_live.ply" || true
  FUSED=$(python3 - "$RUN/status.json" <<'PY' || true
import json, sys
s = json.load(open(sys.argv[1]))
groups = {}
for c in s.get("clients", []):
    groups.setdefault(c.get("group"), []).append(c.get("id"))
print(" ".join(str(g) for g, m in groups.items() if len(m) > 1))
PY
)
fi
grep -E "fused client|final client" "$RUN/server.log" || true

if [ "$DEPTH_EVERY" -gt 1 ] || [ ${#ADAPT[@]} -gt 0 ]; then
  echo "== bandwidth (lean stream: full frames (H.264 pictures + lossless depth) every $DEPTH_EVERY and on request, light frames between; the default pair sends ~87 KB per frame here)"
else
  echo "== bandwidth (every frame full: JPEG q75 + lossless depth)"
fi
for k in 1 2 3; do
  python3 -c 'import json,sys; s=json.load(open(sys.argv[1])); n=max(1,s["frames_sent"]); print("client %s: %.1f KB/frame, %.2f MB/s at 30 Hz, %d of %d frames light, %d depth requests, %d full frames finer within the byte budget%s" % (sys.argv[2], s["bytes_sent"]/n/1e3, s["bytes_sent"]/n*30/1e6, s["frames_light"], n, s["depth_requests"], s["frames_finer"], ", adaptive rate: %d steps down, %d up, depth every %d at the end" % (s["rate_steps_down"], s["rate_steps_up"], s["depth_every_last"]) if s["rate_steps_down"] else ""))' "$RUN/client_${k}_summary.json" "$k" || true
done

echo "== server load (a worker behind its live frames tracks flow frames instead of skipping more: cslam-server --flow)"
python3 - "$RUN/stats.json" "$RUN/status.json" <<'PY' || true
import json, os, sys
path = next((p for p in sys.argv[1:] if os.path.exists(p)), None)
for c in (json.load(open(path)).get("clients", []) if path else []):
    print("client %s: %d frames processed, %d skipped, %d flow frames" % (c["id"], c["frames_processed"], c.get("frames_skipped", 0), c.get("frames_flow", 0)))
PY

echo "== accuracy (APE, metres, SE3 alignment)"
for k in 1 2 3; do
  printf "client %d: " "$k"
  "$BIN/cslam-eval" ate "$SCENE/robot_$k/groundtruth.txt" "$RUN/client_$k.txt" | tail -1
done
[ "$EXIT" = 1 ] && FUSED=$(ls "$RUN"/fused_*.txt 2>/dev/null | head -1 || true)
if [ -n "$FUSED" ]; then
  printf "fused group (all clients, one alignment): "
  "$BIN/cslam-eval" ate "$SCENE/robot_1/groundtruth.txt" "$RUN/client_1.txt" \
    --also "$SCENE/robot_2/groundtruth.txt" "$RUN/client_2.txt" "$SCENE/robot_3/groundtruth.txt" "$RUN/client_3.txt" \
    --aligned "$RUN/aligned_1.txt" "$RUN/aligned_2.txt" "$RUN/aligned_3.txt" | tail -1
else
  echo "no fused group: clients stayed in their own frames (see $RUN/stats.json)"
fi

# Accuracy of a cloud in the fused SLAM frame against the exact scene surface, moved into the
# scene's frame by the one SE3 that aligned the fused trajectories: "median / p95 / completeness".
cloud_line() {
  "$BIN/cslam-eval" cloud "$SCENE/scene.ply" "$1" --move-from "$RUN/client_1.txt" --move-to "$RUN/aligned_1.txt" --json \
    | python3 -c 'import json,sys; j=json.load(sys.stdin); c=j["c2c_test_to_ref"]; print("median %.1f mm, p95 %.1f mm, completeness %.1f %% within 2 cm (%d points)" % (1e3*c["median"], 1e3*c["p95"], 100*j["completeness"]["2cm"], j["test_points"]))'
}
LIVE="$RUN/dense_cloud_live.ply"
[ "$EXIT" = 1 ] && LIVE=$(ls "$RUN"/dense_cloud_*.ply 2>/dev/null | head -1 || true)
if [ -n "$FUSED" ] && [ -s "$LIVE" ]; then
  echo "== live dense map (built by the server from the keyframes the robots sent; no image files)"
  [ -s "$RUN/dense_status.json" ] && python3 -c 'import json,sys; d=json.load(open(sys.argv[1])); print("%d submaps, %d keyframes integrated, %d re-integrations, store %d keyframes %.1f MB, integration %.0f ms per keyframe (median), %s" % (d["submaps"], d["keyframes_integrated"], d["reintegrated"], d["store"]["keyframes"], d["store"]["payload_bytes"]/1e6, d["integrate_ms"]["p50"], "settled" if d.get("settled") else "not settled: %d pending, %d meshes stale, %d submaps to re-integrate" % (d["pending"], d["stale_meshes"], d["distorted_submaps"])))' "$RUN/dense_status.json" || true
  printf "live dense cloud vs exact surface:            "; cloud_line "$LIVE"
  "$BIN/cslam-recon" --dataset "$SCENE/robot_1" "$SCENE/robot_2" "$SCENE/robot_3" \
    --poses "$RUN/client_1.txt" "$RUN/client_2.txt" "$RUN/client_3.txt" --voxel 0.02 --out "$RUN/cloud_2cm.ply" > /dev/null 2>&1
  printf "offline cslam-recon, every frame, same voxel: "; cloud_line "$RUN/cloud_2cm.ply"
  if [ "$EXIT" = 0 ]; then
    PORT=$(cat "$RUN/http_port" 2>/dev/null || echo "$HTTP_PORT")
    curl -sf "http://127.0.0.1:$PORT/api/dense/occupancy.pgm" -o "$RUN/occupancy_live.pgm" || true
    curl -sf "http://127.0.0.1:$PORT/api/dense/octomap.bt" -o "$RUN/octomap_live.bt" || true
  fi
  PGM=$(ls "$RUN"/occupancy_*.pgm 2>/dev/null | head -1 || true)
  BT=$(ls "$RUN"/octomap_*.bt 2>/dev/null | head -1 || true)
  if [ -s "$PGM" ]; then
    python3 - "$PGM" "$BT" <<'PY'
import os, sys
data = open(sys.argv[1], "rb").read()
head = data.split(b"\n", 3)  # P5, "W H", "255", pixels
w, h = map(int, head[1].split())
px = head[3][: w * h]
occ, free = px.count(0), px.count(254)
bt = os.path.getsize(sys.argv[2]) if sys.argv[2] and os.path.exists(sys.argv[2]) else 0
print("navigation maps: 2D grid %d x %d cells at 5 cm (%d occupied, %d free, %d unknown), OctoMap %.0f KB"
      % (w, h, occ, free, w * h - occ - free, bt / 1024))
PY
  fi
fi

echo "== dense reconstruction from the fused poses"
"$BIN/cslam-recon" --dataset "$SCENE/robot_1" "$SCENE/robot_2" "$SCENE/robot_3" \
  --poses "$RUN/client_1.txt" "$RUN/client_2.txt" "$RUN/client_3.txt" --voxel 0.01 \
  --out "$RUN/cloud.ply" --mesh "$RUN/mesh.ply" 2>&1 | tail -2
if [ -n "$FUSED" ]; then
  # The cloud above is in the fused SLAM frame; for accuracy against the exact scene surface, the
  # same reconstruction from the poses aligned to the scene's world frame (one SE3 for all).
  echo "== reconstruction accuracy against the exact scene surface (scene.ply), aligned poses"
  "$BIN/cslam-recon" --dataset "$SCENE/robot_1" "$SCENE/robot_2" "$SCENE/robot_3" \
    --poses "$RUN/aligned_1.txt" "$RUN/aligned_2.txt" "$RUN/aligned_3.txt" --voxel 0.01 \
    --out "$RUN/cloud_world.ply" > /dev/null 2>&1
  "$BIN/cslam-eval" cloud "$SCENE/scene.ply" "$RUN/cloud_world.ply" | tail -4
fi

echo
echo "outputs: $RUN"
echo "  client_K.txt  trajectories (TUM, fused frame)   fused_*.txt  combined trajectory"
echo "  cloud.ply / mesh.ply  dense reconstruction     stats.json   run statistics (written when the server stops)"
echo "  dense_*.ply, occupancy_*.pgm/.yaml, octomap_*.bt  the server's live dense map and navigation maps (at exit)"
if [ "$EXIT" = 0 ]; then
  PORT=$(cat "$RUN/http_port" 2>/dev/null || echo "$HTTP_PORT")
  echo
  echo "web viewer: http://127.0.0.1:$PORT/   (Ctrl-C to stop the server; use --exit to skip this)"
  trap 'kill -TERM $SERVER 2>/dev/null || true' INT TERM
  wait $SERVER || true
  wait $SERVER 2>/dev/null || true
  trap - EXIT
  echo "server stopped; final trajectories and stats.json in $RUN"
fi
