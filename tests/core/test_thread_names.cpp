// Threads named after their stage (name_current_thread, QueueWorker's consumer thread), a
// computation run below its caller's priority (run_at_lower_priority), and the cores a process
// may use (usable_cores).
#include <pthread.h>
#include <sched.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <stdexcept>
#include <string>
#include <thread>

#include <gtest/gtest.h>

#include "core/queue_worker.h"
#include "core/thread_priority.h"

namespace {

std::string current_thread_name() {
  char name[16] = {};
  pthread_getname_np(pthread_self(), name, sizeof(name));
  return name;
}

int current_thread_nice() { return ::getpriority(PRIO_PROCESS, id_t(::syscall(SYS_gettid))); }

}  // namespace

TEST(ThreadNames, NameCurrentThreadSetsAndTruncatesToFifteenCharacters) {
  std::string short_name, long_name;
  std::thread([&] {
    cslam::name_current_thread("track/c3");
    short_name = current_thread_name();
    cslam::name_current_thread("a-stage-name-longer-than-fifteen");
    long_name = current_thread_name();
  }).join();
  EXPECT_EQ(short_name, "track/c3");
  EXPECT_EQ(long_name, "a-stage-name-lo");
}

TEST(ThreadNames, QueueWorkerThreadCarriesItsName) {
  std::string seen;
  {
    cslam::QueueWorker<int> worker(true, "mapping/c7", [&](const int&) { seen = current_thread_name(); });
    worker.start();
    worker.push_waiting(1, 1);
    worker.stop();
  }
  EXPECT_EQ(seen, "mapping/c7");
}

TEST(ThreadNames, SteppedQueueWorkerRunsOnTheCallersThreadUnrenamed) {
  std::string seen;
  std::thread([&] {
    cslam::name_current_thread("caller");
    cslam::QueueWorker<int> worker(false, "mapping/c7", [&](const int&) { seen = current_thread_name(); });
    worker.start();
    worker.push_waiting(1, 1);
    EXPECT_TRUE(worker.step());
  }).join();
  EXPECT_EQ(seen, "caller");
}

TEST(ThreadPriority, RunAtLowerPriorityLowersOnlyTheComputation) {
  int before = 0, inside = 0, after = 0;
  std::string name;
  std::thread([&] {
    before = current_thread_nice();
    cslam::run_at_lower_priority(3, "solve", [&] {
      inside = current_thread_nice();
      name = current_thread_name();
    });
    after = current_thread_nice();
  }).join();
  EXPECT_EQ(inside, std::min(19, before + 3));
  EXPECT_EQ(after, before);  // the caller keeps its priority for what it does next
  EXPECT_EQ(name, "solve");
}

TEST(ThreadPriority, RunAtLowerPriorityRethrowsOnTheCaller) {
  EXPECT_THROW(cslam::run_at_lower_priority(1, "solve", [] { throw std::runtime_error("solve failed"); }),
               std::runtime_error);
}

TEST(ThreadNames, UsableCoresFollowTheAffinityMask) {
  // On a thread of its own, so that the test runner's mask is never touched.
  int all = 0, one = 0;
  bool restricted = false;
  std::thread([&] {
    all = cslam::usable_cores();
    cpu_set_t mask;
    CPU_ZERO(&mask);
    if (::sched_getaffinity(0, sizeof(mask), &mask) != 0) return;
    int first = 0;
    while (!CPU_ISSET(first, &mask)) ++first;
    cpu_set_t single;
    CPU_ZERO(&single);
    CPU_SET(first, &single);
    restricted = ::sched_setaffinity(0, sizeof(single), &single) == 0;
    one = cslam::usable_cores();
  }).join();
  EXPECT_GE(all, 1);
  EXPECT_LE(all, int(std::max(1u, std::thread::hardware_concurrency())));
  ASSERT_TRUE(restricted);
  EXPECT_EQ(one, 1);
}
