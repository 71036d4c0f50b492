#!/usr/bin/env bash
# Live capacity benchmark: N synthetic robots (cslam-synth, shared places) stream live at the
# camera's 30 Hz from preloaded frames to one cslam-server; per N it reports processed fps per
# robot, frames skipped (server) and dropped without credit (client), ATE per robot and of the
# fused group, pose latency p50/p99 (frame capture to Ack), server CPU seconds, peak RSS and the
# longest receive-loop iteration (network_stats.json: wall clock, and the thread's own CPU time).
# Capacity = the largest N at which every robot gets >= 90 % of its frames processed and an ATE
# <= 1.25x its value streaming alone (solo runs of each robot, same live setup).
# Usage: scripts/bench-capacity.sh [RUNS=3] [OUT=bench_out/capacity] [NS="1 2 3 4 6 8"] [FRAMES=600]
# Environment: CSLAM_CAPACITY_SOLO=0 skips the solo runs of robots 2..N (robot 1's N=1 run is then
# every robot's reference; stated in the summary). CSLAM_SERVER_ARGS: more cslam-server options
# (one variant). CSLAM_CAPACITY_VARIANTS="ARGS_A|ARGS_B|...": server variants alternated run by run
# (run r: every N with A, then with B, ...), one table each, e.g. "--flow under-load|--flow off";
# (e.g. --no-dense, to measure the live dense map's cost back to back with and without it).
# A variant that starts with "server=PATH " runs that cslam-server binary (e.g. the previous
# build's, copied aside) with the rest as its options.
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/lib/bench-run.sh
RUNS="${1:-3}"
OUT="${2:-bench_out/capacity}"
NS="${3:-1 2 3 4 6 8}"
FRAMES="${4:-600}"
SOLO="${CSLAM_CAPACITY_SOLO:-1}"
BIN=build/bin
MAXN=$(echo $NS | tr ' ' '\n' | sort -n | tail -1)
mkdir -p "$OUT"
rm -f "$OUT/summary.md"
ROBOTS=$(( MAXN > 8 ? MAXN : 8 ))  # one scene serves every N
SCENE="$OUT/scene_${ROBOTS}x${FRAMES}"
loadavg() { cut -d' ' -f1-3 /proc/loadavg; }
echo "== machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), load $(loadavg)"
echo "== revision $(git rev-parse --short HEAD)$(git diff --quiet || echo '+dirty'), $RUNS run(s), N in {$NS}, $FRAMES frames per robot"
if [ ! -f "$SCENE/robot_${ROBOTS}/groundtruth.txt" ]; then
  echo "-- rendering $ROBOTS robots x $FRAMES frames (cslam-synth, 640x480, 10 % of each path shared)"
  "$BIN/cslam-synth" --robots "$ROBOTS" --frames "$FRAMES" --overlap 0.1 --no-loop --seed 11 --out "$SCENE" --force --log-level warn > /dev/null
fi

# run_case NAME N [FIRST_ROBOT]: one server, N live clients (robots FIRST..FIRST+N-1) started together.
run_case() {
  local name="$1" n="$2" first="${3:-1}" dir="$OUT/$1"
  rm -rf "$dir"; mkdir -p "$dir"
  local load_before; load_before=$(loadavg)
  local VARIANT_BIN VARIANT_ARGS
  server_variant "$SERVER_ARGS"
  local server="$VARIANT_BIN" args="$VARIANT_ARGS"
  /usr/bin/time -f "%U %S %M %e" -o "$dir/server_time.txt" \
    "$server" --bind "tcp://127.0.0.1:*" --endpoint-file "$dir/endpoint" --clients "$n" --exit-when-done \
    --http off --heartbeat-timeout 30 --out-dir "$dir/out" --log-level warn $args > "$dir/server.log" 2>&1 &
  local server_pid=$!
  python3 scripts/lib/thread-cpu.py "$server_pid" "$dir/thread_cpu.json" --child &
  local sampler_pid=$!
  wait_endpoint "$dir/endpoint"
  local endpoint; endpoint=$(head -1 "$dir/endpoint")
  # Frames are loaded and encoded before the common start time (a robot preloads in ~2-4 s on a busy machine).
  local start_at; start_at=$(python3 -c "import time; print(time.time() + 6 + 4 * $n)")
  local pids=() k
  for k in $(seq "$first" $((first + n - 1))); do
    "$BIN/cslam-client" --server "$endpoint" --id "$k" --dataset "$SCENE/robot_$k" --live --preload --start-at "$start_at" \
      --reply-timeout 60 --poses-out "$dir/poses_$k.txt" --summary-out "$dir/client_$k.json" --progress-interval 1000 \
      --log-level warn > "$dir/client_$k.log" 2>&1 &
    pids+=($!)
  done
  wait_run "$dir" "$server_pid" "${pids[@]}"
  wait "$sampler_pid" || true
  echo "$load_before" > "$dir/load_before.txt"; loadavg > "$dir/load_after.txt"
  # ATE per robot, and of each fused group with one alignment.
  for k in $(seq "$first" $((first + n - 1))); do
    "$BIN/cslam-eval" ate "$SCENE/robot_$k/groundtruth.txt" "$dir/out/client_$k.txt" --json > "$dir/ate_$k.json" 2>/dev/null || echo '{}' > "$dir/ate_$k.json"
  done
  python3 - "$dir" "$SCENE" "$BIN" <<'PY' > "$dir/fused_ate.txt" || true
import json, subprocess, sys
d, scene, bins = sys.argv[1:4]
stats = json.load(open(d + "/out/stats.json"))
best = None
for g in stats.get("groups", []):
    if len(g["clients"]) < 2: continue
    cl = g["clients"]
    cmd = [bins + "/cslam-eval", "ate", f"{scene}/robot_{cl[0]}/groundtruth.txt", f"{d}/out/client_{cl[0]}.txt", "--json"]
    if len(cl) > 1:
        cmd.append("--also")
        for c in cl[1:]: cmd += [f"{scene}/robot_{c}/groundtruth.txt", f"{d}/out/client_{c}.txt"]
    r = json.loads(subprocess.run(cmd, capture_output=True, text=True).stdout)
    if best is None or len(cl) > best[0]: best = (len(cl), r["rmse"])
print(f"{best[0]} {best[1]}" if best else "0 nan")
PY
}

