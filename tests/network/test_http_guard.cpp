// Cases 5 and 6 (HTTP slowloris, unlimited headers, chunked bodies past the limit) against the
// real HttpServer on loopback: the guard in front of cpp-httplib enforces a per-request deadline,
// header count and bytes caps, a body limit for chunked bodies and keep-alive limits, and status
// keeps answering while many slow connections are open. Functional checks, generous timeouts.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "raw_socket.h"
#include "server/http/http_server.h"
#include "system/collaborative_system.h"
#include <httplib.h>  // after every Eigen include

namespace cslam::http {
namespace {

using Clock = std::chrono::steady_clock;

int connect_to(int port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(std::uint16_t(port));
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
    ::close(fd);
    return -1;
  }
  return fd;
}

using test::send_all;

// Reads until the peer closes or timeout; returns what arrived.
std::string read_until_close(int fd, double timeout_s, bool* closed = nullptr) {
  std::string out;
  const auto deadline = Clock::now() + std::chrono::duration<double>(timeout_s);
  char buf[4096];
  for (;;) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
    if (left <= 0) break;
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, int(left)) <= 0) break;
    const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
    if (n <= 0) {
      if (closed) *closed = true;
      return out;
    }
    out.append(buf, std::size_t(n));
  }
  if (closed) *closed = false;
  return out;
}

// Reads one response (headers + Content-Length body) without waiting for close.
std::string read_response(int fd, double timeout_s) {
  std::string out;
  const auto deadline = Clock::now() + std::chrono::duration<double>(timeout_s);
  char buf[4096];
  while (Clock::now() < deadline) {
    const auto he = out.find("\r\n\r\n");
    if (he != std::string::npos) {
      const auto cl = out.find("Content-Length: ");
      if (cl != std::string::npos && cl < he) {
        const std::size_t n = std::stoul(out.substr(cl + 16));
        if (out.size() >= he + 4 + n) return out;
      }
    }
    pollfd p{fd, POLLIN, 0};
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
    if (::poll(&p, 1, int(std::max<long>(1, left))) <= 0) break;
    const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
    if (n <= 0) break;
    out.append(buf, std::size_t(n));
  }
  return out;
}

class HttpGuardTest : public ::testing::Test {
 protected:
  static SystemConfig system_config() {
    SystemConfig c;
    c.run_slam = false;
    return c;
  }
  std::unique_ptr<HttpServer> serve(GuardConfig g = {}) {
    HttpConfig c;
    c.port = 0;
    c.guard = g;
    auto s = std::make_unique<HttpServer>(system_, c);
    EXPECT_TRUE(s->start());
    return s;
  }
  CollaborativeSystem system_{system_config()};
};

TEST_F(HttpGuardTest, StatusAnswersWhileFiftySlowlorisConnectionsAreOpen) {
  auto server = serve();
  std::vector<int> slow;
  for (int i = 0; i < 50; ++i) {
    const int fd = connect_to(server->port());
    ASSERT_GE(fd, 0);
    ASSERT_TRUE(send_all(fd, "GET /api/status HTTP/1.1\r\nHost: x\r\n"));  // never finished
    slow.push_back(fd);
  }
  for (int round = 0; round < 3; ++round) {
    for (int fd : slow) send_all(fd, "X-Trickle: " + std::to_string(round) + "\r\n");
    httplib::Client client("127.0.0.1", server->port());
    client.set_read_timeout(10, 0);
    const auto r = client.Get("/api/status");
    ASSERT_TRUE(r) << "status did not answer with 50 slow connections open";
    EXPECT_EQ(r->status, 200);
  }
  for (int fd : slow) ::close(fd);
}

// A client that sends its request and shuts its side at once (HTTP/1.0 tools, `nc -q`) gets its
// answer, then the close: the request and the end of stream often arrive in one read.
TEST_F(HttpGuardTest, ARequestFollowedByAHalfCloseIsAnswered) {
  auto server = serve();
  for (int i = 0; i < 20; ++i) {
    const int fd = connect_to(server->port());
    ASSERT_GE(fd, 0);
    ASSERT_TRUE(send_all(fd, "GET /api/status HTTP/1.1\r\nHost: x\r\n\r\n"));
    ::shutdown(fd, SHUT_WR);
    bool closed = false;
    const std::string reply = read_until_close(fd, 10, &closed);
    ::close(fd);
    EXPECT_EQ(reply.rfind("HTTP/1.1 200", 0), 0u) << "attempt " << i << ": '" << reply.substr(0, 60) << "'";
    EXPECT_TRUE(closed) << "attempt " << i;
  }
}

TEST_F(HttpGuardTest, ARequestNotCompleteWithinTheDeadlineIsClosed) {
  GuardConfig g;
  g.request_deadline_s = 0.5;
  auto server = serve(g);
  const int fd = connect_to(server->port());
  ASSERT_GE(fd, 0);
  ASSERT_TRUE(send_all(fd, "GET /api/status HTTP/1.1\r\n"));
  // Trickle a header line now and then: before the guard, each line reset httplib's read timeout.
  bool closed = false;
  std::string got;
  for (int i = 0; i < 40 && !closed; ++i) {
    send_all(fd, "X-A: b\r\n");
    got += read_until_close(fd, 0.25, &closed);
  }
  EXPECT_TRUE(closed) << "a slow request was kept open";
  EXPECT_NE(got.find("408"), std::string::npos) << got;
  ::close(fd);
  EXPECT_GE(server->guard_stats()->timed_out, 1u);
}

