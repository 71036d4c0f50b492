#!/usr/bin/env bash
# Hardening figures of docs/security.md: cslam-bench-hostile RUNS times without and with the
# hostile peer (SLAM off: the network path alone), and once with SLAM on for the threads a real
# client pipeline costs. Prints median and min-max per figure, and the machine load.
#   scripts/bench-hardening.sh [RUNS] [FRAMES]
#   scripts/bench-hardening.sh recon [RUNS]   reconstruction memory (hardening round 2, item 6):
#     a real cslam-server (SLAM on) serves two synthetic 60-frame 320x240 clients, then takes 50
#     reconstruction requests in a row at the default parameters and 5 at the finest (refused
#     over --recon-max-mb) and 5 at the finest the budget allows; the server's RSS before, its
#     peak, after each phase with the finished jobs kept, and after they expired.
set -euo pipefail
cd "$(dirname "$0")/.."
if [ "${1:-}" = recon ]; then
  RUNS="${2:-3}"
  BIN=build/bin
  OUT="${TMPDIR:-/tmp}/cslam-bench-recon"
  rm -rf "$OUT"; mkdir -p "$OUT"
  "$BIN/cslam-synth" --preset test-small --out "$OUT/scene" --log-level warn >/dev/null
  echo "machine: $(nproc) cores, load before: $(cut -d' ' -f1-3 /proc/loadavg)"
  cat > "$OUT/driver.py" <<'PY'
import json, os, signal, subprocess, sys, threading, time, urllib.request, urllib.error
binp, scene, out = sys.argv[1:4]
KEEP_S = 15  # --recon-keep-s for the run, so that expiry is seen within it
os.makedirs(out, exist_ok=True)
log = open(f"{out}/server.log", "w")
srv = subprocess.Popen([f"{binp}/cslam-server", "--bind", "tcp://127.0.0.1:*", "--endpoint-file", f"{out}/endpoint",
                        "--out-dir", f"{out}/out", "--http", "0", "--http-port-file", f"{out}/port", "--datasets-dir", scene,
                        "--session-ttl", "0", "--recon-keep-s", str(KEEP_S), "--log-level", "info"], stdout=log, stderr=log)
def wait_file(p):
    for _ in range(600):
        if os.path.exists(p) and open(p).read().strip(): return open(p).read().split()[0]
        time.sleep(0.1)
    raise SystemExit(f"no {p}")
endpoint, port = wait_file(f"{out}/endpoint"), wait_file(f"{out}/port")
base = f"http://127.0.0.1:{port}"
def http(method, path):
    req = urllib.request.Request(base + path, method=method, data=b"" if method == "POST" else None)
    try:
        with urllib.request.urlopen(req, timeout=60) as r: return r.status, r.read()
    except urllib.error.HTTPError as e: return e.code, e.read()
def rss_mb():
    for line in open(f"/proc/{srv.pid}/status"):
        if line.startswith("VmRSS:"): return int(line.split()[1]) / 1024
peak = [0.0]; sampling = [True]
def sampler():
    while sampling[0]:
        peak[0] = max(peak[0], rss_mb()); time.sleep(0.05)
