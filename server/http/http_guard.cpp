#include "server/http/http_guard.h"

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
#include "core/thread_priority.h"
#include "server/http/guard_socket.h"
#include "server/http/guard_stream.h"  // httplib.h (after every Eigen include)
#include "server/http/http_request_parse.h"
#include "server/http/request_router.h"
#include "server/http/tls_context.h"

namespace cslam::http {

namespace {

using Clock = std::chrono::steady_clock;

std::chrono::milliseconds ms(double seconds) { return std::chrono::milliseconds(long(seconds * 1000)); }

bool expects_continue(const std::string& buffer) {
  const std::size_t end = buffer.find("\r\n\r\n");
  return end != std::string::npos && lower(buffer.substr(0, end)).find("expect: 100-continue") != std::string::npos;
}

std::string error_response(int status, const char* text, const char* message) {
  const std::string body = std::string("{\"error\":\"") + message + "\"}";
  return "HTTP/1.1 " + std::to_string(status) + " " + text +
         "\r\nContent-Type: application/json\r\nConnection: close\r\nContent-Length: " + std::to_string(body.size()) +
         "\r\n\r\n" + body;
}

}  // namespace

struct HttpGuard::Connection {
  std::unique_ptr<Channel> channel;  // owns the socket (and the TLS state)
  std::string ip;
  int port = 0;
  std::string buffer;
  Clock::time_point request_start;  // first byte of the current request, or accept under TLS (deadline)
  Clock::time_point idle_since;     // end of the last response / accept
  bool in_request = false;          // bytes of a request (or a TLS handshake) have arrived
  bool continue_sent = false;
  bool want_write = false;  // TLS wants the socket writable before it can go on
  std::size_t served = 0;
  int fd() const { return channel->fd(); }
};

struct HttpGuard::Job {
  std::unique_ptr<Connection> connection;
  std::string request;
  bool close = false;
};

HttpGuard::HttpGuard(RequestRouter& router, GuardConfig config, const TlsContext* tls)
    : router_(router), config_(std::move(config)), tls_(tls) {
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

int HttpGuard::bind(const std::string& host, int port) { return listen_socket(host, port, &listen_fd_); }

void HttpGuard::start() {
  if (listen_fd_ < 0 || loop_thread_.joinable()) return;
  for (std::size_t i = 0; i < std::max<std::size_t>(1, config_.workers); ++i)
    workers_.emplace_back([this] { worker(); });
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
  // Every thread has ended: the connections (and their sockets) are closed here.
  connections_.clear();
  returned_.clear();
  jobs_.clear();
}

void HttpGuard::close_connection(int fd) { connections_.erase(fd); }

void HttpGuard::reply_and_close(Connection& c, int status, const char* text) {
  // Best effort, never blocks the event loop; nothing under TLS before the handshake finished.
  c.channel->send_once(error_response(status, text, text));
  close_connection(c.fd());
}

void HttpGuard::accept_all() {
  for (;;) {
    std::string ip;
    int port = 0;
    const int fd = accept_connection(listen_fd_, &ip, &port);
    if (fd < 0) return;
    ++stats_.accepted;
    adopt(fd, ip, port);
  }
}

void HttpGuard::adopt(int fd, const std::string& ip, int port) {
  auto c = std::make_unique<Connection>();
  c->channel = std::make_unique<Channel>(fd, tls_ ? tls_->get() : nullptr);
  c->ip = ip;
  c->port = port;
  c->idle_since = Clock::now();
  if (c->channel->tls()) {  // the handshake counts against the first request's deadline
    c->in_request = true;
    c->request_start = c->idle_since;
  }
  const int yes = 1;
  ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &yes, sizeof yes);
  Connection& ref = *c;
  connections_[fd] = std::move(c);
  if (connections_.size() > config_.max_connections) {
    ++stats_.connections_refused;
    reply_and_close(ref, 503, "Service Unavailable");  // under TLS: closed without a word
  }
}

bool HttpGuard::on_handshake(Connection& c) {
  const Io io = c.channel->handshake();
  c.want_write = io == Io::kWantWrite;
  if (io == Io::kDone || io == Io::kWantRead || io == Io::kWantWrite) return true;
  if (c.channel->plain_http()) {
    ++stats_.plain_http_on_tls;
    c.channel->send_raw_once(error_response(400, "Bad Request", "this port speaks HTTPS: use https://"));
  } else {
    ++stats_.tls_handshake_failed;
  }
  return false;
}

bool HttpGuard::on_readable(Connection& c) {
  if (!c.channel->ready()) {
    if (!on_handshake(c)) return false;    // failed: close
    if (!c.channel->ready()) return true;  // waiting for the peer
  }
  char buf[16384];
  for (;;) {
    std::size_t n = 0;
    const Io io = c.channel->read(buf, sizeof buf, &n);
    c.want_write = io == Io::kWantWrite;
    if (io == Io::kWantRead || io == Io::kWantWrite) break;
    if (io == Io::kClosed && !c.buffer.empty()) return answer_then_close(c);
    if (io != Io::kDone) return false;  // peer closed, or an error
    if (!c.in_request) {
      c.in_request = true;
      c.request_start = Clock::now();
    }
    c.buffer.append(buf, n);
    // Never hold more than one request's worth (plus a little pipelining).
    if (c.buffer.size() > config_.max_header_bytes + config_.max_body_bytes * 3 + 65536) break;
  }
  return try_dispatch(c);
}

// The peer sent its last request and shut its side (HTTP/1.0 tools, `nc -q`), often in the same
// read: a complete request is answered, then the connection closed; anything less is dropped.
bool HttpGuard::answer_then_close(Connection& c) {
  Parsed parsed;
  if (parse_request(c.buffer, config_, &parsed) != Parse::kComplete) return false;
  parsed.close = true;
  enqueue(c, parsed);
  return true;
}

bool HttpGuard::try_dispatch(Connection& c) {
  if (c.buffer.empty()) return true;
  Parsed parsed;
  const Parse verdict = parse_request(c.buffer, config_, &parsed);
  if (verdict == Parse::kIncomplete) {
    send_continue_if_expected(c);
  } else if (verdict == Parse::kComplete) {
    enqueue(c, parsed);
  } else {
    refuse(c, verdict);  // closes c
  }
  return true;
}

void HttpGuard::send_continue_if_expected(Connection& c) {
  if (c.continue_sent || !expects_continue(c.buffer)) return;
  c.continue_sent = true;
  c.channel->send_once("HTTP/1.1 100 Continue\r\n\r\n");
}

void HttpGuard::refuse(Connection& c, Parse verdict) {
  switch (verdict) {
    case Parse::kHeaderTooLarge:
      ++stats_.header_too_large;
      return reply_and_close(c, 431, "Request Header Fields Too Large");
    case Parse::kBodyTooLarge:
      ++stats_.body_too_large;
      return reply_and_close(c, 413, "Payload Too Large");
    default:
      ++stats_.bad_request;
      return reply_and_close(c, 400, "Bad Request");
  }
}

void HttpGuard::enqueue(Connection& c, Parsed& parsed) {
  auto job = std::make_unique<Job>();
  job->request = std::move(parsed.request);
  c.buffer.erase(0, parsed.consumed);
  ++c.served;
  job->close = parsed.close || c.served >= config_.keep_alive_max_requests;
  c.in_request = false;
  c.continue_sent = false;
  const int fd = c.fd();
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (jobs_.size() >= config_.queue_capacity) {
      ++stats_.overloaded;
      return reply_and_close(c, 503, "Service Unavailable");
    }
    // From here on one worker owns the connection (its channel included) until it hands it back.
    job->connection = std::move(connections_.at(fd));
    jobs_.push_back(std::move(job));
  }
  connections_.erase(fd);
  ++stats_.requests;
  jobs_cv_.notify_one();
}

