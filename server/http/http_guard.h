#pragma once
// A guard in front of cpp-httplib (0.11 on Debian 12 has no header-count limit, no limit on a
// chunked body and holds one worker thread per open connection, so 12 slow connections took the
// whole API offline). The guard owns the listening socket:
//  - one event-loop thread reads every connection without blocking (poll) and enforces a
//    per-request deadline (request line, headers and body complete within request_deadline_s),
//    a cap on header count and header bytes, a body limit for Content-Length and chunked bodies,
//    a connection cap and keep-alive limits (requests per connection, idle time);
//  - only a complete, normalised request (chunked body decoded, Content-Length set) goes to a
//    fixed pool of worker threads, which let httplib route it and write the response
//    (RequestRouter, server/http/request_router.h: the one seam into httplib, and why).
// A slow or hostile client therefore costs a few kilobytes in the event loop, never a worker.
//
// With a TlsContext (--http-cert/--http-key) every connection is TLS: the event loop drives the
// non-blocking handshake and reads (server/http/tls_channel.h), the handshake counts against the
// first request's deadline, and the worker writes the response with SSL_write. A connection (and
// its SSL object) belongs to the event loop or to one worker, never both: it is handed over with
// the job and handed back under the mutex.
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

struct pollfd;

namespace cslam::http {

struct GuardConfig {
  double request_deadline_s = 5.0;  // whole request (headers + body) from its first byte
  std::size_t max_header_count = 100;
  std::size_t max_header_bytes = 32 * 1024;   // request line + headers
  std::size_t max_body_bytes = 64 * 1024;     // Content-Length or decoded chunked body
  std::size_t max_connections = 512;          // open connections; more are answered 503 and closed
  std::size_t keep_alive_max_requests = 100;  // then "Connection: close"
  double keep_alive_idle_s = 5.0;             // an idle keep-alive connection is closed after this
  std::size_t workers = 4;                    // threads running handlers (see docs/http.md)
  std::size_t queue_capacity = 64;            // complete requests waiting for a worker; more: 503
  double write_timeout_s = 5.0;               // a response that cannot be written in this time is dropped
};

struct GuardStats {
  std::atomic<std::uint64_t> accepted{0}, requests{0}, timed_out{0}, header_too_large{0}, body_too_large{0},
      bad_request{0}, overloaded{0}, connections_refused{0}, tls_handshake_failed{0}, plain_http_on_tls{0};
};

class TlsContext;     // server/http/tls_context.h
class RequestRouter;  // server/http/request_router.h
enum class Parse;     // server/http/http_request_parse.h
struct Parsed;

class HttpGuard {
 public:
  // router: routes and answers each complete request; tls: null for plain HTTP. Both outlive the guard.
  HttpGuard(RequestRouter& router, GuardConfig config, const TlsContext* tls = nullptr);
  ~HttpGuard();  // stop()
  HttpGuard(const HttpGuard&) = delete;
  HttpGuard& operator=(const HttpGuard&) = delete;

  // Binds host:port (port 0: any free port). Returns the bound port, or -1 (errno kept).
  int bind(const std::string& host, int port);
  void start();  // event loop + workers
  void stop();   // idempotent; closes every connection and joins every thread
  const GuardStats& stats() const { return stats_; }

 private:
  struct Connection;
  struct Job;
  void loop();
  bool adopt_returned();  // false once stopping
  void dispatch_buffered();
  bool poll_once();  // false if poll failed
  // Fills the poll set (wake pipe, listening socket, connections); returns the poll timeout (ms).
  // `active` gets the connections with TLS bytes already decrypted (readable whatever poll says).
  int poll_set(std::vector<pollfd>& fds, std::vector<int>& active) const;
  void drain_wake();
  void expire_deadlines();
  std::chrono::steady_clock::time_point deadline(const Connection& c) const;
  void worker();
  std::unique_ptr<Job> next_job();                // null once stopping
  void serve(Job& job);                           // resets job.connection if the connection is to be closed
  void hand_back(std::unique_ptr<Connection> c);  // a kept-alive connection, to the event loop
  void accept_all();
  void adopt(int fd, const std::string& ip, int port);  // an accepted socket
  // Reads what is available (after the TLS handshake); returns false if the connection should be
  // closed now.
  bool on_readable(Connection& c);
  bool on_handshake(Connection& c);  // false: the handshake failed
  // Looks for a complete request in c's buffer; answers errors itself. Returns false to close.
  bool try_dispatch(Connection& c);
  bool answer_then_close(Connection& c);  // the peer half-closed after a request
  void send_continue_if_expected(Connection& c);
  void refuse(Connection& c, Parse verdict);    // answers a request that broke a limit, and closes
  void enqueue(Connection& c, Parsed& parsed);  // hands a complete request to the workers
  void reply_and_close(Connection& c, int status, const char* text);
  void close_connection(int fd);

  RequestRouter& router_;
  const GuardConfig config_;
  const TlsContext* tls_;
  GuardStats stats_;
  int listen_fd_ = -1;
  int wake_[2] = {-1, -1};
  std::map<int, std::unique_ptr<Connection>> connections_;  // event-loop thread only
  std::thread loop_thread_;
  std::vector<std::thread> workers_;

  std::mutex mutex_;  // jobs_, returned_, stop_
  std::condition_variable jobs_cv_;
  std::deque<std::unique_ptr<Job>> jobs_;
  std::vector<std::unique_ptr<Connection>> returned_;  // keep-alive connections back from workers
  bool stop_ = false;
};

}  // namespace cslam::http
