#include "core/thread_priority.h"

#include <pthread.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <cerrno>

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

void name_current_thread(const std::string& name) {
#ifdef __linux__
  ::pthread_setname_np(::pthread_self(), name.substr(0, 15).c_str());
#else
  (void)name;
#endif
}

}  // namespace cslam
