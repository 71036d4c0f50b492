#pragma once
// Waking the receiving thread's poll loop from other threads or from a signal handler:
//  - WakePipe: a non-blocking self-pipe; notify() is async-signal-safe; the read end is polled.
//  - DoneChannel: FrameDone reports from SLAM worker threads (frame consumed -> ack with its pose
//    and a credit back),
//    a mutex-guarded list plus a WakePipe. No ZeroMQ socket is shared between threads.
#include <mutex>
#include <utility>
#include <vector>

#include "system/system_config.h"

namespace cslam::server {

class WakePipe {
 public:
  WakePipe();  // throws std::system_error
  ~WakePipe();
  WakePipe(const WakePipe&) = delete;
  WakePipe& operator=(const WakePipe&) = delete;

  void notify() noexcept;  // async-signal-safe
  void clear() noexcept;   // drains the pipe (receiving thread)
  int read_fd() const { return fds_[0]; }

 private:
  int fds_[2] = {-1, -1};
};

class DoneChannel {
 public:
  void push(const FrameDone& done);
  std::vector<FrameDone> drain();
  int read_fd() const { return pipe_.read_fd(); }

 private:
  WakePipe pipe_;
  std::mutex mutex_;
  std::vector<FrameDone> items_;
};

}  // namespace cslam::server
