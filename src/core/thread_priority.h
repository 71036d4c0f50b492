#pragma once
// Scheduling priority and name of the calling thread. SLAM's compute threads (per-client workers,
// local mapping, loop closing, fusion) run a little below the I/O threads (network receiver, HTTP)
// so that a saturated machine keeps the server responsive; compute throughput is unchanged.
#include <string>

namespace cslam {

// Raises the calling thread's nice value by `delta` (Linux, per thread; lowering priority needs
// no privilege). Returns false if the system refused; never throws.
bool lower_current_thread_priority(int delta = 5);

// Names the calling thread after its stage, e.g. "track/c3" (Linux keeps 15 characters): top -H,
// ps -L, perf and /proc/PID/task/TID/comm show it, and the capacity benchmark sums CPU per stage.
void name_current_thread(const std::string& name);

}  // namespace cslam
