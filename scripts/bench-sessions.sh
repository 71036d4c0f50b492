#!/usr/bin/env bash
# Multi-session benchmark: a sequence split into sessions, each streamed to a server started on the
# same --state-dir after the previous one stopped (real processes on loopback, as a robot team
# coming back the next day). Per case and mode it reports the combined ATE of every session in the
# final map (one alignment), each session alone (its own alignment), when each later session was
# fused (sequence seconds after its first frame) and the fusion transforms against ground truth.
#
# Usage: scripts/bench-sessions.sh [OUT=bench_out/sessions] [RUNS=3] [MODES="det threaded"]
#                                  [CASES="desk2 desk3 rpy2 synth2"]
#   desk2   fr1/desk frames 1-300, then 280-end (the persistence test's split)
#   desk3   fr1/desk frames 1-200, 180-400, 380-end
#   rpy2    fr1/rpy frames 1-370, 350-end
#   synth2  the synthetic two-day scene of the persistence test: day 1 robot_2, day 2 robot_1
#           (starts away from day 1's path and meets it later)
# Modes: det (servers --deterministic: one outcome per input), threaded (as a server runs live).
# CSLAM_SESSION_RATE: client rate (default max: the client sends as fast as the server acks).
set -euo pipefail
cd "$(dirname "$0")/.."
OUT="${1:-bench_out/sessions}"
RUNS="${2:-3}"
MODES="${3:-det threaded}"
CASES="${4:-desk2 desk3 rpy2 synth2}"
RATE="${CSLAM_SESSION_RATE:-max}"
BIN="${CSLAM_BIN:-$PWD/build/bin}"  # CSLAM_BIN: another build's programs (A/B runs)
DESK="${CSLAM_TUM_DESK:-../shared/data/tum_fr1_desk}"
RPY="${CSLAM_TUM_RPY:-../shared/data/tum_fr1_rpy}"
mkdir -p "$OUT"
OUT="$(cd "$OUT" && pwd)"
echo "== machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), load $(cut -d' ' -f1-3 /proc/loadavg), revision $(git rev-parse --short HEAD 2>/dev/null || echo '?')"

SCENE="$OUT/scene"
if [[ " $CASES " == *" synth2 "* ]] && [ ! -f "$SCENE/robot_2/groundtruth.txt" ]; then
  "$BIN/cslam-synth" --preset test-small --frames 300 --seed 5 --overlap 0.3 --out "$SCENE" --force --log-level warn > /dev/null
fi

# Session lists: "client_id dataset range" per session.
sessions_of() {
  case "$1" in
    desk2) echo "1 $DESK 1:300" "2 $DESK 280:" ;;
    desk3) echo "1 $DESK 1:200" "2 $DESK 180:400" "3 $DESK 380:" ;;
    rpy2) echo "1 $RPY 1:370" "2 $RPY 350:" ;;
    synth2) echo "2 $SCENE/robot_2 1:" "1 $SCENE/robot_1 1:" ;;
    *) echo "bench-sessions: unknown case $1" >&2; exit 2 ;;
  esac
}

# One run: every session on its own server start; prints one result line.
run_case() {
  local case="$1" mode="$2" dir="$3"
  rm -rf "$dir"; mkdir -p "$dir"
  local det=""; [ "$mode" = det ] && det="--deterministic"
  local k=0 sess
  local -a ids=() sets=()
  while read -r id ds range; do
    k=$((k + 1)); ids+=("$id"); sets+=("$ds")
    local cam="--camera tum1"; [ "$case" = synth2 ] && cam=""
    "$BIN/cslam-server" --bind "tcp://127.0.0.1:*" --endpoint-file "$dir/endpoint$k" --out-dir "$dir/out$k" --http off \
      --log-interval 5 --state-dir "$dir/state" --clients 1 --exit-when-done $det > "$dir/server$k.log" 2>&1 &
    local spid=$!
    for _ in $(seq 1 600); do [ -s "$dir/endpoint$k" ] && break; sleep 0.1; done
    "$BIN/cslam-client" --server "$(head -1 "$dir/endpoint$k")" --id "$id" --dataset "$ds" --range "$range" $cam \
      --rate "$RATE" --rgb-codec png > "$dir/client$k.log" 2>&1 || echo "   client $id of session $k failed: $dir/client$k.log"
    wait "$spid" || echo "   server of session $k failed: $dir/server$k.log"
  done < <(sessions_of "$case" | tr ' ' '\n' | paste - - -)
  local last="$dir/out$k"
  # Combined ATE: every session's trajectory in the final map, one alignment.
  local args=() alone=() i
  for i in "${!ids[@]}"; do
    local gt="${sets[$i]}/groundtruth.txt" est="$last/client_${ids[$i]}.txt"
    [ -s "$est" ] || { echo "   no trajectory $est"; return; }
    if [ "$i" = 0 ]; then args=("$gt" "$est"); else args+=(--also "$gt" "$est"); fi
    alone+=("$("$BIN/cslam-eval" ate "$gt" "$est" --json | python3 -c 'import json,sys; print("%.4f" % json.load(sys.stdin)["rmse"])')")
  done
  local combined
  combined=$("$BIN/cslam-eval" ate "${args[@]}" --json | python3 -c 'import json,sys; print("%.4f" % json.load(sys.stdin)["rmse"])')
  # Fusion of each later session: first fusion event naming it, in sequence seconds after its first frame.
  local fused
  fused=$(python3 - "$dir" "$k" "${ids[@]}" <<'EOF'
import json, sys
d, n, ids = sys.argv[1], int(sys.argv[2]), [int(x) for x in sys.argv[3:]]
out = []
for k in range(1, n):
    # Session k+1's own server run (event lists are not kept in snapshots).
    events = json.load(open("%s/out%d/stats.json" % (d, k + 1)))["fusion_events"]
    # The session's first frame: the first pose its own server run wrote.
    with open("%s/out%d/client_%d.txt" % (d, k + 1, ids[k])) as f:
        first = next(float(l.split()[0]) for l in f if l.strip() and not l.startswith("#"))
    ev = [e for e in events if e["kind"] == "fusion" and ids[k] in (e["client_a"], e["client_b"])]
    if ev:
        t = ev[0]["query_timestamp"] if ev[0]["client_a"] == ids[k] else ev[0]["candidate_timestamp"]
    out.append("session %d %s" % (k + 1, ("%.2f s" % (t - first)) if ev else "never"))
print(", ".join(out))
EOF
)
  local gtopt=(--gt "${sets[0]}/groundtruth.txt")
  if [ "$case" = synth2 ]; then
    gtopt=(--client-gt); for i in "${!ids[@]}"; do gtopt+=("${ids[$i]}" "${sets[$i]}/groundtruth.txt"); done
  fi
  for s in $(seq 2 "$k"); do  # each later session's fusion and re-encounters against ground truth
    "$BIN/cslam-eval" events "$dir/out$s/stats.json" "${gtopt[@]}" | grep -E "^(fusion|reencounter)" | sed "s/^/     s$s /" || true
  done
  echo "   combined ATE $combined m | each alone ${alone[*]} m | fused after: $fused"
}

for case in $CASES; do
  for mode in $MODES; do
    echo "-- $case, $mode servers, client rate $RATE"
    for r in $(seq 1 "$RUNS"); do
      d="$OUT/${case}_${mode}_$r"
      printf "  run %d\n" "$r"
      run_case "$case" "$mode" "$d"
    done
  done
done
