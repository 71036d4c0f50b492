#include "core/thread_priority.h"

#include <pthread.h>
#include <sched.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <thread>

namespace cslam {

bool lower_current_thread_priority(int delta) {
#ifdef __linux__
  const pid_t tid = pid_t(::syscall(SYS_gettid));
  errno = 0;
  const int current = ::getpriority(PRIO_PROCESS, id_t(tid));
  if (current == -1 && errno != 0) return false;
  return ::setpriority(PRIO_PROCESS, id_t(tid), current + delta) == 0;
#else
  (void)delta;
  return false;
#endif
}

int usable_cores() {
#ifdef __linux__
  cpu_set_t set;
  CPU_ZERO(&set);
  if (::sched_getaffinity(0, sizeof(set), &set) == 0) return std::max(1, CPU_COUNT(&set));
#endif
  return std::max(1, int(std::thread::hardware_concurrency()));
}

void name_current_thread(const std::string& name) {
#ifdef __linux__
  ::pthread_setname_np(::pthread_self(), name.substr(0, 15).c_str());
#else
  (void)name;
#endif
}

}  // namespace cslam
