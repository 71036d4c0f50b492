#pragma once
#include <chrono>
#include <ctime>
#include <vector>

#include <sys/resource.h>

namespace cslam {

// Wall-clock stopwatch in milliseconds (steady clock).
class Stopwatch {
 public:
  Stopwatch() : start_(std::chrono::steady_clock::now()) {}
  void reset() { start_ = std::chrono::steady_clock::now(); }
  double ms() const {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start_).count();
  }

 private:
  std::chrono::steady_clock::time_point start_;
};

// CPU time of the calling thread (ms): its own work, apart from time it waited for a core.
inline double thread_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return double(ts.tv_sec) * 1e3 + double(ts.tv_nsec) / 1e6;
}

// CPU time of the whole process so far (ms): user and system, every thread.
inline double process_cpu_ms() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return (u.ru_utime.tv_sec + u.ru_stime.tv_sec) * 1e3 + (u.ru_utime.tv_usec + u.ru_stime.tv_usec) / 1e3;
}

// Wall-clock and process CPU time (ms) of repeated runs of a piece of code (benchmarks).
struct RepeatTiming {
  std::vector<double> wall, cpu;
  template <typename F>
  void measure(F&& f) {
    const double c0 = process_cpu_ms();
    Stopwatch sw;
    f();
    wall.push_back(sw.ms());
    cpu.push_back(process_cpu_ms() - c0);
  }
};

}  // namespace cslam
