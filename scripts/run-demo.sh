#!/usr/bin/env bash
# Runs the demo pipeline with already-built programs (scripts/demo.sh builds first).
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=build/bin
OUT="${CSLAM_DEMO_OUT:-demo_out}"
mkdir -p "$OUT"
echo "== cslam demo: output in $OUT"
# Until the synthetic generator exists, evaluate a generated example trajectory.
python3 - "$OUT" <<'PY'
import math, random, sys
out = sys.argv[1]
random.seed(1)
with open(f"{out}/gt.txt", "w") as g, open(f"{out}/est.txt", "w") as e:
    for i in range(300):
        t = i / 30.0
        x, y, z = math.cos(t), math.sin(t), 0.1 * t
        g.write(f"{t:.6f} {x:.6f} {y:.6f} {z:.6f} 0 0 0 1\n")
        e.write(f"{t:.6f} {x+random.gauss(0,0.01):.6f} {y+random.gauss(0,0.01):.6f} {z:.6f} 0 0 0 1\n")
PY
"$BIN/cslam-eval" ate "$OUT/gt.txt" "$OUT/est.txt"
