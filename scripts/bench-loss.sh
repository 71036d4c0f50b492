#!/usr/bin/env bash
# A long tracking loss on a real sequence: the lens is "covered" for a stretch (the colour and depth
# images listed for [FROM, TO) seconds after the first frame are replaced by black and empty ones),
# longer than max_lost_seconds, so tracking starts a second map. Map fusion joins it to the first
# when the camera sees the first map's places again; the trajectory then covers both maps.
# Runs cslam-slam --sync and RUNS threaded runs, with and without map fusion, and prints the poses
# written, the map fusions and the ATE. The dataset is only read: the covered copy is a listing in
# a scratch folder whose rgb/ and depth/ link to the original.
# Usage: scripts/bench-loss.sh [RUNS=3] [DATASET=../shared/data/tum_fr1_desk] [FROM=3.2] [TO=7.7]
set -euo pipefail
cd "$(dirname "$0")/.."
RUNS="${1:-3}"
DS="$(realpath "${2:-../shared/data/tum_fr1_desk}")"
FROM="${3:-3.2}"
TO="${4:-7.7}"
BIN=build/bin
[ -f "$DS/rgb.txt" ] || { echo "bench-loss: $DS/rgb.txt not found" >&2; exit 1; }
WORK="$(mktemp -d /tmp/cslam-bench-loss.XXXXXX)"
trap 'rm -rf "$WORK"' EXIT
COVERED="$WORK/$(basename "$DS")_covered"   # keeps the folder name, so the camera rule sees it
mkdir -p "$COVERED"
ln -s "$DS/rgb" "$COVERED/rgb"
ln -s "$DS/depth" "$COVERED/depth"
cp "$DS/groundtruth.txt" "$COVERED/"
[ -f "$DS/camera.yaml" ] && cp "$DS/camera.yaml" "$COVERED/"
/usr/bin/python3 - "$DS" "$COVERED" "$FROM" "$TO" <<'PY'
import sys
import cv2
import numpy as np
src, dst, t0, t1 = sys.argv[1], sys.argv[2], float(sys.argv[3]), float(sys.argv[4])
h, w = cv2.imread(src + "/" + [l.split()[1] for l in open(src + "/rgb.txt") if not l.startswith("#")][0]).shape[:2]
cv2.imwrite(dst + "/black.png", np.zeros((h, w, 3), np.uint8))
cv2.imwrite(dst + "/empty.png", np.zeros((h, w), np.uint16))
first = min(float(l.split()[0]) for l in open(src + "/rgb.txt") if not l.startswith("#"))
covered = 0
for name, blank in (("rgb.txt", "black.png"), ("depth.txt", "empty.png")):
    out = []
    for line in open(src + "/" + name):
        if line.startswith("#") or not line.strip():
            out.append(line)
            continue
        stamp, path = line.split()[:2]
        if t0 <= float(stamp) - first < t1:
            path = blank
            covered += name == "rgb.txt"
        out.append(f"{stamp} {path}\n")
    open(dst + "/" + name, "w").writelines(out)
print(f"covered {covered} colour frames, {t0:.1f}-{t1:.1f} s after the first frame")
PY

echo "== machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), load $(cut -d' ' -f1-3 /proc/loadavg), revision $(git rev-parse --short HEAD 2>/dev/null || echo n/a)"
one() {  # tag, extra cslam-slam options...
  local tag=$1; shift
  local out="$WORK/$tag"
  "$BIN/cslam-slam" --dataset "$COVERED" --out "$out.txt" --stats "$out.json" --quiet --log-level warn "$@" > "$out.log" 2>&1
  local ate
  ate=$("$BIN/cslam-eval" ate "$COVERED/groundtruth.txt" "$out.txt" --json | /usr/bin/python3 -c 'import json,sys; print("%.4f" % json.load(sys.stdin)["rmse"])')
  /usr/bin/python3 - "$out.json" "$tag" "$ate" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
print(f'{sys.argv[2]:22s} frames tracked {s["frames_tracked"]:4d}  poses written {s["trajectory_poses"]:4d}  maps {s["maps"]}  '
      f'map fusions {s["map_fusions"]}  ATE {sys.argv[3]} m')
PY
}
one sync_fusion --sync
one sync_no_fusion --sync --no-fusion
for r in $(seq 1 "$RUNS"); do
  one "threaded_fusion_$r"
  one "threaded_no_fusion_$r" --no-fusion
done
