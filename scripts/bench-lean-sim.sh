#!/usr/bin/env bash
# The lean stream offline, over several demo scenes: cslam-slam --datasets robot_1 robot_2
# robot_3 --sync (deterministic: one outcome per scene and variant) with each variant's options,
# e.g. --coded-colour (the client's codecs and back) and --depth-every 5 (the lean stream). One
# scene's outcome is chaotic (a loop closed or missed at the end of a robot's run moves its ATE
# 2x), so each variant runs on every scene and is judged by its mean over them. Prints per scene
# the mean of the three robots' ATE (RMSE, cslam-eval, SE3 alignment) in mm, the mean over the
# scenes, its ratio to the first variant's and that ratio's standard error from the per-scene
# differences (one standard error: +-3-9 % over six scenes, +-3-4 % over 24; SEEDS="0 $(seq -s " " 101 123)" runs 24).
# Usage: scripts/bench-lean-sim.sh [OUT=bench_out/lean_sim] [SEEDS="0 101 102 103 104 105"]
#        [VARIANTS="full=--coded-colour|lean=--coded-colour --depth-every 5"]
# SEEDS: 0 is the demo preset's own scene; others render the preset with that --seed.
# VARIANTS: name=cslam-slam options, separated by '|'.
set -euo pipefail
cd "$(dirname "$0")/.."
OUT="${1:-bench_out/lean_sim}"
SEEDS="${2:-0 101 102 103 104 105}"
VARIANTS="${3:-full=--coded-colour|lean=--coded-colour --depth-every 5}"
BIN="$PWD/build/bin"
mkdir -p "$OUT"
echo "== machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)"
echo "== revision $(git rev-parse --short HEAD)$(git diff --quiet || echo '+dirty'); seeds: $SEEDS"

scene_of() {
  local scene="$OUT/scene_$1" seed=()
  [ "$1" != 0 ] && seed=(--seed "$1")
  if [ ! -f "$scene/robot_3/groundtruth.txt" ]; then
    "$BIN/cslam-synth" --preset demo "${seed[@]}" --out "$scene" --force --log-level warn > /dev/null
  fi
  echo "$scene"
}

IFS='|' read -r -a variants <<< "$VARIANTS"
# One scene's variants in order; two scenes at a time (each run is deterministic, so running
# side by side changes nothing but the wall time).
one_scene() {
  local seed=$1 scene v name dir opts k
  scene=$(scene_of "$seed")
  for v in "${variants[@]}"; do
    name="${v%%=*}"
    read -r -a opts <<< "${v#*=}"
    dir="$OUT/${name}_$seed"
    rm -rf "$dir"  # a failed run must not leave an earlier run's figures to be summed
    "$BIN/cslam-slam" --datasets "$scene/robot_1" "$scene/robot_2" "$scene/robot_3" --sync --out-dir "$dir" \
      --quiet --log-level warn "${opts[@]}" > "$dir.log" 2>&1
    for k in 1 2 3; do
      "$BIN/cslam-eval" ate "$scene/robot_$k/groundtruth.txt" "$dir/client_$k.txt" --json > "$dir/ate_$k.json"
    done
    echo "-- scene $seed, $name done"
  done
}
running=0
for seed in $SEEDS; do
  one_scene "$seed" &
  running=$((running + 1))
  if [ "$running" -ge 2 ]; then wait -n; running=$((running - 1)); fi
done
wait

python3 - "$OUT" "$SEEDS" "$VARIANTS" <<'EOF'
import json, sys
out, seeds, variants = sys.argv[1], sys.argv[2].split(), [v.split("=", 1)[0] for v in sys.argv[3].split("|")]
def scene_mean(name, seed):
    return sum(json.load(open(f"{out}/{name}_{seed}/ate_{k}.json"))["rmse"] for k in (1, 2, 3)) / 3 * 1000
print("\n| variant | " + " | ".join(f"scene {s}" for s in seeds) + " | mean mm | ratio | ± SE |")
print("|---" * (len(seeds) + 4) + "|")
base = [scene_mean(variants[0], s) for s in seeds]
first = sum(base) / len(base)
for name in variants:
    per = [scene_mean(name, s) for s in seeds]
    mean = sum(per) / len(per)
    # The standard error of the ratio from the scenes' paired differences to the first variant:
    # one scene's outcome is chaotic, so only many scenes resolve a few per cent.
    d = [a - b for a, b in zip(per, base)]
    n = len(d)
    sd = (sum((x - sum(d) / n) ** 2 for x in d) / (n - 1)) ** 0.5 if n > 1 else float("nan")
    se = sd / n ** 0.5 / first
    print(f"| {name} | " + " | ".join(f"{x:.2f}" for x in per) + f" | {mean:.3f} | {mean / first:.3f} | "
          + ("" if name == variants[0] else f"{se:.3f}") + " |")
EOF
