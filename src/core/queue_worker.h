#pragma once
// One consumer of a FIFO work queue: a step function applied to each item in order, either on an
// own thread of lowered priority (threaded) or on the caller's thread through step() (stepped,
// e.g. --sync runs and tests). Local mapping and loop closing each run one over their keyframes.
//
// The queue mutex also guards the consumer's progress: done() counts the items whose step
// returned, and an owner may keep further milestones with update(), so that producers wait for
// the consumer (wait_until, push_waiting) under one lock. stop() wakes every waiter; the thread
// drains the queue before it ends and is joined (never detached).
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <mutex>
#include <string>
#include <thread>
#include <utility>

#include "core/thread_priority.h"

namespace cslam {

template <typename Item>
class QueueWorker {
 public:
  using Step = std::function<void(const Item&)>;

  // `name`: the thread's name (name_current_thread), e.g. "mapping/c3".
  QueueWorker(bool threaded, std::string name, Step step)
      : threaded_(threaded), name_(std::move(name)), step_(std::move(step)) {}
  QueueWorker(const QueueWorker&) = delete;
  QueueWorker& operator=(const QueueWorker&) = delete;
  // Owners call stop() first (their step function uses their members); this only ends the thread.
  ~QueueWorker() {
    request_stop();
    if (thread_.joinable()) thread_.join();
  }

  // Starts the consumer thread in threaded mode (call once the owner is fully constructed).
  void start() {
    if (threaded_) thread_ = std::thread([this] { run(); });
  }
  bool threaded() const { return threaded_; }

  // Queues `item` unless stop was requested (then false). When `capacity` items are waiting, the
  // oldest is dropped first.
  bool push(const Item& item, std::size_t capacity) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (stop_) return false;
      if (queue_.size() >= capacity && !queue_.empty()) queue_.pop_front();
      queue_.push_back(item);
      ++pushed_;
    }
    queue_cv_.notify_one();
    return true;
  }

  // Queues `item`, also after stop. Threaded mode: first waits while `max_pending` items are
  // queued or in work (or until stop). Returns the item's number (1 for the first pushed), which
  // done() reaches when its step has returned.
  std::uint64_t push_waiting(const Item& item, std::size_t max_pending) {
    std::uint64_t n = 0;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      if (threaded_) progress_cv_.wait(lock, [&] { return stop_ || pushed_ - done_ < max_pending; });
      queue_.push_back(item);
      n = ++pushed_;
    }
    queue_cv_.notify_one();
    return n;
  }

  std::size_t queued() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return queue_.size();
  }

  // Processes one queued item on the calling thread. False if none was queued.
  bool step() {
    Item item;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (queue_.empty()) return false;
      item = std::move(queue_.front());
      queue_.pop_front();
    }
    process(item);
    return true;
  }

  // Requests stop and wakes every waiter; threaded: joins the thread once it drained the queue;
  // stepped: processes what is queued on the calling thread. Idempotent.
  void stop() {
    request_stop();
    if (thread_.joinable()) thread_.join();
    if (!threaded_)
      while (step()) {
      }
  }

  // Runs f() under the queue mutex (e.g. advancing an owner's progress counter), then wakes the
  // waiters of wait_until and push_waiting.
  template <typename F>
  void update(F&& f) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      f();
    }
    progress_cv_.notify_all();
  }

  // Blocks until pred() holds (evaluated under the queue mutex) or stop was requested.
  template <typename Pred>
  void wait_until(Pred&& pred) {
    std::unique_lock<std::mutex> lock(mutex_);
    progress_cv_.wait(lock, [&] { return stop_ || pred(); });
  }

  // Items whose step returned; read it under the queue mutex (inside update or wait_until).
  std::uint64_t done() const { return done_; }

 private:
  void request_stop() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    queue_cv_.notify_all();
    progress_cv_.notify_all();
  }

  void process(const Item& item) {
    step_(item);
    update([&] { ++done_; });
  }

  void run() {
    name_current_thread(name_);
    lower_current_thread_priority();
    for (;;) {
      Item item;
      {
        std::unique_lock<std::mutex> lock(mutex_);
        queue_cv_.wait(lock, [&] { return stop_ || !queue_.empty(); });
        if (queue_.empty()) return;  // stop requested and drained
        item = std::move(queue_.front());
        queue_.pop_front();
      }
      process(item);
    }
  }

  const bool threaded_;
  const std::string name_;
  const Step step_;
  mutable std::mutex mutex_;
  std::condition_variable queue_cv_, progress_cv_;
  std::deque<Item> queue_;
  std::uint64_t pushed_ = 0, done_ = 0;
  bool stop_ = false;
  std::thread thread_;
};

}  // namespace cslam
