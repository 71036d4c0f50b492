#!/usr/bin/env bash
# Hardening figures of docs/security.md: cslam-bench-hostile RUNS times without and with the
# hostile peer (SLAM off: the network path alone), and once with SLAM on for the threads a real
# client pipeline costs. Prints median and min-max per figure, and the machine load.
#   scripts/bench-hardening.sh [RUNS] [FRAMES]
set -euo pipefail
cd "$(dirname "$0")/.."
RUNS="${1:-3}"
FRAMES="${2:-300}"
BIN=build/bin
OUT="${TMPDIR:-/tmp}/cslam-bench-hardening"
rm -rf "$OUT"; mkdir -p "$OUT"
echo "machine: $(nproc) cores, load before: $(cut -d' ' -f1-3 /proc/loadavg)"
for i in $(seq "$RUNS"); do
  "$BIN/cslam-bench-hostile" --bin "$BIN" --out "$OUT/b$i" --frames "$FRAMES" 2>/dev/null | tail -1 >> "$OUT/baseline.jsonl"
  "$BIN/cslam-bench-hostile" --bin "$BIN" --out "$OUT/h$i" --frames "$FRAMES" --hostile 2>/dev/null | tail -1 >> "$OUT/hostile.jsonl"
done
"$BIN/cslam-bench-hostile" --bin "$BIN" --out "$OUT/s1" --frames 60 --hostile --slam 2>/dev/null | tail -1 >> "$OUT/slam.jsonl"
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)"
python3 - "$OUT" <<'PY'
import json, statistics, sys
out = sys.argv[1]
def load(name):
    return [json.loads(l) for l in open(f"{out}/{name}.jsonl") if l.strip()]
def fmt(rows, key):
    v = [r[key] for r in rows]
    return f"{statistics.median(v):.2f} ({min(v):.2f}-{max(v):.2f})"
b, h, s = load("baseline"), load("hostile"), load("slam")
print("| figure | without hostile peer | with hostile peer |")
print("|---|---|---|")
for key in ["receive_loop_max_ms", "receive_loop_max_cpu_ms", "message_max_ms", "message_max_cpu_ms", "decode_max_ms", "peak_rss_mb", "status_ms_p50", "status_ms_p99",
            "status_ms_max", "stream_s", "threads_end"]:
    print(f"| {key} | {fmt(b, key)} | {fmt(h, key)} |")
print(f"| status probes failed | {sum(r['status_probes_failed'] for r in b)} | {sum(r['status_probes_failed'] for r in h)} |")
print(f"| good client all acked | {all(r['good_all_acked'] for r in b)} | {all(r['good_all_acked'] for r in h)} |")
rss = [hr['peak_rss_mb'] / br['peak_rss_mb'] for hr, br in zip(h, b)]
print(f"peak RSS ratio hostile/baseline: median {statistics.median(rss):.2f} ({min(rss):.2f}-{max(rss):.2f})")
print("message max ms by kind (hostile runs, wall):", [r["message_max_ms_by_kind"] for r in h])
print("message max ms by kind (hostile runs, thread CPU):", [r["message_max_cpu_ms_by_kind"] for r in h])
for r in s:
    print(f"SLAM on: threads idle {r['threads_idle']}, after 1000 hellos {r['threads_after_1000_hellos']} "
          f"(--max-clients 64), end {r['threads_end']}, peak RSS {r['peak_rss_mb']:.0f} MB, "
          f"loop max {r['receive_loop_max_ms']:.1f} ms, message max {r['message_max_ms']:.1f} ms {r['message_max_ms_by_kind']}")
PY
