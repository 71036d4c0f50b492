#include "server/wake_pipe.h"

#include <cerrno>
#include <fcntl.h>
#include <system_error>
#include <unistd.h>

namespace cslam::server {

WakePipe::WakePipe() {
  if (::pipe(fds_) != 0) throw std::system_error(errno, std::generic_category(), "pipe");
  for (int fd : fds_) {
    ::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) | O_NONBLOCK);
    ::fcntl(fd, F_SETFD, FD_CLOEXEC);
  }
}

WakePipe::~WakePipe() {
  for (int fd : fds_)
    if (fd >= 0) ::close(fd);
}

void WakePipe::notify() noexcept {
  const char byte = 1;
  // A full pipe already wakes the reader: EAGAIN is fine.
  [[maybe_unused]] ssize_t n = ::write(fds_[1], &byte, 1);
}

void WakePipe::clear() noexcept {
  char buf[256];
  while (::read(fds_[0], buf, sizeof buf) > 0) {
  }
}

void DoneChannel::push(const FrameDone& done) {
  bool was_empty;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    was_empty = items_.empty();
    items_.push_back(done);
  }
  if (was_empty) pipe_.notify();
}

std::vector<FrameDone> DoneChannel::drain() {
  pipe_.clear();
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<FrameDone> out;
  out.swap(items_);
  return out;
}

}  // namespace cslam::server