bool HttpGuard::adopt_returned() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (stop_) return false;
  for (auto& c : returned_) {
    c->idle_since = Clock::now();
    const int fd = c->fd();
    connections_[fd] = std::move(c);
  }
  returned_.clear();
  return true;
}

void HttpGuard::dispatch_buffered() {
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
}

Clock::time_point HttpGuard::deadline(const Connection& c) const {
  return c.in_request ? c.request_start + ms(config_.request_deadline_s) : c.idle_since + ms(config_.keep_alive_idle_s);
}

int HttpGuard::poll_set(std::vector<pollfd>& fds, std::vector<int>& active) const {
  fds.push_back({wake_[0], POLLIN, 0});
  fds.push_back({listen_fd_, POLLIN, 0});
  const auto now = Clock::now();
  auto next = now + std::chrono::seconds(1);  // wake up at the nearest deadline
  for (const auto& [fd, c] : connections_) {
    fds.push_back({fd, short(POLLIN | (c->want_write ? POLLOUT : 0)), 0});
    next = std::min(next, deadline(*c));
    if (c->channel->pending()) active.push_back(fd);
  }
  const long wait_ms = std::chrono::duration_cast<std::chrono::milliseconds>(next - now).count() + 1;
  return active.empty() ? int(std::max<long>(0, wait_ms)) : 0;
}

