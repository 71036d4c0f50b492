#pragma once
// One thread running queued tasks in order (e.g. reclaiming an idle client's SLAM pipeline, which
// joins its threads and writes files: too slow for the receiving thread). The queue is bounded;
// the destructor runs what is queued and joins.
#include <condition_variable>
#include <deque>
#include <functional>
#include <mutex>
#include <string>
#include <thread>
#include <utility>

#include "core/thread_priority.h"

namespace cslam::server {

class BackgroundWorker {
 public:
  // `name`: the thread's name (name_current_thread).
  explicit BackgroundWorker(std::string name, std::size_t capacity = 1024)
      : name_(std::move(name)), capacity_(capacity), thread_([this] { run(); }) {}
  ~BackgroundWorker() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    wake_.notify_all();
    thread_.join();
  }
  BackgroundWorker(const BackgroundWorker&) = delete;
  BackgroundWorker& operator=(const BackgroundWorker&) = delete;

  // False if the queue is full or the worker is stopping.
  bool post(std::function<void()> task) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (stop_ || tasks_.size() >= capacity_) return false;
      tasks_.push_back(std::move(task));
    }
    wake_.notify_one();
    return true;
  }

 private:
  void run() {
    name_current_thread(name_);
    std::unique_lock<std::mutex> lock(mutex_);
    for (;;) {
      wake_.wait(lock, [this] { return stop_ || !tasks_.empty(); });
      if (tasks_.empty()) return;  // stopping
      auto task = std::move(tasks_.front());
      tasks_.pop_front();
      lock.unlock();
      task();
      lock.lock();
    }
  }

  const std::string name_;
  const std::size_t capacity_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<std::function<void()>> tasks_;
  bool stop_ = false;
  std::thread thread_;
};

}  // namespace cslam::server
