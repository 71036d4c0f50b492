#pragma once
// Scheduling priority of the calling thread. SLAM's compute threads (per-client workers, local
// mapping, loop closing, fusion) run a little below the I/O threads (network receiver, HTTP) so
// that a saturated machine keeps the server responsive; compute throughput is unchanged.
namespace cslam {

// Raises the calling thread's nice value by `delta` (Linux, per thread; lowering priority needs
// no privilege). Returns false if the system refused; never throws.
bool lower_current_thread_priority(int delta = 5);

}  // namespace cslam
