#pragma once
// Scheduling priority and name of the calling thread. SLAM's compute threads (per-client workers,
// local mapping, loop closing, fusion) run a little below the I/O threads (network receiver, HTTP)
// so that a saturated machine keeps the server responsive; compute throughput is unchanged.
#include <exception>
#include <string>
#include <thread>

namespace cslam {

// How far below the I/O threads each kind of thread runs (nice increments; the kernel caps nice
// at 19). On a saturated machine the kernel shares a core by these weights, so the work a robot
// waits for (tracking, and local mapping whose map locks tracking reads under) must not compete
// evenly with background work.
inline constexpr int kComputeNice = 5;  // tracking, local mapping, loop closing, map fusion
inline constexpr int kDenseNice = 15;   // the live dense map: it catches up when the robots stop
// Group BA solves (run_at_lower_priority: the snapshot and the writes stay at kComputeNice): the
// largest CPU consumer with several robots, and most runs are cut short by the next link; at an
// even share with tracking they stretched the waits for a core of everything else
// (docs/results/capacity.md).
inline constexpr int kGroupBaNice = 19;

// Raises the calling thread's nice value by `delta` (Linux, per thread; lowering priority needs
// no privilege). Returns false if the system refused; never throws.
bool lower_current_thread_priority(int delta = kComputeNice);

// The cores this process may run on: its CPU affinity mask (a container limited to a cpuset sees
// its own), else the machine's hardware threads; at least 1.
int usable_cores();

// Names the calling thread after its stage, e.g. "track/c3" (Linux keeps 15 characters): top -H,
// ps -L, perf and /proc/PID/task/TID/comm show it, and the capacity benchmark sums CPU per stage.
void name_current_thread(const std::string& name);

// Runs f() on a thread of its own, named `name`, `delta` nice steps below the caller, and waits
// for it (rethrowing what it threw). For a long computation between steps that hold map locks:
// only the computation yields the core, while the locked steps keep the caller's priority (a lock
// holder at nice 19 waits for a core behind every busy thread, and so do the trackers waiting on
// its lock). Lowering needs no privilege; raising a thread's priority back would.
template <class F>
void run_at_lower_priority(int delta, const std::string& name, F&& f) {
  std::exception_ptr error;
  std::thread worker([&] {
    name_current_thread(name);
    lower_current_thread_priority(delta);
    try {
      f();
    } catch (...) {
      error = std::current_exception();
    }
  });
  worker.join();
  if (error) std::rethrow_exception(error);
}

}  // namespace cslam
