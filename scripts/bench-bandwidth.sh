#!/usr/bin/env bash
# Bandwidth benchmark: each robot streams at 30 Hz (lossless pacing, every frame processed) to
# one cslam-server --deterministic, once with the default stream (every frame JPEG q75 + lossless
# zstd depth) and once with the lean stream (cslam-client --depth-every K: full frames, full
# depth with standalone colour, on every K-th frame and whenever the server asks for one; light
# frames between: H.264 colour and depth at every 4th pixel of every 4th row), alternated run by
# run. Reports per robot: mean bytes/s on the wire, KB per frame, the share of light frames,
# depth requests, how many frames after the asking frame they were answered (mean), and the ATE of its trajectory
# (cslam-eval, SE3 alignment); medians and min-max over the runs.
# Sequences: desk (tum_fr1_desk, 1 robot), rpy (tum_fr1_rpy, 1 robot), demo (the demo scene:
# 3 robots streaming together, cslam-synth --preset demo), demo:SEED (the same preset with another
# scene seed: one demo run is one chaotic outcome, so the lean/default ATE ratio is also reported
# over every demo scene given, e.g. "demo demo:101 demo:102 ...").
# Usage: scripts/bench-bandwidth.sh [OUT=bench_out/bandwidth] [RUNS=3] [K=5] [SEQUENCES="desk rpy demo"]
# Environment: CSLAM_BANDWIDTH_CLIENT_ARGS: more cslam-client options for the lean runs (e.g. --colour-crf 26).
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/lib/bench-run.sh
OUT="${1:-bench_out/bandwidth}"
RUNS="${2:-3}"
K="${3:-5}"
SEQUENCES="${4:-desk rpy demo}"
BIN="$PWD/build/bin"
DATA="${CSLAM_DATA:-$PWD/../shared/data}"
mkdir -p "$OUT"
loadavg() { cut -d' ' -f1-3 /proc/loadavg; }
echo "== machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), load $(loadavg)"
echo "== revision $(git rev-parse --short HEAD)$(git diff --quiet || echo '+dirty'), $RUNS run(s), lean stream K=$K"

datasets_of() {
  case "$1" in
    desk) echo "$DATA/tum_fr1_desk" ;;
    rpy) echo "$DATA/tum_fr1_rpy" ;;
    demo | demo:*)
      local scene="$OUT/demo_scene" seed=()
      if [ "$1" != demo ]; then scene="$OUT/demo_scene_${1#demo:}"; seed=(--seed "${1#demo:}"); fi
      if [ ! -f "$scene/robot_3/groundtruth.txt" ]; then
        "$BIN/cslam-synth" --preset demo "${seed[@]}" --out "$scene" --force --log-level warn > /dev/null
      fi
      echo "$scene/robot_1 $scene/robot_2 $scene/robot_3" ;;
    *) echo "unknown sequence $1" >&2; exit 2 ;;
  esac
}

# run_case DIR MODE DATASETS...: one server, one lossless 30 Hz client per dataset, together.
run_case() {
  local dir="$1" mode="$2"; shift 2
  rm -rf "$dir"; mkdir -p "$dir"
  local n=$#
  /usr/bin/time -f "%U %S %M %e" -o "$dir/server_time.txt" \
    "$BIN/cslam-server" --bind "tcp://127.0.0.1:*" --endpoint-file "$dir/endpoint" --clients "$n" --exit-when-done \
    --deterministic --http off --out-dir "$dir/out" --log-level warn > "$dir/server.log" 2>&1 &
  local server_pid=$!
  wait_endpoint "$dir/endpoint"
  local endpoint; endpoint=$(head -1 "$dir/endpoint")
  local extra=()
  [ "$mode" = lean ] && extra=(--depth-every "$K" ${CSLAM_BANDWIDTH_CLIENT_ARGS:-})
  local pids=() k=0 ds
  for ds in "$@"; do
    k=$((k + 1))
    /usr/bin/time -f "%U %S" -o "$dir/client_${k}_time.txt" \
      "$BIN/cslam-client" --server "$endpoint" --id "$k" --dataset "$ds" --rate 30 "${extra[@]}" \
      --summary-out "$dir/client_$k.json" --progress-interval 1000 --reply-timeout 60 --log-level info \
      > "$dir/client_$k.log" 2>&1 &
    pids+=($!)
  done
  wait_run "$dir" "$server_pid" "${pids[@]}"
  k=0
  for ds in "$@"; do
    k=$((k + 1))
    "$BIN/cslam-eval" ate "$ds/groundtruth.txt" "$dir/out/client_$k.txt" --json > "$dir/ate_$k.json" 2>/dev/null || echo '{}' > "$dir/ate_$k.json"
  done
}

