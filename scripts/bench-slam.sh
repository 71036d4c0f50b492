#!/usr/bin/env bash
# SLAM benchmark: repeated cslam-slam runs on the real fr1/rpy sequence (loop closing off and on)
# and on the synthetic demo robots; offline multi-client fusion on fr1/rpy (2 and 3 clients at the
# paper's overlap rates). Prints median and min-max of every figure. Needs a built tree.
# Usage: scripts/bench-slam.sh [RUNS=3] [OUT=bench_out]
set -euo pipefail
cd "$(dirname "$0")/.."
RUNS="${1:-3}"
OUT="${2:-bench_out}"
BIN=build/bin
D="${CSLAM_TUM_RPY:-../shared/data/tum_fr1_rpy}"
mkdir -p "$OUT"
[ -f "$D/rgb.txt" ] || { echo "bench-slam: $D not found" >&2; exit 1; }
SYN="$OUT/synth_demo"
[ -f "$SYN/scene.ply" ] || "$BIN/cslam-synth" --preset demo --out "$SYN" --log-level warn

summary() {  # name, then one number per line on stdin
  python3 -c '
import sys, statistics
name = sys.argv[1]
v = [float(x) for x in sys.stdin.read().split()]
if v: print(f"{name:48s} median {statistics.median(v):9.4f}  min {min(v):9.4f}  max {max(v):9.4f}  (n={len(v)})")
' "$1"
}
json_get() { python3 -c 'import json,sys; d=json.load(open(sys.argv[1])); 
for k in sys.argv[2].split("."): d=d[k]
print(d)' "$1" "$2"; }
ate() { "$BIN/cslam-eval" ate "$1" "$2" --json | python3 -c 'import json,sys; print(json.load(sys.stdin)["rmse"])'; }
rpe() { "$BIN/cslam-eval" rpe "$1" "$2" --json | python3 -c 'import json,sys; d=json.load(sys.stdin); print(d["translation_m"]["rmse"], d["rotation_deg"]["rmse"])'; }

echo "== machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), load $(cut -d' ' -f1-3 /proc/loadavg)"
for mode in noloop loop; do
  flag=""; [ "$mode" = noloop ] && flag="--no-loop"
  for r in $(seq 1 "$RUNS"); do
    "$BIN/cslam-slam" --dataset "$D" --camera tum1 $flag --out "$OUT/rpy_${mode}_$r.txt" --stats "$OUT/rpy_${mode}_$r.json" --quiet --log-level warn > /dev/null
  done
  echo "-- fr1/rpy, loop closing $mode, $RUNS runs"
  for r in $(seq 1 "$RUNS"); do ate "$D/groundtruth.txt" "$OUT/rpy_${mode}_$r.txt"; done | summary "ATE RMSE (m, SE3)"
  for r in $(seq 1 "$RUNS"); do rpe "$D/groundtruth.txt" "$OUT/rpy_${mode}_$r.txt" | cut -d' ' -f1; done | summary "RPE 1 s translation RMSE (m)"
  for r in $(seq 1 "$RUNS"); do rpe "$D/groundtruth.txt" "$OUT/rpy_${mode}_$r.txt" | cut -d' ' -f2; done | summary "RPE 1 s rotation RMSE (deg)"
  for k in frames_lost wall_time_s peak_rss_mb keyframes loops; do
    for r in $(seq 1 "$RUNS"); do json_get "$OUT/rpy_${mode}_$r.json" "$k"; done | summary "$k"
  done
  for k in extract_ms.median track_ms.median extract_plus_track_ms.median local_ba_ms.median loop_query_ms.median global_ba_ms.median; do
    for r in $(seq 1 "$RUNS"); do json_get "$OUT/rpy_${mode}_$r.json" "$k"; done | summary "$k (per-run median)"
  done
done
echo "-- fr1/rpy loops vs ground truth (interpolated; time offset estimated from each run's trajectory)"
for r in $(seq 1 "$RUNS"); do
  "$BIN/cslam-eval" events "$OUT/rpy_loop_$r.json" --gt "$D/groundtruth.txt" --offset auto --est "$OUT/rpy_loop_$r.txt" | sed "s/^/run $r: /"
  "$BIN/cslam-eval" events "$OUT/rpy_loop_$r.json" --gt "$D/groundtruth.txt" | tail -n +3 | sed "s/^/run $r, offset 0: /"
done
echo "-- synthetic demo, single robot each, loop closing on"
for k in 1 2 3; do
  for r in $(seq 1 "$RUNS"); do
    "$BIN/cslam-slam" --dataset "$SYN/robot_$k" --out "$OUT/syn_${k}_$r.txt" --quiet --log-level warn > /dev/null
    ate "$SYN/robot_$k/groundtruth.txt" "$OUT/syn_${k}_$r.txt"
  done | summary "robot $k ATE RMSE (m)"
done
echo "-- synthetic demo robot 1 (loop), loop closing off"
for r in $(seq 1 "$RUNS"); do
  "$BIN/cslam-slam" --dataset "$SYN/robot_1" --no-loop --out "$OUT/syn_1_noloop_$r.txt" --quiet --log-level warn > /dev/null
  ate "$SYN/robot_1/groundtruth.txt" "$OUT/syn_1_noloop_$r.txt"
done | summary "robot 1 ATE RMSE, no loop closing (m)"
if [ "${CSLAM_BENCH_FUSION:-1}" = 1 ]; then
  echo "-- fr1/rpy offline multi-client (paper split), fusion"
  for k in 2 3; do
    for eta in 0.5% 2.5% 5% 10%; do
      dir="$OUT/multi_${k}_${eta%\%}"
      "$BIN/cslam-slam" --dataset "$D" --camera tum1 --clients "$k" --overlap "$eta" --out-dir "$dir" --log-level warn > "$dir.log" 2>&1 || true
      printf "K=%d eta=%-5s " "$k" "$eta"
      grep -E "SLAM time|combined ATE|fusion:|group global BA" "$dir.log" | tr '\n' ' '; echo
      "$BIN/cslam-eval" events "$dir/stats.json" --gt "$D/groundtruth.txt" --offset auto --est "$(ls "$dir"/fused_*.txt | head -1)" | sed "s/^/    /" || true
      "$BIN/cslam-eval" events "$dir/stats.json" --gt "$D/groundtruth.txt" | tail -n 1 | sed "s/^/    offset 0: /" || true
    done
  done
fi
