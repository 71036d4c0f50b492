#!/usr/bin/env python3
"""CPU seconds per thread of a running process, summed per stage, until the process ends.

Usage: thread-cpu.py PID OUT.json [--child]
  --child: PID is a wrapper (e.g. /usr/bin/time); sample its first child instead.

The server names its threads after their stages (name_current_thread: "track/c3", "mapping/c3",
"fusion", "dense", ...). Every 0.2 s this reads /proc/PID/task/*/stat and keeps each thread's last
user + system time; a thread that ends between two samples loses at most 0.2 s of its count.
OUT.json: {"stages": {"track": s, ...}, "threads": {"track/c3": s, ...}, "sampled_s": total}.
The stage of a thread is its name without the "/cN" client suffix; the main thread (named after
the program) is the receive loop.
"""
import json
import os
import re
import sys
import time

TICK = os.sysconf("SC_CLK_TCK")


def child_of(pid, timeout_s=10.0):
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        try:
            kids = open(f"/proc/{pid}/task/{pid}/children").read().split()
            if kids:
                return int(kids[0])
        except OSError:
            return None
        time.sleep(0.02)
    return None


def sample(pid, last):
    try:
        tids = os.listdir(f"/proc/{pid}/task")
    except OSError:
        return False
    for tid in tids:
        try:
            raw = open(f"/proc/{pid}/task/{tid}/stat").read()
        except OSError:
            continue
        name = raw[raw.index("(") + 1 : raw.rindex(")")]
        fields = raw[raw.rindex(")") + 2 :].split()
        # utime and stime are stat fields 14 and 15; fields[0] is field 3 (state).
        last[int(tid)] = (name, (int(fields[11]) + int(fields[12])) / TICK)
    return True


def main():
    pid, out = int(sys.argv[1]), sys.argv[2]
    if "--child" in sys.argv[3:]:
        pid = child_of(pid)
    last = {}
    while pid is not None and sample(pid, last):
        time.sleep(0.2)
    threads, stages = {}, {}
    for tid, (name, cpu) in last.items():
        stage = "receive" if tid == pid else re.sub(r"/c\d+$", "", name)
        threads[name] = threads.get(name, 0.0) + cpu
        stages[stage] = stages.get(stage, 0.0) + cpu
    result = {
        "stages": {k: round(v, 2) for k, v in sorted(stages.items())},
        "threads": {k: round(v, 2) for k, v in sorted(threads.items())},
        "sampled_s": round(sum(stages.values()), 2),
    }
    with open(out, "w") as f:
        json.dump(result, f, indent=1)


if __name__ == "__main__":
    main()
