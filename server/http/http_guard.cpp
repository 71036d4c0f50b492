#include "server/http/http_guard.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>

#include "core/log.h"
#include "server/http/json_reply.h"  // httplib.h (after every Eigen include)

namespace cslam::http {

namespace {

using Clock = std::chrono::steady_clock;

// httplib::Server::process_request is protected: reached through a derived class's member pointer.
struct ProcessAccess : httplib::Server {
  static bool process(httplib::Server& s, httplib::Stream& strm, bool close, bool& closed,
                      const std::function<void(httplib::Request&)>& setup) {
    return (s.*(&ProcessAccess::process_request))(strm, close, closed, setup);
  }
};

void set_nonblocking(int fd, bool on) {
  const int flags = fcntl(fd, F_GETFL, 0);
  fcntl(fd, F_SETFL, on ? (flags | O_NONBLOCK) : (flags & ~O_NONBLOCK));
}

// Writes everything within the deadline (poll for writability); false on error or timeout.
bool write_all(int fd, const char* p, std::size_t n, Clock::time_point deadline) {
  while (n > 0) {
    const ssize_t w = ::send(fd, p, n, MSG_NOSIGNAL | MSG_DONTWAIT);
    if (w > 0) {
      p += w;
      n -= std::size_t(w);
      continue;
    }
    if (w < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR) return false;
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
    if (left <= 0) return false;
    pollfd pfd{fd, POLLOUT, 0};
    if (::poll(&pfd, 1, int(left)) < 0 && errno != EINTR) return false;
  }
  return true;
}

// The request as httplib reads it (from memory), the response straight to the socket.
class BufferedStream : public httplib::Stream {
 public:
  BufferedStream(int fd, std::string request, std::string ip, int port, double write_timeout_s)
      : fd_(fd), in_(std::move(request)), ip_(std::move(ip)), port_(port), write_timeout_s_(write_timeout_s) {}
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
    const auto deadline = Clock::now() + std::chrono::milliseconds(long(write_timeout_s_ * 1000));
    if (!write_all(fd_, ptr, size, deadline)) {
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
  socket_t socket() const override { return fd_; }
  bool failed() const { return failed_; }

 private:
  int fd_;
  std::string in_;
  std::size_t pos_ = 0;
  std::string ip_;
  int port_;
  double write_timeout_s_;
  bool failed_ = false;
};

std::string lower(std::string s) {
  for (char& c : s) c = char(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t");
  if (b == std::string::npos) return "";
  return s.substr(b, s.find_last_not_of(" \t\r") - b + 1);
}

enum class Parse { kIncomplete, kComplete, kHeaderTooLarge, kBodyTooLarge, kBad };

struct Parsed {
  std::string request;  // normalised: request line, headers, Content-Length, body
  std::size_t consumed = 0;
  bool close = false;   // the client asked for Connection: close (or HTTP/1.0 without keep-alive)
  bool expect_continue = false;
};

// Decodes a chunked body starting at `pos`; kIncomplete until the last chunk and trailers arrived.
Parse decode_chunked(const std::string& buf, std::size_t pos, std::size_t max_body, std::string* body, std::size_t* end) {
  body->clear();
  for (;;) {
    const auto eol = buf.find("\r\n", pos);
    if (eol == std::string::npos) return buf.size() - pos > 64 ? Parse::kBad : Parse::kIncomplete;
    std::string size_text = buf.substr(pos, eol - pos);
    if (const auto semi = size_text.find(';'); semi != std::string::npos) size_text.resize(semi);
    size_text = trim(size_text);
    if (size_text.empty() || size_text.size() > 8 || size_text.find_first_not_of("0123456789abcdefABCDEF") != std::string::npos)
      return Parse::kBad;
    const std::size_t n = std::stoul(size_text, nullptr, 16);
    if (body->size() + n > max_body) return Parse::kBodyTooLarge;
    pos = eol + 2;
    if (n == 0) {  // trailers until an empty line
      for (;;) {
        const auto t = buf.find("\r\n", pos);
        if (t == std::string::npos) return buf.size() - pos > 8192 ? Parse::kBad : Parse::kIncomplete;
        if (t == pos) {
          *end = t + 2;
          return Parse::kComplete;
        }
        pos = t + 2;
      }
    }
    if (buf.size() < pos + n + 2) return Parse::kIncomplete;
    if (buf.compare(pos + n, 2, "\r\n") != 0) return Parse::kBad;
    body->append(buf, pos, n);
    pos += n + 2;
  }
}

Parse parse_request(const std::string& buf, const GuardConfig& cfg, Parsed* out) {
  std::size_t header_end = buf.find("\r\n\r\n");
  if (header_end == std::string::npos) {
    if (buf.size() > cfg.max_header_bytes) return Parse::kHeaderTooLarge;
    std::size_t lines = std::count(buf.begin(), buf.end(), '\n');
    return lines > cfg.max_header_count + 1 ? Parse::kHeaderTooLarge : Parse::kIncomplete;
  }
  if (header_end + 4 > cfg.max_header_bytes) return Parse::kHeaderTooLarge;
  std::vector<std::string> lines;
  for (std::size_t pos = 0; pos < header_end;) {
    const auto eol = buf.find("\r\n", pos);
    lines.push_back(buf.substr(pos, eol - pos));
    pos = eol + 2;
  }
  if (lines.empty() || lines.size() - 1 > cfg.max_header_count) return Parse::kHeaderTooLarge;
  const std::string& request_line = lines[0];
  if (request_line.find(' ') == std::string::npos) return Parse::kBad;
  const bool http10 = request_line.size() >= 8 && request_line.compare(request_line.size() - 8, 8, "HTTP/1.0") == 0;
  std::string normalised = request_line + "\r\n";
  long long content_length = -1;
  bool chunked = false, keep_alive_10 = false;
  out->close = http10;
  out->expect_continue = false;
  for (std::size_t i = 1; i < lines.size(); ++i) {
    const auto colon = lines[i].find(':');
    if (colon == std::string::npos || colon == 0) return Parse::kBad;
    const std::string name = lower(trim(lines[i].substr(0, colon))), value = trim(lines[i].substr(colon + 1));
    if (name == "content-length") {
      if (value.empty() || value.size() > 18 || value.find_first_not_of("0123456789") != std::string::npos) return Parse::kBad;
      const long long v = std::stoll(value);
      if (content_length >= 0 && v != content_length) return Parse::kBad;
      content_length = v;
      continue;
    }
    if (name == "transfer-encoding") {
      if (lower(value) != "chunked") return Parse::kBad;  // nothing else is accepted
      chunked = true;
      continue;
    }
    if (name == "expect") {
      out->expect_continue = lower(value) == "100-continue";
      continue;  // the guard answers it; httplib must not
    }
    if (name == "connection") {
      const std::string v = lower(value);
      if (v.find("close") != std::string::npos) out->close = true;
      if (v.find("keep-alive") != std::string::npos) keep_alive_10 = true;
    }
    normalised += lines[i] + "\r\n";
  }
  if (http10 && keep_alive_10) out->close = false;
  if (chunked && content_length >= 0) return Parse::kBad;  // request smuggling shape
  const std::size_t body_start = header_end + 4;
  std::string body;
  std::size_t end = body_start;
  if (chunked) {
    const Parse p = decode_chunked(buf, body_start, cfg.max_body_bytes, &body, &end);
    if (p != Parse::kComplete) return p;
  } else if (content_length > 0) {
    if (std::size_t(content_length) > cfg.max_body_bytes) return Parse::kBodyTooLarge;
    if (buf.size() < body_start + std::size_t(content_length)) return Parse::kIncomplete;
    body = buf.substr(body_start, std::size_t(content_length));
    end = body_start + std::size_t(content_length);
  }
  if (chunked || content_length >= 0) normalised += "Content-Length: " + std::to_string(body.size()) + "\r\n";
  normalised += "\r\n";
  normalised += body;
  out->request = std::move(normalised);
  out->consumed = end;
  return Parse::kComplete;
}

}  // namespace

struct HttpGuard::Connection {
  int fd = -1;
  std::string ip;
  int port = 0;
  std::string buffer;
  Clock::time_point request_start;  // first byte of the current request (deadline)
  Clock::time_point idle_since;     // end of the last response / accept
  bool in_request = false;          // bytes of a request have arrived
  bool continue_sent = false;
  std::size_t served = 0;
};

struct HttpGuard::Job {
  std::unique_ptr<Connection> connection;
  std::string request;
  bool close = false;
};

HttpGuard::HttpGuard(httplib::Server& server, GuardConfig config) : server_(server), config_(std::move(config)) {
  if (::pipe(wake_) != 0) throw std::system_error(errno, std::generic_category(), "pipe");
  set_nonblocking(wake_[0], true);
  set_nonblocking(wake_[1], true);
}

HttpGuard::~HttpGuard() {
  stop();
  for (int fd : wake_)
    if (fd >= 0) ::close(fd);
  if (listen_fd_ >= 0) ::close(listen_fd_);
}

int HttpGuard::bind(const std::string& host, int port) {
  addrinfo hints{}, *res = nullptr;
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  hints.ai_flags = AI_PASSIVE;
  const std::string service = std::to_string(port);
  if (::getaddrinfo(host.empty() ? nullptr : host.c_str(), service.c_str(), &hints, &res) != 0 || !res) return -1;
  int bound = -1;
  for (addrinfo* ai = res; ai && bound < 0; ai = ai->ai_next) {
    const int fd = ::socket(ai->ai_family, ai->ai_socktype | SOCK_CLOEXEC, ai->ai_protocol);
    if (fd < 0) continue;
    const int yes = 1;
    ::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
    if (::bind(fd, ai->ai_addr, ai->ai_addrlen) != 0 || ::listen(fd, 128) != 0) {
      ::close(fd);
      continue;
    }
    sockaddr_storage addr{};
    socklen_t len = sizeof addr;
    ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len);
    bound = addr.ss_family == AF_INET ? ntohs(reinterpret_cast<sockaddr_in*>(&addr)->sin_port)
                                      : ntohs(reinterpret_cast<sockaddr_in6*>(&addr)->sin6_port);
    set_nonblocking(fd, true);
    listen_fd_ = fd;
  }
  ::freeaddrinfo(res);
  return bound;
}

void HttpGuard::start() {
  if (listen_fd_ < 0 || loop_thread_.joinable()) return;
  for (std::size_t i = 0; i < std::max<std::size_t>(1, config_.workers); ++i) workers_.emplace_back([this] { worker(); });
  loop_thread_ = std::thread([this] { loop(); });
}

void HttpGuard::stop() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (stop_) return;
    stop_ = true;
  }
  const char c = 's';
  [[maybe_unused]] const ssize_t n = ::write(wake_[1], &c, 1);
  jobs_cv_.notify_all();
  if (loop_thread_.joinable()) loop_thread_.join();
  for (std::thread& t : workers_)
    if (t.joinable()) t.join();
  for (auto& [fd, c] : connections_) ::close(fd);
  connections_.clear();
  for (auto& c : returned_) ::close(c->fd);
  returned_.clear();
  for (auto& j : jobs_) ::close(j->connection->fd);
  jobs_.clear();
}

