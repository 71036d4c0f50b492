#pragma once
// A fixed number of slots handed out in arrival order: at most `slots` holders at a time, and a
// waiter is served before everyone who arrived after it. The client workers share one so that,
// on a machine with fewer cores than robots, frames are tracked one after another at full speed
// instead of all at once at a fraction of it (which stretches every frame's latency).
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <mutex>

namespace cslam {

class FifoSlots {
 public:
  explicit FifoSlots(int slots) : free_(slots) {}
  FifoSlots(const FifoSlots&) = delete;
  FifoSlots& operator=(const FifoSlots&) = delete;

  // Holds a slot until destroyed.
  class Hold {
   public:
    explicit Hold(FifoSlots* owner) : owner_(owner) {
      if (owner_) owner_->acquire();
    }
    ~Hold() {
      if (owner_) owner_->release();
    }
    Hold(const Hold&) = delete;
    Hold& operator=(const Hold&) = delete;

   private:
    FifoSlots* owner_;
  };

  // Threads waiting for a slot now.
  std::size_t waiting() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return std::size_t(next_ticket_ - serving_);
  }

 private:
  void acquire() {
    std::unique_lock<std::mutex> lock(mutex_);
    const std::uint64_t ticket = next_ticket_++;
    cv_.wait(lock, [&] { return ticket == serving_ && free_ > 0; });
    --free_;
    ++serving_;
    lock.unlock();
    cv_.notify_all();  // the next ticket may find a free slot too
  }
  void release() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      ++free_;
    }
    cv_.notify_all();
  }

  mutable std::mutex mutex_;
  std::condition_variable cv_;
  int free_;
  std::uint64_t next_ticket_ = 0, serving_ = 0;
};

}  // namespace cslam
