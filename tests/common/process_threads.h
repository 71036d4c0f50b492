#pragma once
// The number of threads of the test process (/proc/self/task): checks that threads are joined.
//
// A joined thread's entry can outlive pthread_join by a moment: the kernel wakes the joiner when
// the thread releases its memory map, and reaps the task a little later (measured: 61 of 20 000
// join-then-count pairs still saw the thread). A check after joins therefore asks for the count
// to settle at or below a bound; a thread that was never joined keeps it above, and the check
// fails after the deadline.
#include <chrono>
#include <cstddef>
#include <thread>

#include <dirent.h>

namespace cslam::test {

inline std::size_t thread_count() {
  std::size_t n = 0;
  if (DIR* d = opendir("/proc/self/task")) {
    while (dirent* e = readdir(d)) n += e->d_name[0] != '.';
    closedir(d);
  }
  return n;
}

// The thread count once exited threads have been reaped: returns as soon as it is <= `bound`,
// or the count at the deadline otherwise.
inline std::size_t thread_count_settled_to(std::size_t bound,
                                           std::chrono::milliseconds deadline = std::chrono::seconds(5)) {
  const auto until = std::chrono::steady_clock::now() + deadline;
  std::size_t n = thread_count();
  while (n > bound && std::chrono::steady_clock::now() < until) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
    n = thread_count();
  }
  return n;
}

}  // namespace cslam::test
