// HTTP beyond loopback (issue 34, item 8) over real sockets: the real HttpServer bound to 0.0.0.0
// with TLS (a self-signed certificate made at test time) and a token. Every API route needs the
// token, wrong tokens from one address are throttled (429, even with the right token) while other
// addresses are served, plain HTTP to the TLS port gets a clear answer, and the guard's limits
// hold under TLS: a stalled handshake is closed by the request deadline, header and body caps, the
// connection cap, keep-alive. Functional checks with generous timeouts, no timing assertions.
#include <chrono>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "common/run_program.h"
#include "network/tls_test_util.h"
#include "server/http/http_server.h"
#include "server/http/tls_channel.h"
#include "server/http/tls_context.h"
#include "system/collaborative_system.h"
#include <httplib.h>  // after every Eigen include

#include <openssl/ssl.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

namespace cslam::http {
namespace {

const std::string kToken = "a-token-of-24-characters";

class TlsAuthTest : public ::testing::Test {
 protected:
  static SystemConfig system_config() {
    SystemConfig c;
    c.run_slam = false;
    return c;
  }
  std::unique_ptr<HttpServer> serve(GuardConfig g = {}, AuthConfig a = {}) {
    HttpConfig c;
    c.port = 0;
    c.bind = "0.0.0.0";
    c.token = kToken;
    c.tls_cert = cert_.cert;
    c.tls_key = cert_.key;
    c.guard = g;
    c.auth = a;
    c.web_root = std::string(CSLAM_SOURCE_DIR) + "/web";
    auto s = std::make_unique<HttpServer>(system_, c);
    EXPECT_TRUE(s->start());
    return s;
  }
  // An HTTPS client that verifies the server against the test's certificate (CN/SAN 127.0.0.1).
  std::unique_ptr<httplib::SSLClient> client(const HttpServer& s, const std::string& token = kToken) const {
    auto cli = std::make_unique<httplib::SSLClient>("127.0.0.1", s.port());
    cli->set_ca_cert_path(cert_.cert.c_str());
    cli->enable_server_certificate_verification(true);
    cli->set_connection_timeout(10, 0);
    cli->set_read_timeout(10, 0);
    if (!token.empty()) cli->set_bearer_token_auth(token.c_str());
    return cli;
  }
  // Waits (bounded) for a line in /metrics, asked from `source_ip` with the right token.
  static bool metrics_show(int port, const std::string& line, const std::string& source_ip) {
    for (int i = 0; i < 100; ++i) {
      test::TlsConn c(port, source_ip);
      if (c.handshake() && c.send(test::get_request("/metrics", kToken)) &&
          c.read_response().find(line) != std::string::npos)
        return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(100));  // the metrics refresh every 0.2 s
    }
    return false;
  }

