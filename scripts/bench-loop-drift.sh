#!/usr/bin/env bash
# Loop-closing benchmark on a synthetic loop with injected drift: one robot drives a closed loop
# through the procedural room with realistic degradations (cslam-synth --noise: depth noise ~ z^2,
# missing depth at grazing angles, image noise, motion blur). Runs cslam-slam with loop closing on
# and off RUNS times each and prints the ATE RMSE medians and their ratio. Needs a built tree.
# Usage: scripts/bench-loop-drift.sh [RUNS=5] [FRAMES=600] [OUT=bench_out/loop_drift]
set -euo pipefail
cd "$(dirname "$0")/.."
RUNS="${1:-5}"
FRAMES="${2:-600}"
OUT="${3:-bench_out/loop_drift}"
BIN=build/bin
mkdir -p "$OUT"
SEQ="$OUT/scene_$FRAMES"
[ -f "$SEQ/robot_1/groundtruth.txt" ] || "$BIN/cslam-synth" --single --frames "$FRAMES" --noise --out "$SEQ" --force --log-level warn > /dev/null
GT="$SEQ/robot_1/groundtruth.txt"
echo "== machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), load $(cut -d' ' -f1-3 /proc/loadavg)"
for mode in on off; do
  flag=""; [ "$mode" = off ] && flag="--no-loop"
  for r in $(seq 1 "$RUNS"); do
    "$BIN/cslam-slam" --dataset "$SEQ/robot_1" $flag --out "$OUT/${mode}_$r.txt" --stats "$OUT/${mode}_$r.json" --quiet --log-level warn > /dev/null
    "$BIN/cslam-eval" ate "$GT" "$OUT/${mode}_$r.txt" --json | python3 -c 'import json,sys; print(json.load(sys.stdin)["rmse"])' > "$OUT/${mode}_$r.ate"
  done
done
python3 - "$OUT" "$RUNS" <<'PY'
import json, statistics, sys
out, runs = sys.argv[1], int(sys.argv[2])
ate = {m: [float(open(f"{out}/{m}_{r}.ate").read()) for r in range(1, runs + 1)] for m in ("on", "off")}
loops = [json.load(open(f"{out}/on_{r}.json"))["loops"] for r in range(1, runs + 1)]
gba = [json.load(open(f"{out}/on_{r}.json"))["global_ba_ms"].get("median", float("nan")) for r in range(1, runs + 1)]
for m in ("on", "off"):
    v = ate[m]
    print(f"loop closing {m:3s}: ATE RMSE median {statistics.median(v):.4f} m  (min {min(v):.4f}, max {max(v):.4f}; runs: {' '.join(f'{x:.4f}' for x in v)})")
print(f"loops closed per run: {loops}; global BA ms (per-run median): {' '.join(f'{x:.0f}' for x in gba)}")
print(f"ratio of medians off/on: {statistics.median(ate['off']) / statistics.median(ate['on']):.2f}x")
PY