IFS='|' read -ra VARIANTS <<< "${CSLAM_CAPACITY_VARIANTS:-${CSLAM_SERVER_ARGS:-}}"
[ "${#VARIANTS[@]}" -gt 0 ] || VARIANTS=("")
prefix() { [ "${#VARIANTS[@]}" -gt 1 ] && echo "v$1_" || true; }
for r in $(seq 1 "$RUNS"); do
  for n in $NS; do
    for vi in "${!VARIANTS[@]}"; do
      SERVER_ARGS="${VARIANTS[$vi]}"
      name="$(prefix "$vi")n${n}_r${r}"
      run_case "$name" "$n"
      printf "N=%d run %d %s done (load %s -> %s)\n" "$n" "$r" "${SERVER_ARGS:+[$SERVER_ARGS]}" "$(cat "$OUT/$name/load_before.txt")" "$(cat "$OUT/$name/load_after.txt")"
    done
  done
done
SERVER_ARGS="${VARIANTS[0]}"
# Robot 1's reference is its N = 1 run; an N list without 1 streams it alone once here.
if ! grep -qw 1 <<< "$NS"; then run_case "solo1" 1 1; echo "robot 1 alone done"; fi
if [ "$SOLO" = 1 ]; then
  for k in $(seq 2 "$MAXN"); do run_case "solo${k}" 1 "$k"; echo "robot $k alone done"; done
fi

for vi in "${!VARIANTS[@]}"; do
[ "${#VARIANTS[@]}" -gt 1 ] && echo "
### Server options: ${VARIANTS[$vi]:-(defaults)}
" | tee -a "$OUT/summary.md"
python3 - "$OUT" "$RUNS" "$NS" "$FRAMES" "$SOLO" "$(prefix "$vi")" <<'PY' | tee -a "$OUT/summary.md"
import json, os, statistics, sys
out, runs, ns, frames, solo = sys.argv[1], int(sys.argv[2]), [int(x) for x in sys.argv[3].split()], int(sys.argv[4]), sys.argv[5] == "1"
prefix = sys.argv[6]

def load(path, default=None):
    try: return json.load(open(path))
    except Exception: return default

def case(dirname):
    d = f"{out}/{dirname}"
    stats = load(d + "/out/stats.json", {"clients": []})
    server = {c["id"]: c for c in stats["clients"]}
    u, s, rss_kb, wall = (open(d + "/server_time.txt").read().split()[-4:] + ["nan"] * 4)[:4]
    robots = {}
    for k, c in server.items():
        cj = load(f"{d}/client_{k}.json", {})
        ate = load(f"{d}/ate_{k}.json", {}).get("rmse", float("nan"))
        lat = []
        try:
            for line in open(f"{d}/poses_{k}.txt.feedback.csv").readlines()[1:]:
                f = line.strip().split(",")
                if f[2] != "skipped": lat.append(float(f[7]))
        except OSError: pass
        robots[k] = {"processed": c["frames_processed"], "skipped": c.get("frames_skipped", 0), "flow": c.get("frames_flow", 0),
                     "dropped_client": cj.get("frames_dropped_client", 0), "fps": cj.get("processed_fps", 0.0),
                     "ate": ate, "latency": lat, "tracked": c.get("trajectory_poses", 0)}
    fused = open(d + "/fused_ate.txt").read().split() if os.path.exists(d + "/fused_ate.txt") else ["0", "nan"]
    load_b = open(d + "/load_before.txt").read().split()[0] if os.path.exists(d + "/load_before.txt") else "?"
    net = load(d + "/out/network_stats.json", {})
    return {"loop_ms": net.get("receive_loop_max_ms", float("nan")), "loop_cpu_ms": net.get("receive_loop_max_cpu_ms", float("nan")),
            "robots": robots, "cpu_s": float(u) + float(s), "rss_mb": float(rss_kb) / 1024, "wall": float(wall),
            "fused_n": int(fused[0]), "fused_ate": float(fused[1]), "load": load_b,
            "stages": load(d + "/thread_cpu.json", {}).get("stages", {})}

