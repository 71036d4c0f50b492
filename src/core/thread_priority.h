#pragma once
// Scheduling priority and name of the calling thread. SLAM's compute threads (per-client workers,
// local mapping, loop closing, fusion) run a little below the I/O threads (network receiver, HTTP)
// so that a saturated machine keeps the server responsive; compute throughput is unchanged.
#include <string>

namespace cslam {

// How far below the I/O threads each kind of thread runs (nice increments; the kernel caps nice
// at 19). On a saturated machine the kernel shares a core by these weights, so the work a robot
// waits for (tracking, and local mapping whose map locks tracking reads under) must not compete
// evenly with background work.
inline constexpr int kComputeNice = 5;  // tracking, local mapping, loop closing, map fusion
inline constexpr int kDenseNice = 15;   // the live dense map: it catches up when the robots stop
// Group BAs: the largest CPU consumer with several robots, and most runs are cut short by the
// next link; at an even share with tracking they stretched the map-lock holds tracking waits on
// (4 robots live in a slow spell: pose latency p99 127-128 against 156-163 ms in two sittings,
// docs/results/capacity.md).
inline constexpr int kGroupBaNice = 19;

// Raises the calling thread's nice value by `delta` (Linux, per thread; lowering priority needs
// no privilege). Returns false if the system refused; never throws.
bool lower_current_thread_priority(int delta = kComputeNice);

// Names the calling thread after its stage, e.g. "track/c3" (Linux keeps 15 characters): top -H,
// ps -L, perf and /proc/PID/task/TID/comm show it, and the capacity benchmark sums CPU per stage.
void name_current_thread(const std::string& name);

}  // namespace cslam
