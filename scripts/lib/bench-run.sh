# Shared by the live benchmarks (bench-bandwidth, bench-capacity, bench-link, bench-live-split):
# one server and its robots per run. Source it; it defines functions only.

# wait_endpoint FILE: waits (60 s at most) until the server has written its endpoint to FILE.
wait_endpoint() {
  local _
  for _ in $(seq 1 600); do [ -s "$1" ] && return 0; sleep 0.1; done
  return 0  # the robots then fail to connect, and wait_run says so
}

# wait_run DIR SERVER_PID CLIENT_PID...: waits for the robots, then the server (it exits once they
# said goodbye); says so if any of them exited non-zero (their logs are in DIR).
wait_run() {
  local dir=$1 server=$2 rc=0 p
  shift 2
  for p in "$@"; do wait "$p" || rc=1; done
  wait "$server" || rc=1
  [ "$rc" = 0 ] || echo "   (a process exited non-zero: see $dir/*.log)"
}

# server_variant VARIANT: sets VARIANT_BIN and VARIANT_ARGS from a benchmark's server variant. A
# variant "server=PATH ARGS..." runs that cslam-server binary (e.g. the previous build's, copied
# aside) with ARGS; any other variant is options for "$BIN/cslam-server".
server_variant() {
  VARIANT_BIN="$BIN/cslam-server" VARIANT_ARGS="$1"
  if [[ "$1" == server=* ]]; then
    VARIANT_BIN="${1%% *}"; VARIANT_BIN="${VARIANT_BIN#server=}"
    if [[ "$1" == *" "* ]]; then VARIANT_ARGS="${1#* }"; else VARIANT_ARGS=""; fi
  fi
}