def pct(v, p):
    if not v: return float("nan")
    v = sorted(v); return v[min(len(v) - 1, int(p * (len(v) - 1) + 0.5))]

def med(v):
    v = [x for x in v if x == x]
    return (statistics.median(v), min(v), max(v)) if v else (float("nan"),) * 3

def fmt(t, f="{:.1f}"):
    return f"{f.format(t[0])} ({f.format(t[1])}–{f.format(t[2])})"

cases = {n: [case(f"{prefix}n{n}_r{r}") for r in range(1, runs + 1)] for n in ns}
ref = {}
base = [c["robots"].get(1, {}).get("ate", float("nan")) for c in cases.get(1, [])] or [case("solo1")["robots"].get(1, {}).get("ate", float("nan"))]
ref[1] = med(base)[0]
for k in range(2, max(ns) + 1):
    ref[k] = case(f"solo{k}")["robots"].get(k, {}).get("ate", float("nan")) if solo else ref[1]

print(f"Live capacity, {frames} frames per robot at 30 Hz, {runs} run(s) per N; median (min–max over runs).\n")
print("| N | processed % (worst robot) | processed fps per robot | flow frames % of processed | skipped (server) per robot | dropped (client) per robot | ATE cm (worst robot / ref) | fused ATE cm | pose latency p50 ms | p99 ms | server CPU s | peak RSS MB | longest receive loop ms (thread CPU ms) | load (1 min) before | verdict |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
capacity = 0
for n in ns:
    rows = cases[n]
    worst_pct, fps, flow, skipped, dropped, ate_ratio, p50, p99, worst_ate = [], [], [], [], [], [], [], [], []
    ok_all = True
    for c in rows:
        rb = c["robots"]
        if len(rb) < n: ok_all = False; continue
        worst_pct.append(min(100.0 * r["processed"] / frames for r in rb.values()))
        fps.append(statistics.mean(r["fps"] for r in rb.values()))
        flow.append(100.0 * sum(r["flow"] for r in rb.values()) / max(1, sum(r["processed"] for r in rb.values())))
        skipped.append(statistics.mean(r["skipped"] for r in rb.values()))
        dropped.append(statistics.mean(r["dropped_client"] for r in rb.values()))
        ratios = [r["ate"] / ref[k] if ref.get(k, 0) == ref.get(k, 0) and ref.get(k) else float("inf") for k, r in rb.items()]
        ate_ratio.append(max(ratios))
        worst_ate.append(100 * max(r["ate"] for r in rb.values()))
        lat = [x for r in rb.values() for x in r["latency"]]
        p50.append(pct(lat, 0.5)); p99.append(pct(lat, 0.99))
    ok = ok_all and worst_pct and statistics.median(worst_pct) >= 90.0 and statistics.median(ate_ratio) <= 1.25
    fused = [100 * c["fused_ate"] for c in rows if c["fused_n"] >= 2]
    print(f"| {n} | {fmt(med(worst_pct))} | {fmt(med(fps))} | {fmt(med(flow), '{:.0f}')} | {fmt(med(skipped), '{:.0f}')} | {fmt(med(dropped), '{:.0f}')} | "
          f"{fmt(med(worst_ate), '{:.2f}')} / x{med(ate_ratio)[0]:.2f} | {fmt(med(fused), '{:.2f}') if fused else '–'} | "
          f"{fmt(med(p50))} | {fmt(med(p99))} | {fmt(med([c['cpu_s'] for c in rows]))} | {fmt(med([c['rss_mb'] for c in rows]), '{:.0f}')} | "
          f"{fmt(med([c['loop_ms'] for c in rows]))} ({fmt(med([c['loop_cpu_ms'] for c in rows]))}) | "
          f"{', '.join(c['load'] for c in rows)} | {'ok' if ok else 'below target'} |")
    cases[n] = (rows, ok)
# Where the server's CPU went: seconds per stage (threads named after their stage), medians.
stage_names = sorted({s for n in ns for c in cases[n][0] for s in c["stages"]})
if stage_names:
    print("\nServer CPU s by stage (thread names; median (min–max) over runs):\n")
    print("| N | " + " | ".join(stage_names) + " |")
    print("|---|" + "---|" * len(stage_names))
    for n in ns:
        rows = cases[n][0]
        print(f"| {n} | " + " | ".join(fmt(med([c["stages"].get(s, 0.0) for c in rows])) for s in stage_names) + " |")
# Capacity: the largest N such that it and every smaller measured N meet the criteria.
for n in sorted(ns):
    if not cases[n][1]: break
    capacity = n
print(f"\nCapacity: N = {capacity} robots live at 30 Hz (every robot >= 90 % of its frames processed, ATE <= 1.25x "
      f"{'its solo value' if solo else 'robot 1 alone'}; median over runs).")
print("ATE reference (cm, each robot streaming alone): " + ", ".join(f"{k}: {100 * v:.2f}" for k, v in sorted(ref.items()) if k <= max(ns)))
PY
done
