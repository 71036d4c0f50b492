#!/usr/bin/env bash
# Builds the cslam image with docker or podman (whichever works) and runs what compose.yaml runs:
# the image's cslam-synth makes a small synthetic scene in the /data volume, the image's
# cslam-server serves it, two of the image's cslam-client replay robots 1 and 2. Checks
# /api/status (HTTPS with the token, as the image's CMD serves it), the viewer page and its three.js,
# the healthcheck command, both trajectories (ATE with the image's cslam-eval) and the refusal of a
# read-only --out-dir; reports the image size.
#
# Where no registry is reachable, the Debian 12 base image is made locally: debootstrap bookworm
# into a folder, trimmed like debian:bookworm-slim, `podman import`. Where podman's defaults cannot
# start containers (crun: "setrlimit RLIMIT_NOFILE: Operation not permitted" without
# CAP_SYS_RESOURCE, "cgroups in hybrid mode not supported"), it retries with the host's limits
# (--ulimit) and with runc; where that fails too, the same programs run from the image's own file
# tree (`podman image mount`) with chroot, as the image's user, with writable folders bound at
# /data and /tmp. The script says which mode ran.
#
# Not part of ctest (the image build takes 10-25 minutes; root needed for podman/chroot). Environment:
#   CSLAM_SMOKE_DIR   work folder (default /var/tmp/cslam-smoke): rootfs, build log, /data volume
#   CSLAM_IMAGE       image tag (default localhost/cslam:smoke)
#   CSLAM_ENGINE      docker | podman (default: docker if its engine answers, else podman)
#   CSLAM_CCACHE_DIR  optional compiler cache folder bound into the build stage at /ccache
#   NODE_EXTRA_CA_CERTS  if set, bound into the build stage for npm ci (TLS-inspecting proxies)
#   CSLAM_SKIP_BUILD  1: use the already built image
set -euo pipefail
cd "$(dirname "$0")/.."
DIR="${CSLAM_SMOKE_DIR:-/var/tmp/cslam-smoke}"
IMAGE="${CSLAM_IMAGE:-localhost/cslam:smoke}"
BASE=docker.io/library/debian:bookworm
mkdir -p "$DIR"
say() { echo "[container-smoke] $*"; }
fail() { echo "[container-smoke] FAIL: $*" >&2; exit 1; }

# --- engine ---------------------------------------------------------------------------------
ENGINE="${CSLAM_ENGINE:-}"
if [ -z "$ENGINE" ]; then
  if command -v docker > /dev/null && docker info > /dev/null 2>&1; then ENGINE=docker
  elif command -v podman > /dev/null; then ENGINE=podman
  else fail "neither a docker engine nor podman is available (Debian: apt-get install podman)"; fi
fi
if [ "$ENGINE" = podman ]; then
  # cgroupfs: no systemd in these sandboxes.
  E=(podman --cgroup-manager=cgroupfs)
else
  E=(docker)
fi
say "engine: ${E[*]}"

