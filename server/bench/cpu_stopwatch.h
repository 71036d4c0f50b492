#pragma once
// Thread CPU time in ms for the benchmarks: other processes on the machine (builds) distort wall
// time, not this.
#include <ctime>

namespace cslam {

class CpuStopwatch {
 public:
  CpuStopwatch() { reset(); }
  void reset() { start_ = now(); }
  double ms() const { return now() - start_; }

 private:
  static double now() {
    timespec ts{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return ts.tv_sec * 1e3 + ts.tv_nsec / 1e6;
  }
  double start_ = 0;
};

}  // namespace cslam
