#pragma once
// The stream a guard worker hands to RequestRouter::route (server/http/request_router.h): the
// request is read from memory (the event loop already read and normalised it), the response is
// written through the connection's Channel (plain or TLS), each write within the write timeout.
// httplib::Stream is cpp-httplib's public interface for this.
#include <algorithm>
#include <chrono>
#include <cstring>
#include <string>

#include "server/http/tls_channel.h"
#include <httplib.h>  // after every Eigen include

namespace cslam::http {

class BufferedStream : public httplib::Stream {
 public:
  BufferedStream(Channel& channel, std::string request, std::string ip, int port, double write_timeout_s)
      : channel_(channel),
        in_(std::move(request)),
        ip_(std::move(ip)),
        port_(port),
        write_timeout_s_(write_timeout_s) {}
  bool is_readable() const override { return pos_ < in_.size(); }
  bool is_writable() const override { return !failed_; }
  ssize_t read(char* ptr, size_t size) override {
    const std::size_t n = std::min(size, in_.size() - pos_);
    std::memcpy(ptr, in_.data() + pos_, n);
    pos_ += n;
    return ssize_t(n);
  }
  ssize_t write(const char* ptr, size_t size) override {
    if (failed_) return -1;
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(long(write_timeout_s_ * 1000));
    if (!write_all(channel_, ptr, size, deadline)) {
      failed_ = true;
      return -1;
    }
    return ssize_t(size);
  }
  void get_remote_ip_and_port(std::string& ip, int& port) const override {
    ip = ip_;
    port = port_;
  }
  void get_local_ip_and_port(std::string& ip, int& port) const override {
    ip = "";
    port = 0;
  }
  socket_t socket() const override { return channel_.fd(); }
  bool failed() const { return failed_; }

 private:
  Channel& channel_;
  std::string in_;
  std::size_t pos_ = 0;
  std::string ip_;
  int port_;
  double write_timeout_s_;
  bool failed_ = false;
};

}  // namespace cslam::http