  test::TempDir dir_{"cslam_http_tls"};
  test::CertFiles cert_ = test::make_self_signed(dir_.str());
  CollaborativeSystem system_{system_config()};
};

TEST_F(TlsAuthTest, EveryApiRouteNeedsTheTokenOverTls) {
  auto server = serve();
  for (const char* path : {"/api/status", "/metrics", "/api/trajectories?client=all&format=tum", "/api/fusion/events",
                           "/api/clients/1", "/api/dense/status", "/api/health"}) {
    const auto none = client(*server, "")->Get(path);
    ASSERT_TRUE(none) << path << ": " << httplib::to_string(none.error());
    EXPECT_EQ(none->status, 401) << path;
    EXPECT_EQ(none->get_header_value("WWW-Authenticate"), "Bearer");
    const auto wrong = client(*server, "not-the-token-but-as-long")->Get(path);
    ASSERT_TRUE(wrong);
    EXPECT_EQ(wrong->status, 401) << path;
  }
  EXPECT_EQ(client(*server, "")->Post("/api/reconstruction", "", "text/plain")->status, 401);
  const auto ok = client(*server)->Get("/api/status");
  ASSERT_TRUE(ok) << httplib::to_string(ok.error());
  EXPECT_EQ(ok->status, 200);
  EXPECT_NE(ok->body.find("\"server\":\"cslam-server\""), std::string::npos);
  // The viewer's files carry no data and stay public (the page asks for the token).
  const auto page = client(*server, "")->Get("/");
  ASSERT_TRUE(page);
  EXPECT_EQ(page->status, 200);
  EXPECT_NE(page->body.find("<html"), std::string::npos);
  EXPECT_EQ(client(*server, "")->Get("/net.js")->status, 200);
}

TEST_F(TlsAuthTest, PlainHttpToTheTlsPortIsAnsweredAndServingGoesOn) {
  auto server = serve();
  for (int i = 0; i < 3; ++i) {
    httplib::Client plain("127.0.0.1", server->port());
    plain.set_read_timeout(10, 0);
    const auto r = plain.Get("/api/status", {{"Authorization", "Bearer " + kToken}});
    ASSERT_TRUE(r) << httplib::to_string(r.error());
    EXPECT_EQ(r->status, 400);
    EXPECT_NE(r->body.find("https://"), std::string::npos) << r->body;
  }
  const auto ok = client(*server)->Get("/api/status");
  ASSERT_TRUE(ok) << httplib::to_string(ok.error());
  EXPECT_EQ(ok->status, 200);
  EXPECT_EQ(server->guard_stats()->plain_http_on_tls, 3u);
}

TEST_F(TlsAuthTest, WrongTokensFromOneAddressAreThrottledEvenWithTheRightToken) {
  AuthConfig a;
  a.max_failures = 3;
  a.window_s = 600;  // one attempt back every 200 s: nothing refills during the test
  auto server = serve({}, a);
  const auto ask = [&](const std::string& source_ip, const std::string& token) {
    test::TlsConn c(server->port(), source_ip);
    EXPECT_TRUE(c.handshake());
    EXPECT_TRUE(c.send(test::get_request("/api/status", token)));
    return c.read_response();
  };
  for (int i = 0; i < 3; ++i) EXPECT_EQ(test::status_of(ask("127.0.0.1", "guess-number-" + std::to_string(i))), 401);
  const std::string throttled = ask("127.0.0.1", "guess-number-4");
  EXPECT_EQ(test::status_of(throttled), 429) << throttled;
  EXPECT_NE(throttled.find("Retry-After: 200"), std::string::npos) << throttled;
  // The right token does not get through either: a 200 would confirm a guess made while throttled.
  EXPECT_EQ(test::status_of(ask("127.0.0.1", kToken)), 429);
  // Another address (any 127.x is this machine) is served meanwhile.
  EXPECT_EQ(test::status_of(ask("127.0.0.2", kToken)), 200);
  EXPECT_EQ(server->auth().stats().wrong, 3u);
  EXPECT_EQ(server->auth().stats().throttled, 2u);
  EXPECT_TRUE(metrics_show(server->port(), "cslam_http_auth_failures_total{reason=\"wrong\"} 3", "127.0.0.2"));
  EXPECT_TRUE(metrics_show(server->port(), "cslam_http_auth_throttled_total 2", "127.0.0.2"));
}

TEST_F(TlsAuthTest, AStalledHandshakeIsClosedByTheDeadlineWhileOthersAreServed) {
  GuardConfig g;
  g.request_deadline_s = 1;
  g.keep_alive_idle_s = 60;  // only the request deadline can close the stalled connections in time
  auto server = serve(g);
  std::vector<std::unique_ptr<test::TlsConn>> stalled;
  for (int i = 0; i < 20; ++i) {
    stalled.push_back(std::make_unique<test::TlsConn>(server->port()));
    ASSERT_TRUE(stalled.back()->connected());
    // The first bytes of a TLS record header, then nothing: the handshake never completes.
    if (i % 2 == 0) {
      ASSERT_TRUE(stalled.back()->send_raw(std::string("\x16\x03\x01", 3)));
    }
  }
  const auto ok = client(*server)->Get("/api/status");  // served while they stall
  ASSERT_TRUE(ok) << httplib::to_string(ok.error());
  EXPECT_EQ(ok->status, 200);
  for (auto& c : stalled) {
    bool closed = false;
    const std::string got = c->read_until_close(15, &closed);
    EXPECT_TRUE(closed) << "a stalled handshake was not closed";
    EXPECT_TRUE(got.empty()) << "no plain-text reply on a TLS port before the handshake";
  }
  EXPECT_GE(server->guard_stats()->timed_out, 20u);
}

TEST_F(TlsAuthTest, TheGuardsLimitsHoldUnderTls) {
  GuardConfig g;
  g.request_deadline_s = 2;
  auto server = serve(g);
  {  // 20 000 header lines: 431, closed
    test::TlsConn c(server->port());
    ASSERT_TRUE(c.handshake());
    std::string flood = "GET /api/status HTTP/1.1\r\nHost: x\r\n";
    for (int i = 0; i < 20000; ++i) flood += "X-Flood-" + std::to_string(i) + ": 1\r\n";
    c.send(flood);  // the server may close before all of it is written
    EXPECT_EQ(test::status_of(c.read_response()), 431);
  }
  {  // a chunked body past the 64 kB limit: 413
    test::TlsConn c(server->port());
    ASSERT_TRUE(c.handshake());
    std::string chunked = "POST /api/reconstruction HTTP/1.1\r\nHost: x\r\nTransfer-Encoding: chunked\r\n\r\n";
    for (int i = 0; i < 20; ++i) chunked += "1000\r\n" + std::string(4096, 'a') + "\r\n";
    c.send(chunked);
    EXPECT_EQ(test::status_of(c.read_response()), 413);
  }
  {  // half a request after the handshake: 408 through TLS, closed
    test::TlsConn c(server->port());
    ASSERT_TRUE(c.handshake());
    ASSERT_TRUE(c.send("GET /api/status HTTP/1.1\r\nHost: x\r\n"));
    bool closed = false;
    const std::string got = c.read_until_close(15, &closed);
    EXPECT_EQ(test::status_of(got), 408) << got;
    EXPECT_TRUE(closed);
  }
  {  // keep-alive: three requests on one TLS connection
    const auto accepted = server->guard_stats()->accepted.load();
    test::TlsConn c(server->port());
    ASSERT_TRUE(c.handshake());
    for (int i = 0; i < 3; ++i) {
      ASSERT_TRUE(c.send(test::get_request("/api/status", kToken, false)));
      EXPECT_EQ(test::status_of(c.read_response()), 200) << "request " << i;
    }
    EXPECT_EQ(server->guard_stats()->accepted.load(), accepted + 1);
  }
}

TEST_F(TlsAuthTest, TheConnectionCapHoldsUnderTls) {
  GuardConfig g;
  g.max_connections = 8;
  auto server = serve(g);
  // The ninth connection is closed at once (without a word: no handshake was made), the eight are served.
  std::vector<std::unique_ptr<test::TlsConn>> open;
  for (int i = 0; i < 8; ++i) {
    open.push_back(std::make_unique<test::TlsConn>(server->port()));
    ASSERT_TRUE(open.back()->handshake());
  }
  test::TlsConn extra(server->port());
  bool closed = false;
  EXPECT_TRUE(extra.read_until_close(15, &closed).empty());
  EXPECT_TRUE(closed);
  for (auto& c : open) {
    ASSERT_TRUE(c->send(test::get_request("/api/status", kToken)));
    EXPECT_EQ(test::status_of(c->read_response()), 200);
  }
  EXPECT_EQ(server->guard_stats()->connections_refused, 1u);
}

// A worker writing a response to a client that has gone: OpenSSL's own socket BIO writes with
// write(2), which raises SIGPIPE and ends the process; the guard's BIO sends with MSG_NOSIGNAL.
TEST(TlsChannel, WritingToAPeerThatHasGoneFailsWithoutSigpipe) {
  test::TempDir dir("cslam_tls_channel");
  const test::CertFiles cert = test::make_self_signed(dir.str());
  const TlsContext tls(cert.cert, cert.key);
  int sv[2];
  ASSERT_EQ(::socketpair(AF_UNIX, SOCK_STREAM | SOCK_NONBLOCK, 0, sv), 0);
  Channel server(sv[0], tls.get());
  SSL_CTX* client_ctx = SSL_CTX_new(TLS_client_method());
  SSL* client = SSL_new(client_ctx);
  SSL_set_fd(client, sv[1]);
  SSL_set_connect_state(client);
  for (int i = 0; i < 1000 && !server.ready(); ++i) {  // both ends stepped in turn, non-blocking
    SSL_do_handshake(client);
    const Io io = server.handshake();
    ASSERT_NE(io, Io::kError);
    pollfd p[2] = {{sv[0], POLLIN, 0}, {sv[1], POLLIN, 0}};
    ::poll(p, 2, 100);
  }
  ASSERT_TRUE(server.ready());
  SSL_free(client);  // the peer goes away without a word
  SSL_CTX_free(client_ctx);
  ::close(sv[1]);
  const std::string body(1 << 20, 'x');
  EXPECT_FALSE(
      write_all(server, body.data(), body.size(), std::chrono::steady_clock::now() + std::chrono::seconds(10)));
}

}  // namespace
}  // namespace cslam::http