for seq in $SEQUENCES; do
  read -r -a sets <<< "$(datasets_of "$seq")"
  for r in $(seq 1 "$RUNS"); do
    for mode in default lean; do
      echo "-- $seq run $r $mode (load $(loadavg))"
      run_case "$OUT/${seq/:/_}/${mode}_r$r" "$mode" "${sets[@]}"
    done
  done
done

python3 - "$OUT" "$RUNS" "$SEQUENCES" <<'EOF'
import json, os, random, statistics, sys
out, runs, seqs = sys.argv[1], int(sys.argv[2]), sys.argv[3].split()
def med(v):
    return f"{statistics.median(v):.4g} ({min(v):.4g}-{max(v):.4g})" if v else "n/a"
print("\n| sequence | stream | MB/s per robot | KB/frame | light frames | depth requests | request lag frames | ATE m (mean over robots) | server CPU s |")
print("|---|---|---|---|---|---|---|---|---|")
ates_of = {}  # (sequence, stream) -> every run's ATE
for seq in seqs:
    for mode in ("default", "lean"):
        mbs, kbf, share, req, lag, ate, cpu = [], [], [], [], [], [], []
        for r in range(1, runs + 1):
            d = f"{out}/{seq.replace(':', '_')}/{mode}_r{r}"
            if not os.path.isdir(d): continue
            rates, kbs, shares, reqs, lags, ates = [], [], [], [], [], []
            k = 1
            while os.path.exists(f"{d}/client_{k}.json"):
                s = json.load(open(f"{d}/client_{k}.json"))
                rates.append(s["bytes_per_s"] / 1e6)
                kbs.append(s["bytes_sent"] / max(1, s["frames_sent"]) / 1e3)
                shares.append(100.0 * s.get("frames_light", 0) / max(1, s["frames_sent"]))
                reqs.append(s.get("depth_requests", 0))
                if s.get("depth_requests", 0): lags.append(s.get("depth_request_lag_frames", {}).get("mean", 0))
                a = json.load(open(f"{d}/ate_{k}.json")) if os.path.exists(f"{d}/ate_{k}.json") else {}
                if "rmse" in a: ates.append(a["rmse"])
                k += 1
            if not rates: continue
            mbs.append(statistics.mean(rates)); kbf.append(statistics.mean(kbs)); share.append(statistics.mean(shares))
            req.append(sum(reqs))
            if lags: lag.append(statistics.mean(lags))
            if len(ates) == len(rates): ate.append(statistics.mean(ates))
            t = open(f"{d}/server_time.txt").read().split()
            cpu.append(float(t[0]) + float(t[1]))
        print(f"| {seq} | {mode} | {med(mbs)} | {med(kbf)} | {med(share)} % | {med(req)} | {med(lag)} | {med(ate)} | {med(cpu)} |")
        ates_of[(seq, mode)] = ate
# How far one sitting of 3 runs per stream can land from the streams' cost: the ratio of two
# 3-run medians drawn from these runs (fixed seed), for the default pair against itself (its own
# run-to-run scatter: multi-robot runs depend on timing) and for the lean stream against it.
def three_run_ratios(num, den, same):
    rng, ratios = random.Random(1), []
    for _ in range(10000):
        if same:
            pick = rng.sample(num, 6)
            a, b = pick[:3], pick[3:]
        else:
            a, b = rng.sample(num, 3), rng.sample(den, 3)
        ratios.append(statistics.median(a) / statistics.median(b))
    ratios.sort()
    q = lambda p: ratios[int(p * (len(ratios) - 1))]
    above = sum(r > 1.05 for r in ratios) / len(ratios)
    return f"median {q(0.5):.3f}, p5-p95 {q(0.05):.3f}-{q(0.95):.3f}, above 1.05 in {100 * above:.0f} %"
for seq in seqs:
    d, l = ates_of.get((seq, "default"), []), ates_of.get((seq, "lean"), [])
    if len(d) >= 6 and len(l) >= 3 and len(set(d)) > 1:
        print(f"\n{seq}: a 3-run sitting's ATE ratio, resampled from these runs: default / default "
              f"{three_run_ratios(d, d, True)}; lean / default {three_run_ratios(l, d, False)}")
demo_ates = {m: [a for s in seqs if s.startswith("demo") for a in ates_of.get((s, m), [])] for m in ("default", "lean")}
if len([s for s in seqs if s.startswith("demo")]) > 1 and demo_ates["default"] and demo_ates["lean"]:
    d, l = statistics.mean(demo_ates["default"]), statistics.mean(demo_ates["lean"])
    print(f"\nDemo scenes ({len(demo_ates['default'])} default / {len(demo_ates['lean'])} lean runs): mean ATE "
          f"default {d:.5f} m, lean {l:.5f} m, lean/default {l / d:.3f}")
EOF