void HttpGuard::close_connection(int fd) {
  ::close(fd);
  connections_.erase(fd);
}

void HttpGuard::reply_and_close(Connection& c, int status, const char* text) {
  const std::string body = std::string("{\"error\":\"") + text + "\"}";
  const std::string response = "HTTP/1.1 " + std::to_string(status) + " " + text +
                               "\r\nContent-Type: application/json\r\nConnection: close\r\nContent-Length: " +
                               std::to_string(body.size()) + "\r\n\r\n" + body;
  // Best effort, never blocks the event loop.
  [[maybe_unused]] const ssize_t n = ::send(c.fd, response.data(), response.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
  close_connection(c.fd);
}

void HttpGuard::accept_all() {
  for (;;) {
    sockaddr_storage addr{};
    socklen_t len = sizeof addr;
    const int fd = ::accept4(listen_fd_, reinterpret_cast<sockaddr*>(&addr), &len, SOCK_NONBLOCK | SOCK_CLOEXEC);
    if (fd < 0) return;
    ++stats_.accepted;
    auto c = std::make_unique<Connection>();
    c->fd = fd;
    char ip[INET6_ADDRSTRLEN] = "";
    if (addr.ss_family == AF_INET) {
      inet_ntop(AF_INET, &reinterpret_cast<sockaddr_in*>(&addr)->sin_addr, ip, sizeof ip);
      c->port = ntohs(reinterpret_cast<sockaddr_in*>(&addr)->sin_port);
    } else if (addr.ss_family == AF_INET6) {
      inet_ntop(AF_INET6, &reinterpret_cast<sockaddr_in6*>(&addr)->sin6_addr, ip, sizeof ip);
      c->port = ntohs(reinterpret_cast<sockaddr_in6*>(&addr)->sin6_port);
    }
    c->ip = ip;
    c->idle_since = Clock::now();
    const int yes = 1;
    ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &yes, sizeof yes);
    Connection& ref = *c;
    connections_[fd] = std::move(c);
    if (connections_.size() > config_.max_connections) {
      ++stats_.connections_refused;
      reply_and_close(ref, 503, "Service Unavailable");
    }
  }
}