# --- base image -------------------------------------------------------------------------------
if ! "${E[@]}" image exists "$BASE" 2> /dev/null && ! "${E[@]}" image inspect "$BASE" > /dev/null 2>&1; then
  if "${E[@]}" pull "$BASE" > "$DIR/pull.log" 2>&1; then
    say "pulled $BASE"
  else
    [ "$ENGINE" = podman ] || fail "cannot pull $BASE (see $DIR/pull.log)"
    command -v debootstrap > /dev/null || fail "no registry and no debootstrap (apt-get install debootstrap)"
    say "no registry: debootstrap bookworm into $DIR/rootfs (a few minutes)"
    rm -rf "$DIR/rootfs"
    debootstrap --variant=minbase bookworm "$DIR/rootfs" http://deb.debian.org/debian > "$DIR/debootstrap.log" 2>&1 \
      || fail "debootstrap failed (see $DIR/debootstrap.log)"
    # Trim like debian:bookworm-slim: no package caches or lists, no docs/man/locales (also for
    # packages installed later in the image).
    R="$DIR/rootfs"
    rm -rf "$R"/var/cache/apt/archives/*.deb "$R"/var/cache/apt/*.bin "$R"/var/lib/apt/lists/*
    find "$R/usr/share/doc" -mindepth 1 ! -name copyright ! -type d -delete
    find "$R/usr/share/man" "$R/usr/share/info" -type f -delete  # keep the folders (postinst scripts use them)
    find "$R/usr/share/locale" -mindepth 1 -maxdepth 1 ! -name locale.alias -exec rm -rf {} +
    cat > "$R/etc/dpkg/dpkg.cfg.d/docker-slim" << 'EOF'
path-exclude /usr/share/doc/*
path-include /usr/share/doc/*/copyright
path-exclude /usr/share/man/*
path-exclude /usr/share/info/*
path-exclude /usr/share/locale/*
path-include /usr/share/locale/locale.alias
EOF
    tar -C "$R" -c . | "${E[@]}" import - "$BASE" > /dev/null
    say "imported $BASE from the debootstrapped folder"
  fi
fi
say "base image $BASE: $("${E[@]}" image inspect --format '{{.Size}}' "$BASE" | awk '{printf "%.0f MB", $1/1e6}')"

# --- build ------------------------------------------------------------------------------------
if [ "${CSLAM_SKIP_BUILD:-0}" != 1 ]; then
  BUILD_ARGS=(-t "$IMAGE" -f Dockerfile)
  if [ "$ENGINE" = podman ]; then
    BUILD_ARGS+=(--isolation=chroot --format docker)  # docker format keeps HEALTHCHECK
    if [ -n "${CSLAM_CCACHE_DIR:-}" ]; then mkdir -p "$CSLAM_CCACHE_DIR"; BUILD_ARGS+=(-v "$CSLAM_CCACHE_DIR:/ccache"); fi
    # A host that reaches the npm registry through a TLS-inspecting proxy trusts its CA with
    # NODE_EXTRA_CA_CERTS: the build stage's npm ci gets the same file (nothing of it enters the image).
    if [ -n "${NODE_EXTRA_CA_CERTS:-}" ] && [ -f "$NODE_EXTRA_CA_CERTS" ]; then
      BUILD_ARGS+=(-v "$NODE_EXTRA_CA_CERTS:/run/cslam-npm-ca.crt:ro" --build-arg CSLAM_NPM_CA=/run/cslam-npm-ca.crt)
    fi
  fi
  say "building $IMAGE (log: $DIR/build.log)"
  t0=$(date +%s)
  "${E[@]}" build "${BUILD_ARGS[@]}" . > "$DIR/build.log" 2>&1 || { tail -30 "$DIR/build.log" >&2; fail "image build failed"; }
  say "built in $(( $(date +%s) - t0 )) s"
fi
SIZE=$("${E[@]}" image inspect --format '{{.Size}}' "$IMAGE")
say "image size: $SIZE bytes ($(awk -v s="$SIZE" 'BEGIN{printf "%.0f MB", s/1e6}'))"
HC=$("${E[@]}" image inspect --format '{{json .Config.Healthcheck}}' "$IMAGE" 2> /dev/null || echo null)
echo "$HC" | grep -q "api/status" || fail "the image has no healthcheck on /api/status (got $HC)"
USER_=$("${E[@]}" image inspect --format '{{.Config.User}}' "$IMAGE")
[ -n "$USER_" ] && [ "$USER_" != root ] && [ "$USER_" != 0 ] || fail "the image runs as root"

# --- run: containers, or the image's files under chroot -----------------------------------------
DATA="$DIR/data"
rm -rf "$DATA" && mkdir -p "$DATA/keys" && chown 10001:10001 "$DATA" "$DATA/keys"  # keys: the image's /keys
MODE=container
RUN_OPTS=()  # options every `run` of this script gets (set below where the engine's defaults fail)
if ! "${E[@]}" run --rm "$IMAGE" cslam-server --help > "$DIR/run-probe.log" 2>&1; then
  [ "$ENGINE" = podman ] || { cat "$DIR/run-probe.log" >&2; fail "the engine cannot run the image"; }
  say "containers do not start with podman's defaults ($(grep -m1 -o 'setrlimit[^"]*\|cgroups in hybrid[^"]*' "$DIR/run-probe.log" || tail -1 "$DIR/run-probe.log"))"
  # Podman asks for RLIMIT_NOFILE and RLIMIT_NPROC 1048576, which a host without CAP_SYS_RESOURCE
  # cannot raise to: ask for the host's hard open-files limit, and 4096 processes (the image's
  # user runs the server's ~20 threads and a few clients; podman starts conmon with at most 32768
  # here, so the host's own process limit can be too high as well). crun (podman's default) also
  # refuses hosts whose cgroup v2 hierarchy has controllers next to v1 ("cgroups in hybrid mode not
  # supported"); runc (Debian package runc) runs there.
  NPROC=$(ulimit -Hu); [ "$NPROC" = unlimited ] || [ "$NPROC" -gt 4096 ] && NPROC=4096
  LIMITS=(--ulimit "nofile=$(ulimit -Hn):$(ulimit -Hn)" --ulimit "nproc=$NPROC:$NPROC")
  for rt in "" runc; do
    [ -z "$rt" ] || command -v "$rt" > /dev/null || { say "  ($rt not installed: apt-get install $rt)"; continue; }
    E2=("${E[@]}"); [ -z "$rt" ] || E2+=(--runtime "$rt")
    if "${E2[@]}" run --rm "${LIMITS[@]}" "$IMAGE" cslam-server --help > "$DIR/run-probe-$rt.log" 2>&1; then
      E=("${E2[@]}"); RUN_OPTS=("${LIMITS[@]}")
      say "containers start with ${rt:-the default runtime} and the host's limits (${LIMITS[*]})"
      break
    fi
    say "  not with ${rt:-the default runtime} and ${LIMITS[*]}: $(tail -1 "$DIR/run-probe-$rt.log")"
  done
  if [ ${#RUN_OPTS[@]} -eq 0 ]; then
    MODE=chroot
    say "containers cannot start here;"
    say "running the image's own programs from 'podman image mount' under chroot, /data bound to $DATA"
  fi
fi
say "mode: $MODE (engine: ${E[*]})"

# Runs a program of the image (chroot: as the image's user with the image's PATH). Started in the
# background as "${IMG[@]}" CMD &, so that $! is the program itself (chroot and env exec it).
img() { "${IMG[@]}" "$@"; }
PIDS=()
cleanup() {
  for p in "${PIDS[@]}"; do kill "$p" 2> /dev/null || true; done
  wait 2> /dev/null || true
  if [ "$MODE" = chroot ] && [ -n "${MNT:-}" ]; then
    for m in keys data proc dev tmp; do umount "$MNT/$m" 2> /dev/null || true; done
    "${E[@]}" image unmount "$IMAGE" > /dev/null 2>&1 || true
  elif [ "$MODE" = container ]; then
    for c in cslam-smoke-server cslam-smoke-ro; do  # one by one: a name already gone fails the whole call
      "${E[@]}" rm -f "$c" > /dev/null 2>&1 || true
    done
    "${E[@]}" network rm cslam-smoke > /dev/null 2>&1 || true
  fi
}
trap cleanup EXIT

if [ "$MODE" = chroot ]; then
  MNT=$("${E[@]}" image mount "$IMAGE")
  for m in data proc dev keys tmp; do [ -d "$MNT/$m" ] || fail "image lacks /$m"; done
  # A container's /tmp is writable (its own layer); the image's mounted tree is not.
  rm -rf "$DIR/tmp" && mkdir -p "$DIR/tmp" && chmod 1777 "$DIR/tmp"
  mount --bind "$DIR/tmp" "$MNT/tmp"
  mount --bind "$DATA" "$MNT/data"
  mount --bind "$DATA/keys" "$MNT/keys"
  mount --bind /proc "$MNT/proc"
  mount --bind /dev "$MNT/dev"
  IMG=(chroot --userspec=10001:10001 "$MNT" /usr/bin/env -i PATH=/opt/cslam/bin:/usr/local/bin:/usr/bin:/bin HOME=/data)
  SERVER_HOST=127.0.0.1
  ZMQ_PORT=$(( 20000 + RANDOM % 20000 )); HTTP_PORT=$(( ZMQ_PORT + 1 ))
  HTTP_URL="https://127.0.0.1:$HTTP_PORT"
  in_net() { "$@"; }
  IMG_NONET=("${IMG[@]}")
else
  "${E[@]}" network create cslam-smoke > /dev/null
  # One-off programs: no healthcheck of their own (the server's container keeps the image's).
  IMG=("${E[@]}" run --rm -i "${RUN_OPTS[@]}" --no-healthcheck --network cslam-smoke -v "$DATA:/data" -v "$DATA/keys:/keys" "$IMAGE")
  # Without a network, for checks that read a program's whole output (the engine's network set-up
  # may log to the same stderr).
  IMG_NONET=("${E[@]}" run --rm -i "${RUN_OPTS[@]}" --no-healthcheck --network none -v "$DATA:/data" -v "$DATA/keys:/keys" "$IMAGE")
  SERVER_HOST=cslam-smoke-server
  ZMQ_PORT=5555; HTTP_PORT=8080
  HTTP_URL="https://cslam-smoke-server:8080"
  in_net() { img "$@"; }
fi

say "cslam-server refuses a read-only --out-dir at start"
if "${IMG_NONET[@]}" cslam-server --out-dir /proc/cslam-out --http off --bind "tcp://127.0.0.1:$ZMQ_PORT" > "$DIR/ro.log" 2>&1; then
  fail "the server started with an unwritable --out-dir"
fi
[ "$(wc -l < "$DIR/ro.log")" -le 2 ] || { cat "$DIR/ro.log" >&2; fail "expected one clear line for an unwritable --out-dir"; }
say "  -> $(tail -1 "$DIR/ro.log")"
if [ "$MODE" = container ]; then
  # A read-only container root without a writable /tmp (docker's --read-only; podman's with
  # --read-only-tmpfs=false): no folder for the keyframe store, one line saying what to do.
  RO=(--read-only); [ "$ENGINE" = podman ] && RO+=(--read-only-tmpfs=false)
  say "cslam-server refuses a read-only container root without a writable /tmp at start"
  if "${E[@]}" run --rm "${RUN_OPTS[@]}" --no-healthcheck --network none "${RO[@]}" -v "$DATA:/data" "$IMAGE" \
      cslam-server --http off --bind "tcp://127.0.0.1:$ZMQ_PORT" > "$DIR/ro-tmp.log" 2>&1; then
    fail "the server started without a folder for its keyframe store"
  fi
  grep -q "keyframe store's temporary folder.*--state-dir" "$DIR/ro-tmp.log" \
    || { cat "$DIR/ro-tmp.log" >&2; fail "expected one clear line for a read-only /tmp"; }
  say "  -> $(tail -1 "$DIR/ro-tmp.log")"
  say "cslam-server runs in a read-only container root with --state-dir on the volume"
  "${E[@]}" run -d --name cslam-smoke-ro "${RUN_OPTS[@]}" --no-healthcheck --network none "${RO[@]}" -v "$DATA:/data" \
    "$IMAGE" cslam-server --http off --bind "tcp://127.0.0.1:$ZMQ_PORT" --state-dir /data/ro-state \
    --out-dir /data/ro-out > /dev/null
  for _ in $(seq 1 150); do
    "${E[@]}" logs cslam-smoke-ro 2>&1 | grep -q "live dense map on" && break
    sleep 0.2
  done
  "${E[@]}" stop -t 20 cslam-smoke-ro > /dev/null
  "${E[@]}" logs cslam-smoke-ro > "$DIR/ro-state.log" 2>&1
  RO_EXIT=$("${E[@]}" inspect --format '{{.State.ExitCode}}' cslam-smoke-ro)
  "${E[@]}" rm -f cslam-smoke-ro > /dev/null
  grep -q "keyframe store /data/ro-state/dense" "$DIR/ro-state.log" \
    || { cat "$DIR/ro-state.log" >&2; fail "no live dense map in a read-only container with --state-dir"; }
  [ "$RO_EXIT" = 0 ] || { cat "$DIR/ro-state.log" >&2; fail "the read-only container's server exited $RO_EXIT"; }
  say "  -> $(grep -o 'live dense map on.*' "$DIR/ro-state.log" | head -1); exit code 0 after SIGTERM"
fi

# A server built with CURVE support (cslam-keygen in the image) runs keyed, as a deployment should:
# keys made by the image's cslam-keygen, each robot's key bound to its id.
SERVER_KEYS=(); CLIENT_KEYS=()
# (The help is read whole first: with pipefail, grep -q closing the pipe early could fail the test.)
SERVER_HELP=$(img cslam-server --help 2> /dev/null || true)
if grep -q -- --curve-secret <<< "$SERVER_HELP"; then
  say "the image's server supports CURVE: keys from its cslam-keygen in /data/keys"
  img sh -c 'mkdir -p /data/keys/clients && cslam-keygen --out /data/keys/server > /dev/null &&
             for k in 1 2; do cslam-keygen --out /data/keys/robot$k --client-ids $k > /dev/null &&
             cp /data/keys/robot$k.pub /data/keys/clients/; done' || fail "cslam-keygen"
  SERVER_KEYS=(--curve-secret /data/keys/server.key --clients-allowed /data/keys/clients)
  CLIENT_KEYS=(--server-key /data/keys/server.pub)
fi

# HTTP is bound beyond the container's loopback, so it serves HTTPS and needs a token: a self-signed
# certificate and a token made by the image's openssl, in /keys as the image's CMD and healthcheck
# expect (docs/security.md, "HTTP beyond loopback"). The checks below use -k (self-signed).
say "HTTP certificate and token from the image's openssl in /keys"
img sh -c 'openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes -days 2 -subj /CN=cslam-server \
             -addext subjectAltName=DNS:cslam-smoke-server,DNS:localhost,IP:127.0.0.1 \
             -keyout /keys/http.key -out /keys/http.crt 2> /dev/null &&
           (umask 077 && head -c 24 /dev/urandom | base64 > /keys/http.token)' || fail "openssl in the image"
HTTP_TOKEN=$(cat "$DATA/keys/http.token")
api() { in_net curl -sfk -H "Authorization: Bearer $HTTP_TOKEN" "$@"; }

say "synthetic scene (cslam-synth --preset test-small) into /data/scene"
img cslam-synth --preset test-small --out /data/scene --log-level warn > "$DIR/synth.log" 2>&1 || { cat "$DIR/synth.log"; fail "cslam-synth"; }

say "starting cslam-server"
SERVER_CMD=(cslam-server --bind "tcp://*:$ZMQ_PORT" --http "$HTTP_PORT" --http-bind 0.0.0.0 --out-dir /data/out
            --http-cert /keys/http.crt --http-key /keys/http.key --http-token-file /keys/http.token
            --clients 2 --exit-when-done --log-interval 5 "${SERVER_KEYS[@]}")
if [ "$MODE" = chroot ]; then
  "${IMG[@]}" "${SERVER_CMD[@]}" > "$DIR/server.log" 2>&1 &
  PIDS+=($!)
else
  "${E[@]}" run -d "${RUN_OPTS[@]}" --name cslam-smoke-server --network cslam-smoke -v "$DATA:/data" -v "$DATA/keys:/keys" \
    "$IMAGE" "${SERVER_CMD[@]}" > /dev/null
fi
STATUS=""
for _ in $(seq 1 100); do
  STATUS=$(api "$HTTP_URL/api/status" 2> /dev/null) && break
  sleep 0.2
done
[ -n "$STATUS" ] || { cat "$DIR/server.log" 2> /dev/null || "${E[@]}" logs cslam-smoke-server; fail "no /api/status answer"; }
say "/api/status answers: $STATUS"
[ "$(in_net curl -sk -o /dev/null -w '%{http_code}' "$HTTP_URL/api/status")" = 401 ] || fail "/api/status answers without the token"
in_net curl -sfk "$HTTP_URL/" > "$DIR/index.html" && grep -qi "<html" "$DIR/index.html" || fail "the viewer page is not served"
in_net curl -sfk "$HTTP_URL/vendor/three.module.js" > "$DIR/three.module.js" || fail "three.js is not served"
THREE=$(grep -o "REVISION = '[0-9]*'" "$DIR/three.module.js" | head -1)
[ -n "$THREE" ] || fail "/vendor/three.module.js is not three.js"
say "viewer page and /vendor/three.module.js served ($(wc -c < "$DIR/three.module.js") bytes, $THREE)"
# Every module of the viewer (web/*.js; the page loads app.js, which imports the others).
for m in web/*.js; do
  in_net curl -sfk -o /dev/null "$HTTP_URL/$(basename "$m")" || fail "the viewer module $(basename "$m") is not served by the image"
done
say "the viewer's $(ls web/*.js | wc -l) modules served"
if [ "$MODE" = chroot ]; then
  # The image's HEALTHCHECK command, with the port of this run.
  img sh -c "printf 'header = \"Authorization: Bearer %s\"\\n' \"\$(cat /keys/http.token)\" |
             curl -sfk -o /dev/null -K - https://127.0.0.1:$HTTP_PORT/api/status" || fail "healthcheck command failed"
else
  if [ "$ENGINE" = podman ]; then
    # The image's HEALTHCHECK itself, run by the engine in the server's container.
    "${E[@]}" healthcheck run cslam-smoke-server > "$DIR/healthcheck.log" 2>&1 \
      || { cat "$DIR/healthcheck.log" >&2; fail "the image's healthcheck does not pass in the server's container"; }
  else
    say "(docker has no 'healthcheck run'; the same curl was checked above from the network)"
  fi
fi
say "healthcheck command passes"

if [ ${#SERVER_KEYS[@]} -gt 0 ]; then
  if img cslam-client --server "tcp://$SERVER_HOST:$ZMQ_PORT" --id 1 --dataset /data/scene/robot_1 --range 1:2 \
       --reply-timeout 3 > "$DIR/client_nokey.log" 2>&1; then
    fail "a client without keys got through"
  fi
  say "a client without keys gets nothing"
fi

say "two replay clients (robot_1 full frames, robot_2 a lean stream: H.264 colour through the image's libavcodec)"
CPIDS=()
for k in 1 2; do
  KEYS=()
  [ ${#CLIENT_KEYS[@]} -gt 0 ] && KEYS=("${CLIENT_KEYS[@]}" --curve-secret "/data/keys/robot$k.key")
  LEAN=(); [ "$k" = 2 ] && LEAN=(--depth-every 5)
  "${IMG[@]}" cslam-client --server "tcp://$SERVER_HOST:$ZMQ_PORT" --id "$k" --dataset "/data/scene/robot_$k" --rate max \
    "${KEYS[@]}" "${LEAN[@]}" > "$DIR/client_$k.log" 2>&1 &
  CPIDS+=($!)
done
PIDS+=("${CPIDS[@]}")
# /api/status while the robots stream (as a service next to them would see it).
for _ in $(seq 1 150); do
  LIVE=$(api "$HTTP_URL/api/status" 2> /dev/null || true)
  [ "$(echo "$LIVE" | grep -o '"id":[0-9]*' | sort -u | wc -l)" -ge 2 ] && break
  sleep 0.2
done
say "/api/status with the robots connected: $LIVE"
for p in "${CPIDS[@]}"; do wait "$p" || { cat "$DIR"/client_*.log >&2; fail "a client failed"; }; done
say "clients done; waiting for the server to write its results"
if [ "$MODE" = chroot ]; then
  wait "${PIDS[0]}" || { tail -20 "$DIR/server.log" >&2; fail "the server failed"; }
else
  [ "$("${E[@]}" wait cslam-smoke-server)" = 0 ] || { "${E[@]}" logs cslam-smoke-server >&2; fail "the server failed"; }
fi
for k in 1 2; do
  f="$DATA/out/client_$k.txt"
  [ -s "$f" ] || fail "no trajectory $f"
  n=$(grep -vc '^#' "$f")
  ate=$(img cslam-eval ate "/data/scene/robot_$k/groundtruth.txt" "/data/out/client_$k.txt" | tail -1 | awk '{print $6}')
  say "client $k: $n poses, APE RMSE $ate m (the image's cslam-eval against the scene's ground truth)"
done
LIGHT=$(grep -o '"frames_light": *[0-9]*' "$DATA/out/network_stats.json" | awk -F: '{s += $2} END {print s + 0}')
[ "$LIGHT" -gt 0 ] || fail "the server received no light frames from the lean robot (network_stats.json)"
say "lean robot: $LIGHT light frames decoded by the image's server"
say "PASS ($MODE mode, image $IMAGE, $(awk -v s="$SIZE" 'BEGIN{printf "%.0f MB", s/1e6}'))"
