#!/usr/bin/env bash
# The paper's experiment streamed live: fr1/desk split into 3 robots at 5 % overlap (cslam-eval
# split), each a `cslam-client --live --preload` at the camera's 30 Hz, all started together,
# against one cslam-server. Per run: each robot's frames tracked (poses in the server's trajectory
# / frames in its range), frames skipped by the server, pose latency p50/p99 (capture to ack, from
# the clients' summaries), flow frames, and the fused ATE (one alignment over the three robots).
# Server variants are alternated run by run (VARIANTS="ARGS_A|ARGS_B", e.g. "--flow under-load|--flow off"; a variant
# "server=PATH ARGS" runs that cslam-server binary, e.g. the previous build's copied aside).
# Usage: scripts/bench-live-split.sh [RUNS=3] [OUT=bench_out/live_split] [VARIANTS=""] [DATASET=../shared/data/tum_fr1_desk]
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/lib/bench-run.sh
RUNS="${1:-3}"
OUT="${2:-bench_out/live_split}"
IFS='|' read -ra VARIANTS <<< "${3:-}"
[ "${#VARIANTS[@]}" -gt 0 ] || VARIANTS=("")
DS="${4:-../shared/data/tum_fr1_desk}"
BIN=build/bin
[ -f "$DS/rgb.txt" ] || { echo "bench-live-split: $DS not found" >&2; exit 1; }
mkdir -p "$OUT"
# Frames of the dataset as cslam-client pairs them (every colour frame with a depth image within 20 ms).
N=$(/usr/bin/python3 - "$DS" <<'PY'
import bisect, sys
d = sys.argv[1]
read = lambda f: [float(l.split()[0]) for l in open(f"{d}/{f}") if l.strip() and not l.startswith("#")]
rgb, depth = read("rgb.txt"), sorted(read("depth.txt"))
def near(t):
    i = bisect.bisect_left(depth, t)
    return min(abs(depth[j] - t) for j in (i - 1, i) if 0 <= j < len(depth)) <= 0.02
print(sum(1 for t in rgb if near(t)))
PY
)
mapfile -t RANGES < <("$BIN/cslam-eval" split --frames "$N" --clients 3 --overlap 0.05 | awk '/^client/ {print $3 ":" $4}')
echo "== machine: $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg); revision $(git rev-parse --short HEAD)$(git diff --quiet || echo '+dirty')"
echo "== $DS: $N frames, robots ${RANGES[*]}, $RUNS run(s) per variant"

run_case() {  # dir variant
  local dir=$1 VARIANT_BIN VARIANT_ARGS
  server_variant "$2"
  local args=$VARIANT_ARGS
  rm -rf "$dir"; mkdir -p "$dir"
  # shellcheck disable=SC2086
  /usr/bin/time -f "%U %S %M %e" -o "$dir/server_time.txt" \
    "$VARIANT_BIN" --bind "tcp://127.0.0.1:*" --endpoint-file "$dir/endpoint" --clients 3 --exit-when-done --http off \
    --heartbeat-timeout 30 --out-dir "$dir/out" --log-level warn $args > "$dir/server.log" 2>&1 &
  local server=$!
  wait_endpoint "$dir/endpoint"
  local start_at; start_at=$(/usr/bin/python3 -c "import time; print(time.time() + 15)")
  local pids=() k
  for k in 1 2 3; do
    "$BIN/cslam-client" --server "$(head -1 "$dir/endpoint")" --id "$k" --dataset "$DS" --range "${RANGES[$((k - 1))]}" --live --preload \
      --start-at "$start_at" --reply-timeout 60 --summary-out "$dir/client_$k.json" --progress-interval 1000 --log-level warn \
      > "$dir/client_$k.log" 2>&1 &
    pids+=($!)
  done
  wait_run "$dir" "$server" "${pids[@]}"
}

for r in $(seq 1 "$RUNS"); do
  for vi in "${!VARIANTS[@]}"; do
    run_case "$OUT/v${vi}_r$r" "${VARIANTS[$vi]}"
    echo "run $r [${VARIANTS[$vi]:-defaults}] done, load $(cut -d' ' -f1 /proc/loadavg)"
  done
done

/usr/bin/python3 - "$OUT" "$RUNS" "$DS" "$BIN" "${RANGES[@]}" -- "${VARIANTS[@]}" <<'PY' | tee "$OUT/summary.md"
import json, statistics, subprocess, sys
args = sys.argv[1:]
out, runs, ds, bins = args[0], int(args[1]), args[2], args[3]
sep = args.index("--")
ranges, variants = args[4:sep], args[sep + 1:] or [""]
sizes = [int(b) - int(a) + 1 for a, b in (r.split(":") for r in ranges)]
def med(v):
    v = [x for x in v if x == x]
    return f"{statistics.median(v):.{2 if max(v) < 10 else 1}f} ({min(v):.{2 if max(v) < 10 else 1}f}–{max(v):.{2 if max(v) < 10 else 1}f})" if v else "–"
print(f"fr1/desk split into 3 robots at 5 % ({', '.join(ranges)}), live at 30 Hz; median (min–max) over {runs} run(s).\n")
print("| server options | tracked % (worst robot) | skipped per robot | flow frames % | pose latency p50 ms | p99 ms (worst robot) | fused ATE cm | server CPU s |")
print("|---|---|---|---|---|---|---|---|")
for vi, v in enumerate(variants):
    worst, skipped, flow, p50, p99, ate, cpu = [], [], [], [], [], [], []
    for r in range(1, runs + 1):
        d = f"{out}/v{vi}_r{r}"
        try:
            stats = json.load(open(f"{d}/out/stats.json"))
        except Exception:
            continue
        cl = {c["id"]: c for c in stats["clients"]}
        worst.append(min(100.0 * cl[k]["trajectory_poses"] / sizes[k - 1] for k in (1, 2, 3)))
        skipped.append(statistics.mean(cl[k].get("frames_skipped", 0) for k in (1, 2, 3)))
        flow.append(100.0 * sum(cl[k].get("frames_flow", 0) for k in (1, 2, 3)) / max(1, sum(cl[k]["frames_processed"] for k in (1, 2, 3))))
        summ = [json.load(open(f"{d}/client_{k}.json")) for k in (1, 2, 3)]
        p50.append(statistics.median(s["latency_ms"]["p50"] for s in summ))
        p99.append(max(s["latency_ms"]["p99"] for s in summ))
        gt = f"{ds}/groundtruth.txt"
        cmd = [f"{bins}/cslam-eval", "ate", gt, f"{d}/out/client_1.txt", "--json", "--also", gt, f"{d}/out/client_2.txt", gt, f"{d}/out/client_3.txt"]
        res = subprocess.run(cmd, capture_output=True, text=True)
        ate.append(100 * json.loads(res.stdout)["rmse"] if res.returncode == 0 else float("nan"))
        user, system = open(f"{d}/server_time.txt").read().split()[:2]
        cpu.append(float(user) + float(system))
    print(f"| {v or '(defaults)'} | {med(worst)} | {med(skipped)} | {med(flow)} | {med(p50)} | {med(p99)} | {med(ate)} | {med(cpu)} |")
PY