TEST_F(HttpGuardTest, TwentyThousandHeadersAreRefused) {
  auto server = serve();
  const int fd = connect_to(server->port());
  ASSERT_GE(fd, 0);
  std::string req = "GET /api/status HTTP/1.1\r\nHost: x\r\n";
  const std::string value(1000, 'a');
  bool refused = false;
  send_all(fd, req);
  for (int i = 0; i < 20000 && !refused; ++i) {
    if (!send_all(fd, "X-H" + std::to_string(i) + ": " + value + "\r\n")) refused = true;
    if (i % 50 == 0) {
      pollfd p{fd, POLLIN, 0};
      if (::poll(&p, 1, 0) > 0) refused = true;
    }
  }
  const std::string got = read_until_close(fd, 10);
  EXPECT_NE(got.find("431"), std::string::npos) << got.substr(0, 200);
  ::close(fd);
  // Many short headers: the count cap.
  const int fd2 = connect_to(server->port());
  std::string many = "GET /api/status HTTP/1.1\r\nHost: x\r\n";
  for (int i = 0; i < 500; ++i) many += "X" + std::to_string(i) + ": 1\r\n";
  many += "\r\n";
  send_all(fd2, many);
  EXPECT_NE(read_until_close(fd2, 10).find("431"), std::string::npos);
  ::close(fd2);
  EXPECT_GE(server->guard_stats()->header_too_large, 2u);
}

TEST_F(HttpGuardTest, ChunkedBodyPastTheLimitIsRefused) {
  auto server = serve();
  const int fd = connect_to(server->port());
  ASSERT_GE(fd, 0);
  send_all(fd, "POST /api/reconstruction HTTP/1.1\r\nHost: x\r\nTransfer-Encoding: chunked\r\n\r\n");
  const std::string chunk(16384, 'z');
  char size_line[32];
  std::snprintf(size_line, sizeof size_line, "%zx\r\n", chunk.size());
  for (int i = 0; i < 64; ++i)  // 1 MB in chunks, past the 64 kB limit
    if (!send_all(fd, size_line + chunk + "\r\n")) break;
  const std::string got = read_until_close(fd, 10);
  EXPECT_NE(got.find("413"), std::string::npos) << got.substr(0, 200);
  EXPECT_EQ(got.find("202"), std::string::npos);
  ::close(fd);
  // A small chunked body still reaches the handler (decoded, with a Content-Length).
  const int fd2 = connect_to(server->port());
  send_all(fd2,
           "POST /api/reconstruction HTTP/1.1\r\nHost: x\r\nTransfer-Encoding: chunked\r\n\r\n2\r\n{}\r\n0\r\n\r\n");
  const std::string small = read_response(fd2, 10);
  EXPECT_EQ(small.find("413"), std::string::npos) << small.substr(0, 200);
  EXPECT_NE(small.find("HTTP/1.1 "), std::string::npos);
  ::close(fd2);
  // Content-Length past the limit is refused before the body is read.
  const int fd3 = connect_to(server->port());
  send_all(fd3, "POST /api/reconstruction HTTP/1.1\r\nHost: x\r\nContent-Length: 10000000\r\n\r\n");
  EXPECT_NE(read_until_close(fd3, 10).find("413"), std::string::npos);
  ::close(fd3);
  // The refusals are counted in /metrics.
  httplib::Client client("127.0.0.1", server->port());
  std::string metrics;
  for (int i = 0; i < 100; ++i) {
    const auto r = client.Get("/metrics");
    ASSERT_TRUE(r);
    metrics = r->body;
    if (metrics.find("cslam_http_refused_total{reason=\"body_too_large\"} 2") != std::string::npos) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  EXPECT_NE(metrics.find("cslam_http_refused_total{reason=\"body_too_large\"} 2"), std::string::npos) << metrics;
}

TEST_F(HttpGuardTest, KeepAliveIsLimitedInRequestsAndIdleTime) {
  GuardConfig g;
  g.keep_alive_max_requests = 3;
  g.keep_alive_idle_s = 0.5;
  auto server = serve(g);
  const int fd = connect_to(server->port());
  ASSERT_GE(fd, 0);
  for (int i = 0; i < 3; ++i) {
    ASSERT_TRUE(send_all(fd, "GET /api/status HTTP/1.1\r\nHost: x\r\n\r\n"));
    const std::string r = read_response(fd, 10);
    EXPECT_NE(r.find("200 OK"), std::string::npos) << r.substr(0, 200);
    if (i == 2) {
      EXPECT_NE(r.find("Connection: close"), std::string::npos);
    }
  }
  bool closed = false;
  read_until_close(fd, 10, &closed);
  EXPECT_TRUE(closed);  // after the third request
  ::close(fd);
  // An idle keep-alive connection is closed after keep_alive_idle_s.
  const int fd2 = connect_to(server->port());
  send_all(fd2, "GET /api/status HTTP/1.1\r\nHost: x\r\n\r\n");
  EXPECT_NE(read_response(fd2, 10).find("200 OK"), std::string::npos);
  closed = false;
  read_until_close(fd2, 10, &closed);
  EXPECT_TRUE(closed);
  ::close(fd2);
}

}  // namespace
}  // namespace cslam::http
