#!/usr/bin/env bash
# Map-fusion benchmark: the fr1/rpy split (paper's ranges) into 2 and 3 offline clients at every
# overlap rate, with and without the group global BA, each fusion's transform checked against
# ground truth; then the time of one fusion on two larger maps (cslam-bench-fusion).
# Usage: scripts/bench-fusion.sh [RUNS=2] [OUT=bench_out/fusion]
set -euo pipefail
cd "$(dirname "$0")/.."
RUNS="${1:-2}"
OUT="${2:-bench_out/fusion}"
BIN=build/bin
D="${CSLAM_TUM_RPY:-../shared/data/tum_fr1_rpy}"
mkdir -p "$OUT"
[ -f "$D/rgb.txt" ] || { echo "bench-fusion: $D not found" >&2; exit 1; }
echo "== machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), load $(cut -d' ' -f1-3 /proc/loadavg)"
echo "-- single client, whole sequence (the SLAM-time reference)"
for r in $(seq 1 "$RUNS"); do
  "$BIN/cslam-slam" --dataset "$D" --camera tum1 --out "$OUT/single_$r.txt" --stats "$OUT/single_$r.json" --quiet --log-level warn | grep -o "wall [0-9.]* s"
done
for gba in on off; do
  flag=""; [ "$gba" = off ] && flag="--no-group-ba"
  echo "-- fr1/rpy offline multi-client, group global BA $gba"
  for k in 2 3; do
    for eta in 0.5% 2.5% 5% 10%; do
      [ "$gba" = off ] && [ "$eta" != 5% ] && continue  # the ablation at 5 % only
      for r in $(seq 1 "$RUNS"); do
        dir="$OUT/k${k}_${eta%\%}_gba${gba}_$r"
        "$BIN/cslam-slam" --dataset "$D" --camera tum1 --clients "$k" --overlap "$eta" --out-dir "$dir" --log-level warn $flag > "$dir.log" 2>&1 || true
        printf "K=%d eta=%-5s run %d: " "$k" "$eta" "$r"
        grep -E "SLAM time|combined ATE|fusion:|group global BA" "$dir.log" | sed 's/ (frame time [0-9.]*)//' | tr '\n' ' '; echo
        if [ "$gba" = on ]; then
          est=$(ls "$dir"/fused_*.txt 2>/dev/null | head -1 || true)
          [ -n "$est" ] && "$BIN/cslam-eval" events "$dir/stats.json" --gt "$D/groundtruth.txt" --offset auto --est "$est" | grep -E "offset|fusion|loop" | sed "s/^/    /" || true
          "$BIN/cslam-eval" events "$dir/stats.json" --gt "$D/groundtruth.txt" | grep -E "^fusion|^loop" | sed "s/^/    offset 0: /" || true
        fi
      done
    done
  done
done
echo "-- one fusion on two larger maps (synthetic, 2 robots x 600 frames, 10 % of the path shared)"
SYN="$OUT/synth_late"
[ -f "$SYN/robot_2/groundtruth.txt" ] || "$BIN/cslam-synth" --robots 2 --frames 600 --overlap 0.1 --no-loop --out "$SYN" --force --log-level warn > /dev/null
"$BIN/cslam-bench-fusion" --dataset-a "$SYN/robot_1" --dataset-b "$SYN/robot_2" --range-a 1:380 --range-b 1:380 --runs 5 --group-ba-runs 2
"$BIN/cslam-bench-fusion" --dataset-a "$SYN/robot_1" --dataset-b "$SYN/robot_2" --runs 5 --group-ba-runs 2