clients = [subprocess.Popen([f"{binp}/cslam-client", "--server", endpoint, "--id", str(k), "--dataset", f"{scene}/robot_{k}"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL) for k in (1, 2)]
for c in clients: c.wait(timeout=600)
for _ in range(600):  # every frame processed
    st = json.loads(http("GET", "/api/status")[1])
    if len(st["clients"]) == 2 and all(c["frames_processed"] >= 60 and c["queue_depth"] == 0 for c in st["clients"]): break
    time.sleep(0.2)
time.sleep(3)
r = {"rss_before": rss_mb()}
threading.Thread(target=sampler, daemon=True).start()
def run_job(query):
    code, body = http("POST", "/api/reconstruction" + query)
    if code != 202: return code, None
    job = json.loads(body)["job"]
    while True:
        v = json.loads(http("GET", f"/api/reconstruction/{job}")[1])
        if v["state"] not in ("queued", "running"): break
        time.sleep(0.1)
    if v["state"] == "done": http("GET", v["cloud_url"])  # a download, as a user would
    return code, v
def wait_expired():
    for _ in range(KEEP_S * 10 + 100):
        if json.loads(http("GET", "/api/status")[1])["reconstruction"]["jobs"] == 0: break
        time.sleep(0.1)
    time.sleep(1)
    return rss_mb()
peak[0] = 0; views = []
for _ in range(50):
    code, v = run_job("")
    if v and v["state"] == "done": views.append(v)
r["defaults_done"] = len(views)
r["defaults_peak"] = peak[0]
time.sleep(1)
r["defaults_after_kept"] = rss_mb()
r["defaults_after_expired"] = wait_expired()
r["defaults_job_s"] = sorted(v["elapsed_s"] for v in views)[len(views) // 2]
r["defaults_estimate_mb"] = views[0]["estimate_mb"]
r["defaults_growth_mb"] = max(v["peak_growth_mb"] for v in views)
before = rss_mb(); refused = 0
for _ in range(5):
    code, body = http("POST", "/api/reconstruction?voxel=0.002&stride=1&mesh=1")
    refused += code == 413
    r["finest_estimate_mb"] = json.loads(body).get("estimate_mb", 0)
r["finest_refused"] = refused
r["finest_refused_rss_delta"] = rss_mb() - before
peak[0] = 0; views = []; r["finest_allowed"] = None
for voxel in ("0.003", "0.004", "0.005", "0.0075", "0.01"):
    q = f"?voxel={voxel}&stride=1&mesh=1"
    code, v = run_job(q)
    if code == 202:
        r["finest_allowed"] = q; views.append(v)
        break
for _ in range(4):
    code, v = run_job(r["finest_allowed"])
    views.append(v)
r["finest_allowed_done"] = sum(v is not None and v["state"] == "done" for v in views)
r["finest_allowed_peak"] = peak[0]
time.sleep(1)
r["finest_allowed_after_kept"] = rss_mb()
r["finest_allowed_after_expired"] = wait_expired()
r["finest_allowed_job_s"] = sorted(v["elapsed_s"] for v in views)[len(views) // 2]
r["finest_allowed_estimate_mb"] = views[0]["estimate_mb"]
r["finest_allowed_growth_mb"] = max(v["peak_growth_mb"] for v in views)
sampling[0] = False
srv.send_signal(signal.SIGTERM); srv.wait(timeout=120)
print(json.dumps(r))
PY
  for i in $(seq "$RUNS"); do
    python3 "$OUT/driver.py" "$BIN" "$OUT/scene" "$OUT/run$i" | tee -a "$OUT/runs.jsonl"
  done
  echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)"
  python3 - "$OUT/runs.jsonl" <<'PY'
import json, statistics, sys
rows = [json.loads(l) for l in open(sys.argv[1]) if l.strip().startswith("{")]
def fmt(key):
    v = [r[key] for r in rows]
    return f"{statistics.median(v):.1f} ({min(v):.1f}-{max(v):.1f})"
print(f"| figure (MB unless said; {len(rows)} runs, median (min-max)) | value |")
print("|---|---|")
for key in ["rss_before", "defaults_peak", "defaults_after_kept", "defaults_after_expired", "defaults_job_s",
            "finest_refused_rss_delta", "finest_allowed_peak", "finest_allowed_after_kept",
            "finest_allowed_after_expired", "finest_allowed_job_s", "finest_allowed_estimate_mb",
            "finest_allowed_growth_mb", "defaults_estimate_mb", "defaults_growth_mb", "finest_estimate_mb"]:
    print(f"| {key} | {fmt(key)} |")
print("finest allowed parameters:", sorted({r["finest_allowed"] for r in rows}))
print("all 50 default requests done:", all(r["defaults_done"] == 50 for r in rows),
      "| finest refused with 413:", all(r["finest_refused"] == 5 for r in rows),
      "| finest allowed done:", all(r["finest_allowed_done"] == 5 for r in rows))
PY
  exit 0
fi
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
