#!/usr/bin/env bash
# Link-limited benchmark: N synthetic robots stream live at 30 Hz (preloaded frames, started
# together) to one cslam-server through ONE shared link of RATE: the script creates a network
# namespace whose loopback (MTU 1500) is shaped by a token-bucket filter (tc tbf), and runs the
# server and the robots inside it. Each run streams once with the default pair (every frame
# JPEG q75 + lossless depth) and once with the lean stream (cslam-client --depth-every K),
# alternated, and once with the default pair under adaptive rate (cslam-client --adapt: the
# robots step to a lean stream while their acks say the link queues). Reports per robot: frames processed (of those captured), pose latency p50/p99
# (capture to ack, client side), MB/s sent and ATE; medians and min-max over the runs.
# A mode may end in @sS: the server runs with --tracking-slots S (e.g. "lean lean@s2"), and in @pP:
# the robots encode the colour stream with x264 preset P (e.g. "lean lean@pveryfast"), and in @fF:
# the server's flow frames (--flow F, e.g. "lean lean@falways"), and in @xPATH: that cslam-server
# binary (e.g. the previous build's copied aside: "lean@x/tmp/cslam-server.before lean"), in @cPATH:
# that cslam-client binary for the robots (a trial build's beside the current one), and in
# @bB: the robots' byte budget in MB/s (cslam-client --byte-budget, e.g. "lean@b0 lean").
# Needs root (ip netns, tc). Usage:
#   scripts/bench-link.sh [OUT=bench_out/link] [RUNS=3] [N=4] [RATE=40mbit] [FRAMES=600] [K=5] [MODES="default lean adapt"]
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/lib/bench-run.sh
OUT="${1:-bench_out/link}"
RUNS="${2:-3}"
N="${3:-4}"
RATE="${4:-40mbit}"
FRAMES="${5:-600}"
K="${6:-5}"
MODES="${7:-default lean adapt}"
BIN="$PWD/build/bin"
[ "$(id -u)" = 0 ] || { echo "bench-link.sh needs root (it creates a network namespace and shapes its loopback)" >&2; exit 2; }
mkdir -p "$OUT"
OUT="$(cd "$OUT" && pwd)"
NS="cslam-link-$$"
ip netns add "$NS"
trap 'ip netns del "$NS" 2>/dev/null || true' EXIT
ip netns exec "$NS" ip link set lo mtu 1500
ip netns exec "$NS" ip link set lo up
ip netns exec "$NS" tc qdisc add dev lo root tbf rate "$RATE" burst 64kb latency 400ms
inns() { ip netns exec "$NS" "$@"; }
loadavg() { cut -d' ' -f1-3 /proc/loadavg; }
echo "== machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), load $(loadavg)"
echo "== revision $(git rev-parse --short HEAD)$(git diff --quiet || echo '+dirty'), $RUNS run(s), $N robots x $FRAMES frames, one link of $RATE (tc tbf in netns $NS), lean K=$K"
SCENE="$OUT/scene_${N}x${FRAMES}"
if [ ! -f "$SCENE/robot_${N}/groundtruth.txt" ]; then
  echo "-- rendering $N robots x $FRAMES frames (cslam-synth, 640x480, 10 % of each path shared)"
  "$BIN/cslam-synth" --robots "$N" --frames "$FRAMES" --overlap 0.1 --no-loop --seed 11 --out "$SCENE" --force --log-level warn > /dev/null
fi