void HttpGuard::drain_wake() {
  char drain[64];
  while (::read(wake_[0], drain, sizeof drain) > 0) {
  }
}

bool HttpGuard::poll_once() {
  std::vector<pollfd> fds;
  std::vector<int> active;  // connections with something to read or write
  const int timeout = poll_set(fds, active);
  if (::poll(fds.data(), fds.size(), timeout) < 0 && errno != EINTR) {
    logger("http")->error("HTTP guard: poll failed: {}", std::strerror(errno));
    return false;
  }
  if (fds[0].revents & POLLIN) drain_wake();
  if (fds[1].revents & POLLIN) accept_all();
  for (std::size_t i = 2; i < fds.size(); ++i)
    if (fds[i].revents) active.push_back(fds[i].fd);
  std::sort(active.begin(), active.end());
  active.erase(std::unique(active.begin(), active.end()), active.end());
  for (int fd : active) {
    auto it = connections_.find(fd);
    if (it == connections_.end()) continue;
    if (!on_readable(*it->second)) close_connection(fd);
  }
  return true;
}

void HttpGuard::expire_deadlines() {
  // A request not complete in time gets 408 (a TLS handshake not finished: closed); an idle
  // keep-alive connection is closed.
  const auto t = Clock::now();
  std::vector<int> expired_request, expired_idle;
  for (const auto& [fd, c] : connections_) {
    if (t <= deadline(*c)) continue;
    (c->in_request ? expired_request : expired_idle).push_back(fd);
  }
  for (int fd : expired_request) {
    ++stats_.timed_out;
    reply_and_close(*connections_.at(fd), 408, "Request Timeout");
  }
  for (int fd : expired_idle) close_connection(fd);
}

void HttpGuard::loop() {
  name_current_thread("http-accept");
  while (adopt_returned()) {
    dispatch_buffered();
    if (!poll_once()) return;
    expire_deadlines();
  }
}

void HttpGuard::serve(Job& job) {
  Connection& c = *job.connection;
  BufferedStream stream(*c.channel, std::move(job.request), c.ip, c.port, config_.write_timeout_s);
  bool closed = false;
  const std::string ip = c.ip;
  const int port = c.port;
  try {
    router_.route(stream, job.close, closed, [&](httplib::Request& req) {
      req.remote_addr = ip;
      req.remote_port = port;
      req.set_header("REMOTE_ADDR", ip);
      req.set_header("REMOTE_PORT", std::to_string(port));
    });
  } catch (const std::exception& e) {
    logger("http")->warn("HTTP request failed: {}", e.what());
    closed = true;
  }
  if (job.close || closed || stream.failed()) job.connection.reset();  // closed (TLS: close_notify first)
}

std::unique_ptr<HttpGuard::Job> HttpGuard::next_job() {
  std::unique_lock<std::mutex> lock(mutex_);
  jobs_cv_.wait(lock, [this] { return stop_ || !jobs_.empty(); });
  if (stop_) return nullptr;
  std::unique_ptr<Job> job = std::move(jobs_.front());
  jobs_.pop_front();
  return job;
}

void HttpGuard::hand_back(std::unique_ptr<Connection> c) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (stop_) return;                  // closed here
    returned_.push_back(std::move(c));  // back to the event loop, with its channel
  }
  const char w = 'r';
  [[maybe_unused]] const ssize_t n = ::write(wake_[1], &w, 1);
}

void HttpGuard::worker() {
  name_current_thread("http-serve");
  while (std::unique_ptr<Job> job = next_job()) {
    serve(*job);
    if (job->connection) hand_back(std::move(job->connection));
  }
}

}  // namespace cslam::http
