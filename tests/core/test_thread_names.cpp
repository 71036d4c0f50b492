// Threads named after their stage: name_current_thread and QueueWorker's consumer thread.
#include <pthread.h>

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
