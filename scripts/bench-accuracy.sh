#!/usr/bin/env bash
# SLAM accuracy benchmark on the real TUM sequences (fr1/desk: the paper's reconstruction sequence,
# fast sweeps; fr1/rpy: rotation): repeated threaded runs (median, min-max) and the deterministic
# stepped run (--sync) of one client on fr1/desk up to 1305031460.63 s (client 1 of the paper's
# 3-client split at 5 % under the one-to-one association: frames 1-198 of 573; with the default
# association, which keeps every colour frame, the same span is frames 1-219 of 596), fr1/desk whole and fr1/rpy whole; then the offline multi-client runs on fr1/desk
# (K = 2, 3 at 5 % overlap) with every fusion checked against ground truth.
# Usage: scripts/bench-accuracy.sh [RUNS=5] [OUT=bench_accuracy]   (needs a built tree)
set -euo pipefail
cd "$(dirname "$0")/.."
RUNS="${1:-5}"
OUT="${2:-bench_accuracy}"
BIN=build/bin
DESK="${CSLAM_TUM_DESK:-../shared/data/tum_fr1_desk}"
RPY="${CSLAM_TUM_RPY:-../shared/data/tum_fr1_rpy}"
MULTI_RUNS="${CSLAM_BENCH_MULTI_RUNS:-3}"
mkdir -p "$OUT"
for d in "$DESK" "$RPY"; do [ -f "$d/rgb.txt" ] || { echo "bench-accuracy: $d not found" >&2; exit 1; }; done

# Runs one cslam-slam and prints: ate rpe_t rpe_r keyframes wall_s cpu_s frames
one() {  # dataset range(all|a:b) mode(thr|sync) tag
  local ds=$1 range=$2 mode=$3 tag=$4 extra=()
  [ "$range" != all ] && extra+=(--range "$range")
  [ "$mode" = sync ] && extra+=(--sync)
  python3 - "$BIN" "$ds" "$OUT/$tag" "${extra[@]}" <<'PY'
import json, os, resource, subprocess, sys
bin_, ds, base, *extra = sys.argv[1:]
before = resource.getrusage(resource.RUSAGE_CHILDREN)
subprocess.run([f"{bin_}/cslam-slam", "--dataset", ds, "--camera", "tum1", "--out", base + ".txt", "--stats", base + ".json",
                "--quiet", "--log-level", "warn", *extra], check=True, stdout=subprocess.DEVNULL)
after = resource.getrusage(resource.RUSAGE_CHILDREN)
cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
ev = lambda *a: json.loads(subprocess.run([f"{bin_}/cslam-eval", *a, "--json"], check=True, capture_output=True, text=True).stdout)
gt = os.path.join(ds, "groundtruth.txt")
ate = ev("ate", gt, base + ".txt")["rmse"]
rpe = ev("rpe", gt, base + ".txt")
st = json.load(open(base + ".json"))
print(f'{ate:.4f} {rpe["translation_m"]["rmse"]:.4f} {rpe["rotation_deg"]["rmse"]:.3f} {st["keyframes"]} {st["wall_time_s"]:.2f} {cpu:.2f} {st["frames"]}')
PY
}

summary() {  # name; rows of numbers on stdin, column per figure
  python3 -c '
import sys, statistics
name = sys.argv[1]
rows = [list(map(float, l.split())) for l in sys.stdin if l.strip()]
cols = ["ATE m", "RPE1s m", "RPE1s deg", "keyframes", "wall s", "CPU s", "CPU ms/frame"]
rows = [r[:6] + [1000 * r[5] / r[6]] for r in rows]
out = []
for i, c in enumerate(cols):
  v = [r[i] for r in rows]
  out.append(f"{c} {statistics.median(v):.4g} ({min(v):.4g}-{max(v):.4g})" if len(v) > 1 else f"{c} {v[0]:.4g}")
print(f"{name:34s} " + " | ".join(out) + f"  [n={len(rows)}]")
' "$1"
}

echo "== machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), load $(cut -d' ' -f1-3 /proc/loadavg), revision $(git rev-parse --short HEAD 2>/dev/null || echo n/a)"
for spec in "desk198 $DESK 1:219" "desk $DESK all" "rpy $RPY all"; do
  set -- $spec
  name=$1 ds=$2 range=$3
  one "$ds" "$range" sync "${name}_sync" | summary "$name --sync (deterministic)"
  for r in $(seq 1 "$RUNS"); do one "$ds" "$range" thr "${name}_thr_$r"; done | summary "$name threaded"
done

echo "-- fr1/desk offline multi-client, 5 % overlap (fusions vs interpolated ground truth)"
for k in 2 3; do
  for mode in sync $(seq 1 "$MULTI_RUNS"); do
    dir="$OUT/multi_k${k}_$mode"
    flag=(); [ "$mode" = sync ] && flag=(--sync)
    "$BIN/cslam-slam" --dataset "$DESK" --camera tum1 --clients "$k" --overlap 5% --out-dir "$dir" "${flag[@]}" --log-level warn > "$dir.log" 2>&1
    fused=$(grep -c "^fusion:" "$dir.log" || true)
    printf "K=%d %-6s fusions %d  %s\n" "$k" "$mode" "$fused" "$(grep -E "combined ATE|client [0-9] ATE" "$dir.log" | sed 's/ (n=[0-9]*)//' | tr '\n' ' ')"
    "$BIN/cslam-eval" events "$dir/stats.json" --gt "$DESK/groundtruth.txt" | tail -n +2 | sed 's/^/    /' || true
  done
done
