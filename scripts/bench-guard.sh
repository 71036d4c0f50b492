#!/usr/bin/env bash
# The accuracy guard set: deterministic (--sync) single-client runs of fr1/desk, fr1/desk 1:219
# (client 1 of the paper's 3-client split), fr1/rpy, and 12 overlapping 150-frame segments (6 of
# each sequence, each from an empty map). Prints each run's ATE (RMSE, m), keyframes, flow frames
# and CPU seconds, the segments' mean ATE, and one md5 over every trajectory (equal md5: outputs
# byte-identical). Two runs at a time.
# Usage: scripts/bench-guard.sh [OUT=bench_out/guard] [-- extra cslam-slam options, e.g. --no-flow]
set -euo pipefail
cd "$(dirname "$0")/.."
OUT="${1:-bench_out/guard}"
shift || true
[ "${1:-}" = "--" ] && shift
EXTRA=("$@")
BIN=build/bin
DESK="${CSLAM_TUM_DESK:-../shared/data/tum_fr1_desk}"
RPY="${CSLAM_TUM_RPY:-../shared/data/tum_fr1_rpy}"
for d in "$DESK" "$RPY"; do [ -f "$d/rgb.txt" ] || { echo "bench-guard: $d not found" >&2; exit 1; }; done
mkdir -p "$OUT"
echo "== machine: $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg); revision $(git rev-parse --short HEAD)$(git diff --quiet || echo '+dirty'); options: ${EXTRA[*]:-none}"

# name dataset range(all|a:b)
jobs_list=("desk $DESK all" "desk_1_219 $DESK 1:219" "rpy $RPY all")
for s in 1 90 180 270 360 447; do jobs_list+=("seg_desk_$s $DESK $s:$((s + 149))"); done
for s in 1 115 230 345 460 574; do jobs_list+=("seg_rpy_$s $RPY $s:$((s + 149))"); done

one() {
  local name=$1 ds=$2 range=$3 extra=()
  [ "$range" != all ] && extra+=(--range "$range")
  /usr/bin/time -f "%U %S" -o "$OUT/$name.time" "$BIN/cslam-slam" --dataset "$ds" --camera tum1 --sync --out "$OUT/$name.txt" \
    --stats "$OUT/$name.json" --quiet --log-level warn "${extra[@]}" "${EXTRA[@]}" > /dev/null
}
running=0
for j in "${jobs_list[@]}"; do
  # shellcheck disable=SC2086
  one $j &
  running=$((running + 1))
  if [ "$running" -ge 2 ]; then wait -n; running=$((running - 1)); fi
done
wait

/usr/bin/python3 - "$BIN" "$OUT" "${jobs_list[@]}" <<'PY'
import hashlib, json, os, subprocess, sys
bin_, out, *jobs = sys.argv[1:]
rows, seg, md5 = [], [], hashlib.md5()
for j in jobs:
    name, ds, _ = j.split()
    traj = os.path.join(out, name + ".txt")
    md5.update(open(traj, "rb").read())
    ate = json.loads(subprocess.run([f"{bin_}/cslam-eval", "ate", os.path.join(ds, "groundtruth.txt"), traj, "--json"],
                                    check=True, capture_output=True, text=True).stdout)["rmse"]
    st = json.load(open(os.path.join(out, name + ".json")))
    cpu = sum(float(x) for x in open(os.path.join(out, name + ".time")).read().split()[:2])
    rows.append((name, ate, st["keyframes"], st.get("frames_flow", 0), st["frames"], cpu))
    if name.startswith("seg_"):
        seg.append(ate)
print(f"{'run':<14} {'ATE m':>8} {'KFs':>5} {'flow':>5} {'frames':>6} {'CPU s':>6}")
for r in rows:
    print(f"{r[0]:<14} {r[1]:>8.4f} {r[2]:>5} {r[3]:>5} {r[4]:>6} {r[5]:>6.2f}")
print(f"segments mean ATE {sum(seg) / len(seg):.4f} m over {len(seg)}; total CPU {sum(r[5] for r in rows):.1f} s; "
      f"trajectories md5 {md5.hexdigest()}")
PY