bool HttpGuard::on_readable(Connection& c) {
  char buf[16384];
  for (;;) {
    const ssize_t n = ::recv(c.fd, buf, sizeof buf, 0);
    if (n > 0) {
      if (!c.in_request) {
        c.in_request = true;
        c.request_start = Clock::now();
      }
      c.buffer.append(buf, std::size_t(n));
      // Never hold more than one request's worth (plus a little pipelining).
      if (c.buffer.size() > config_.max_header_bytes + config_.max_body_bytes * 3 + 65536) break;
      continue;
    }
    if (n == 0) return false;  // peer closed
    if (errno == EAGAIN || errno == EWOULDBLOCK) break;
    if (errno == EINTR) continue;
    return false;
  }
  return try_dispatch(c);
}

bool HttpGuard::try_dispatch(Connection& c) {
  if (c.buffer.empty()) return true;
  Parsed parsed;
  switch (parse_request(c.buffer, config_, &parsed)) {
    case Parse::kIncomplete:
      if (!c.continue_sent && c.buffer.find("\r\n\r\n") != std::string::npos &&
          lower(c.buffer.substr(0, c.buffer.find("\r\n\r\n"))).find("expect: 100-continue") != std::string::npos) {
        c.continue_sent = true;
        static const char kContinue[] = "HTTP/1.1 100 Continue\r\n\r\n";
        [[maybe_unused]] const ssize_t n = ::send(c.fd, kContinue, sizeof kContinue - 1, MSG_NOSIGNAL | MSG_DONTWAIT);
      }
      return true;
    case Parse::kHeaderTooLarge:
      ++stats_.header_too_large;
      reply_and_close(c, 431, "Request Header Fields Too Large");
      return true;  // already closed
    case Parse::kBodyTooLarge:
      ++stats_.body_too_large;
      reply_and_close(c, 413, "Payload Too Large");
      return true;
    case Parse::kBad:
      ++stats_.bad_request;
      reply_and_close(c, 400, "Bad Request");
      return true;
    case Parse::kComplete: break;
  }
  auto job = std::make_unique<Job>();
  job->request = std::move(parsed.request);
  c.buffer.erase(0, parsed.consumed);
  ++c.served;
  job->close = parsed.close || c.served >= config_.keep_alive_max_requests;
  c.in_request = false;
  c.continue_sent = false;
  const int fd = c.fd;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (jobs_.size() >= config_.queue_capacity) {
      ++stats_.overloaded;
      reply_and_close(c, 503, "Service Unavailable");
      return true;
    }
    job->connection = std::move(connections_.at(fd));
    jobs_.push_back(std::move(job));
  }
  connections_.erase(fd);
  ++stats_.requests;
  jobs_cv_.notify_one();
  return true;
}

