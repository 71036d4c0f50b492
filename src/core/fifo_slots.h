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
      if (owner_ && held_) owner_->release();
    }
    Hold(const Hold&) = delete;
    Hold& operator=(const Hold&) = delete;

    // While the holder waits for another thread's work, its slot serves the next waiter; taking it
    // back goes before every thread that has not held a slot yet (its frame is half done).
    void lend() {
      if (owner_ && held_) owner_->release();
      held_ = false;
    }
    void take_back() {
      if (owner_ && !held_) owner_->acquire_returning();
      held_ = true;
    }

   private:
    FifoSlots* owner_;
    bool held_ = true;
  };

  // Threads waiting for a slot now (new tickets and returning lenders).
  std::size_t waiting() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return std::size_t(next_ticket_ - serving_) + std::size_t(returning_);
  }

 private:
  void acquire() {
    std::unique_lock<std::mutex> lock(mutex_);
    const std::uint64_t ticket = next_ticket_++;
    cv_.wait(lock, [&] { return ticket == serving_ && free_ > 0 && returning_ == 0; });
    --free_;
    ++serving_;
    lock.unlock();
    cv_.notify_all();  // the next ticket may find a free slot too
  }
  void acquire_returning() {
    std::unique_lock<std::mutex> lock(mutex_);
    ++returning_;
    cv_.wait(lock, [&] { return free_ > 0; });
    --free_;
    --returning_;
    lock.unlock();
    cv_.notify_all();
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
  int returning_ = 0;  // lent slots being taken back: served before new tickets
  std::uint64_t next_ticket_ = 0, serving_ = 0;
};

}  // namespace cslam