run_case() {
  local dir="$1" mode="${2%%@*}" server_extra=() client_extra=() opt server_bin="$BIN/cslam-server" client_bin="$BIN/cslam-client"
  IFS=@ read -ra opts <<< "${2#"$mode"}"
  for opt in "${opts[@]}"; do
    case "$opt" in
      '') ;;
      s*) server_extra+=(--tracking-slots "${opt#s}") ;;
      f*) server_extra+=(--flow "${opt#f}") ;;
      p*) client_extra+=(--colour-preset "${opt#p}") ;;
      b*) client_extra+=(--byte-budget "${opt#b}") ;;
      x*) server_bin="${opt#x}" ;;
      c*) client_bin="${opt#c}" ;;
      *) echo "bench-link.sh: unknown mode suffix @$opt in $2" >&2; exit 2 ;;
    esac
  done
  rm -rf "$dir"; mkdir -p "$dir"
  inns /usr/bin/time -f "%U %S %M %e" -o "$dir/server_time.txt" \
    "$server_bin" "${server_extra[@]}" --bind "tcp://127.0.0.1:*" --endpoint-file "$dir/endpoint" --clients "$N" --exit-when-done \
    --http off --heartbeat-timeout 30 --out-dir "$dir/out" --log-level warn > "$dir/server.log" 2>&1 &
  local server_pid=$!
  wait_endpoint "$dir/endpoint"
  local endpoint; endpoint=$(head -1 "$dir/endpoint")
  local start_at; start_at=$(python3 -c "import time; print(time.time() + 8 + 5 * $N)")
  local extra=()
  [ "$mode" = lean ] && extra=(--depth-every "$K")
  [ "$mode" = adapt ] && extra=(--adapt)
  extra+=("${client_extra[@]}")
  local pids=() k
  for k in $(seq 1 "$N"); do
    inns "$client_bin" --server "$endpoint" --id "$k" --dataset "$SCENE/robot_$k" --live --preload --start-at "$start_at" \
      "${extra[@]}" --reply-timeout 60 --summary-out "$dir/client_$k.json" --progress-interval 1000 --log-level warn \
      > "$dir/client_$k.log" 2>&1 &
    pids+=($!)
  done
  wait_run "$dir" "$server_pid" "${pids[@]}"
  for k in $(seq 1 "$N"); do
    "$BIN/cslam-eval" ate "$SCENE/robot_$k/groundtruth.txt" "$dir/out/client_$k.txt" --json > "$dir/ate_$k.json" 2>/dev/null || echo '{}' > "$dir/ate_$k.json"
  done
}

for r in $(seq 1 "$RUNS"); do
  for mode in $MODES; do
    echo "-- run $r $mode (load $(loadavg))"
    run_case "$OUT/${mode//\//_}_r$r" "$mode"  # a binary path in the mode: one folder
  done
done

python3 - "$OUT" "$RUNS" "$N" "$MODES" <<'EOF'
import json, os, statistics, sys
out, runs, n, modes = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4].split()
def med(v, f="{:.3g}"):
    return (f.format(statistics.median(v)) + " (" + f.format(min(v)) + "-" + f.format(max(v)) + ")") if v else "n/a"
print("\n| stream | worst robot processed % | pose latency p99 ms (worst robot) | MB/s per robot (mean) | ATE m (worst robot) |")
print("|---|---|---|---|---|")
for mode in modes:
    proc, p99, mbs, ate = [], [], [], []
    for r in range(1, runs + 1):
        d = f"{out}/{mode.replace('/', '_')}_r{r}"
        if not os.path.isdir(d): continue
        ps, ls, bs, es = [], [], [], []
        for k in range(1, n + 1):
            try:
                s = json.load(open(f"{d}/client_{k}.json"))
            except Exception:
                ps.append(0.0); continue
            ps.append(100.0 * s["frames_processed"] / max(1, s["dataset_frames"]))
            ls.append(s["latency_ms"]["p99"])
            bs.append(s["bytes_per_s"] / 1e6)
            a = json.load(open(f"{d}/ate_{k}.json"))
            es.append(a.get("rmse", float("nan")))
        proc.append(min(ps)); p99.append(max(ls) if ls else float("nan")); mbs.append(statistics.mean(bs) if bs else 0)
        ate.append(max(es) if es else float("nan"))
    print(f"| {mode} | {med(proc, '{:.1f}')} | {med(p99, '{:.0f}')} | {med(mbs, '{:.2f}')} | {med(ate, '{:.4f}')} |")
EOF