void HttpGuard::loop() {
  auto log = logger("http");
  for (;;) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (stop_) return;
      for (auto& c : returned_) {
        c->idle_since = Clock::now();
        const int fd = c->fd;
        connections_[fd] = std::move(c);
      }
      returned_.clear();
    }
    // Requests already buffered (pipelined) behind a returned connection.
    std::vector<int> pending;
    for (auto& [fd, c] : connections_)
      if (!c->buffer.empty() && !c->in_request) pending.push_back(fd);
    for (int fd : pending) {
      auto it = connections_.find(fd);
      if (it == connections_.end()) continue;
      it->second->in_request = true;
      it->second->request_start = Clock::now();
      try_dispatch(*it->second);
    }
    std::vector<pollfd> fds;
    fds.push_back({wake_[0], POLLIN, 0});
    fds.push_back({listen_fd_, POLLIN, 0});
    for (const auto& [fd, c] : connections_) fds.push_back({fd, POLLIN, 0});
    // Wake up at the nearest deadline.
    const auto now = Clock::now();
    auto next = now + std::chrono::seconds(1);
    for (const auto& [fd, c] : connections_) {
      const auto deadline = c->in_request ? c->request_start + std::chrono::milliseconds(long(config_.request_deadline_s * 1000))
                                          : c->idle_since + std::chrono::milliseconds(long(config_.keep_alive_idle_s * 1000));
      next = std::min(next, deadline);
    }
    const int timeout = int(std::max<long>(0, std::chrono::duration_cast<std::chrono::milliseconds>(next - now).count() + 1));
    if (::poll(fds.data(), fds.size(), timeout) < 0 && errno != EINTR) {
      log->error("HTTP guard: poll failed: {}", std::strerror(errno));
      return;
    }
    if (fds[0].revents & POLLIN) {
      char drain[64];
      while (::read(wake_[0], drain, sizeof drain) > 0) {
      }
    }
    if (fds[1].revents & POLLIN) accept_all();
    for (std::size_t i = 2; i < fds.size(); ++i) {
      if (!fds[i].revents) continue;
      auto it = connections_.find(fds[i].fd);
      if (it == connections_.end()) continue;
      if (!on_readable(*it->second)) close_connection(fds[i].fd);
    }
    // Deadlines: a request not complete in time gets 408; an idle keep-alive connection is closed.
    const auto t = Clock::now();
    std::vector<int> expired_request, expired_idle;
    for (const auto& [fd, c] : connections_) {
      if (c->in_request && t - c->request_start > std::chrono::milliseconds(long(config_.request_deadline_s * 1000)))
        expired_request.push_back(fd);
      else if (!c->in_request && t - c->idle_since > std::chrono::milliseconds(long(config_.keep_alive_idle_s * 1000)))
        expired_idle.push_back(fd);
    }
    for (int fd : expired_request) {
      ++stats_.timed_out;
      reply_and_close(*connections_.at(fd), 408, "Request Timeout");
    }
    for (int fd : expired_idle) close_connection(fd);
  }
}

