#!/usr/bin/env bash
# fr1/rpy CPU against stock ORB-SLAM2, back to back. Each round runs stock ORB-SLAM2 (the reference
# tool in ../shared/tools/orbslam2-reference, unpaced) and then every cslam-slam variant, so that
# this VM's drifting speed falls on all of them alike. Prints each run's user + sys seconds and ATE,
# then per variant its CPU over the same round's ORB-SLAM2 (median and min-max over the rounds).
# Usage: scripts/bench-orbslam2-cpu.sh [RUNS=3] [OUT=bench_out/orbslam2_cpu] [VARIANT...]
#   VARIANT: cslam-slam options as one string (default: "" and "--flow always"); a leading
#   "bin=PATH " runs another cslam-slam build, e.g. "bin=/tmp/old/cslam-slam ".
# Needs the reference tool built once (its README: build.sh; $ORBSLAM2_ROOT, default /tmp/orbslam2,
# with voc_rpy.bin). Env: CSLAM_TUM_RPY (the dataset), ORBSLAM2_REF (the tool's folder).
set -euo pipefail
cd "$(dirname "$0")/.."
RUNS="${1:-3}"
OUT="${2:-bench_out/orbslam2_cpu}"
shift 2 || shift $#
VARIANTS=("$@")
[ ${#VARIANTS[@]} -gt 0 ] || VARIANTS=("" "--flow always")
D="${CSLAM_TUM_RPY:-../shared/data/tum_fr1_rpy}"
REF="${ORBSLAM2_REF:-../shared/tools/orbslam2-reference}"
VOC="${ORBSLAM2_ROOT:-/tmp/orbslam2}/voc_rpy.bin"
[ -f "$D/rgb.txt" ] || { echo "bench-orbslam2-cpu: $D not found" >&2; exit 1; }
[ -x "$REF/run.sh" ] || { echo "bench-orbslam2-cpu: no reference tool at $REF" >&2; exit 1; }
[ -s "$VOC" ] || { echo "bench-orbslam2-cpu: no $VOC: build the reference tool first ($REF/README.md)" >&2; exit 1; }
mkdir -p "$OUT"
frames=$(grep -vc '^#' "$D/rgb.txt")

ate() { build/bin/cslam-eval ate "$D/groundtruth.txt" "$1" --json | python3 -c 'import json,sys; print(json.load(sys.stdin)["rmse"])'; }

echo "== machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), load $(cut -d' ' -f1-3 /proc/loadavg); revision $(git rev-parse --short HEAD)$(git diff --quiet || echo '+dirty'); $(date '+%F %T')"
rows="$OUT/rows.txt"
: > "$rows"
for r in $(seq 1 "$RUNS"); do
  line=$(VOC="$VOC" "$REF/run.sh" "$D" "$REF/TUM1.yaml" "$OUT/orbslam2_$r.txt" 2> "$OUT/orbslam2_$r.log" | tail -1)
  orb=$(sed -n 's/.*user+sys_s \([0-9.]*\).*/\1/p' <<< "$line")
  [ -n "$orb" ] || { echo "bench-orbslam2-cpu: ORB-SLAM2 printed no CPU time: $line" >&2; exit 1; }
  echo "round $r  ORB-SLAM2 ${orb} s  ATE $(ate "$OUT/orbslam2_$r.txt" | cut -c1-6) m"
  for v in "${!VARIANTS[@]}"; do
    opts="${VARIANTS[$v]}" bin=build/bin/cslam-slam
    if [[ "$opts" =~ ^bin=([^ ]+)\ ?(.*)$ ]]; then bin="${BASH_REMATCH[1]}" opts="${BASH_REMATCH[2]}"; fi
    traj="$OUT/cslam_${v}_$r.txt"
    # shellcheck disable=SC2086
    /usr/bin/time -f "%U %S" -o "$OUT/cslam_${v}_$r.time" "$bin" --dataset "$D" --camera tum1 --out "$traj" --quiet \
      --log-level warn $opts > /dev/null
    cpu=$(awk '{print $1 + $2}' "$OUT/cslam_${v}_$r.time")
    echo "round $r  variant $v [${VARIANTS[$v]:-default}]  ${cpu} s  ATE $(ate "$traj" | cut -c1-6) m"
    echo "$v $orb $cpu" >> "$rows"
  done
done
echo "-- fr1/rpy, $frames frames, user + sys over the same round's stock ORB-SLAM2"
for v in "${!VARIANTS[@]}"; do
  python3 - "$rows" "$v" "${VARIANTS[$v]:-default}" "$frames" << 'EOF'
import statistics, sys
rows = [l.split() for l in open(sys.argv[1])]
v, name, frames = sys.argv[2], sys.argv[3], int(sys.argv[4])
pairs = [(float(o), float(c)) for k, o, c in rows if k == v]
ratio = [c / o for o, c in pairs]
ms = [1000 * c / frames for o, c in pairs]
orb = [1000 * o / frames for o, c in pairs]
print(f"{name:32s} ratio median {statistics.median(ratio):.3f} (min {min(ratio):.3f}, max {max(ratio):.3f}); "
      f"{statistics.median(ms):.1f} ms per frame ({min(ms):.1f}-{max(ms):.1f}) against ORB-SLAM2's "
      f"{statistics.median(orb):.1f} ({min(orb):.1f}-{max(orb):.1f}), n={len(pairs)}")
EOF
done
