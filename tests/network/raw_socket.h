#pragma once
// Writing raw bytes to a socket in tests (no SIGPIPE if the peer has closed).
#include <sys/socket.h>
#include <sys/types.h>

#include <string>

namespace cslam::test {

inline bool send_all(int fd, const std::string& s) {
  std::size_t off = 0;
  while (off < s.size()) {
    const ssize_t n = ::send(fd, s.data() + off, s.size() - off, MSG_NOSIGNAL);
    if (n <= 0) return false;
    off += std::size_t(n);
  }
  return true;
}

}  // namespace cslam::test