void HttpGuard::worker() {
  for (;;) {
    std::unique_ptr<Job> job;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      jobs_cv_.wait(lock, [this] { return stop_ || !jobs_.empty(); });
      if (stop_) return;
      job = std::move(jobs_.front());
      jobs_.pop_front();
    }
    Connection& c = *job->connection;
    BufferedStream stream(c.fd, std::move(job->request), c.ip, c.port, config_.write_timeout_s);
    bool closed = false;
    const std::string ip = c.ip;
    const int port = c.port;
    try {
      ProcessAccess::process(server_, stream, job->close, closed, [&](httplib::Request& req) {
        req.remote_addr = ip;
        req.remote_port = port;
        req.set_header("REMOTE_ADDR", ip);
        req.set_header("REMOTE_PORT", std::to_string(port));
      });
    } catch (const std::exception& e) {
      logger("http")->warn("HTTP request failed: {}", e.what());
      closed = true;
    }
    if (job->close || closed || stream.failed()) {
      ::close(c.fd);
      continue;
    }
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (stop_) {
        ::close(c.fd);
        continue;
      }
      returned_.push_back(std::move(job->connection));
    }
    const char w = 'r';
    [[maybe_unused]] const ssize_t n = ::write(wake_[1], &w, 1);
  }
}

}  // namespace cslam::http
