"""Shared helpers of the Python tests: programs from build/bin, a synthetic scene, a server run."""
import json
import os
import shutil
import subprocess
import tempfile
import time

BIN = os.environ.get("CSLAM_BIN_DIR", "")
# The servers run --deterministic (mapping inline on the client's worker): identical frames give
# the identical trajectory, whichever client library or replay tool sent them. (Threaded, seven
# identical cslam-client runs on the test-small robot 1 gave APE RMSE 5.4-10.3 mm.)
ATE_TOLERANCE = 1e-6
ATE_MAX = 0.03
SCRATCH = os.environ.get("CSLAM_SCRATCH", tempfile.gettempdir())


def program(name):
    path = os.path.join(BIN, name)
    if not os.path.isfile(path):
        raise AssertionError(f"{path} missing: build the project and run through ctest")
    return path


def scratch(name):
    d = tempfile.mkdtemp(prefix=f"{name}-", dir=SCRATCH)
    return d


def synth_scene(out, frames=None):
    args = [program("cslam-synth"), "--preset", "test-small", "--out", out, "--log-level", "warn"]
    if frames:
        args += ["--frames", str(frames)]
    subprocess.run(args, check=True)
    return out


class Server:
    """cslam-server on a free loopback port, ending by itself after `clients` goodbyes."""

    def __init__(self, run_dir, clients=1, extra=()):
        self.dir = run_dir
        os.makedirs(run_dir, exist_ok=True)
        self.out = os.path.join(run_dir, "out")
        endpoint_file = os.path.join(run_dir, "endpoint")
        self.log_path = os.path.join(run_dir, "server.log")
        self.log = open(self.log_path, "w")
        self.proc = subprocess.Popen(
            [program("cslam-server"), "--bind", "tcp://127.0.0.1:*", "--endpoint-file", endpoint_file, "--out-dir",
             self.out, "--http", "off", "--clients", str(clients), "--exit-when-done", "--log-interval", "5",
             "--deterministic", *extra],
            stdout=self.log, stderr=subprocess.STDOUT)
        deadline = time.monotonic() + 30
        while not (os.path.exists(endpoint_file) and open(endpoint_file).read().strip()):
            if self.proc.poll() is not None or time.monotonic() > deadline:
                self.stop()
                raise AssertionError(f"server did not start, see {self.log_path}")
            time.sleep(0.05)
        self.endpoint = open(endpoint_file).read().strip()

    def wait(self, timeout=300):
        try:
            return self.proc.wait(timeout)
        finally:
            self.log.close()

    def stop(self):
        if self.proc.poll() is None:
            self.proc.terminate()
            self.proc.wait(30)
        self.log.close()

    def network_stats(self):
        with open(os.path.join(self.out, "network_stats.json")) as f:
            return json.load(f)

    def trajectory(self, client_id):
        return read_tum(os.path.join(self.out, f"client_{client_id}.txt"))


def read_tum(path):
    rows = []
    with open(path) as f:
        for line in f:
            if line.strip() and not line.startswith("#"):
                rows.append([float(v) for v in line.split()])
    return rows


def ate_rmse(groundtruth, estimate):
    """APE RMSE (m, SE3 alignment) from cslam-eval's table (a header line naming the columns)."""
    out = subprocess.run([program("cslam-eval"), "ate", groundtruth, estimate], check=True, capture_output=True,
                         text=True).stdout.splitlines()
    for header, values in zip(out, out[1:]):
        names, vals = header.split(), values.split()
        if "rmse" in names and 0 < len(vals) <= len(names):
            names = names[len(names) - len(vals):]  # the unit label heads the row names' column
            return float(vals[names.index("rmse")])
    raise AssertionError("no rmse column in cslam-eval output: " + "\n".join(out))


def client_stats(stats, client_id):
    for c in stats["clients"]:
        if c.get("id", c.get("client")) == client_id:
            return c
    raise AssertionError(f"client {client_id} not in network_stats.json: {stats}")


def cleanup(path, ok):
    if ok:
        shutil.rmtree(path, ignore_errors=True)
