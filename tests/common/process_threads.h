#pragma once
// The number of threads of the test process (/proc/self/task): checks that threads are joined.
#include <cstddef>

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

}  // namespace cslam::test
