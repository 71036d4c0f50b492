// HTTP beyond loopback (issue 34, item 8), without sockets: the constant-time token comparison,
// the per-address rate limit of wrong tokens (bucket, bounded table, IPv6 /64), and the
// configuration errors of --http-bind beyond loopback (token mandatory, TLS or --http-insecure,
// certificate and key files named when they cannot be used).
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/run_program.h"
#include "core/cli.h"
#include "core/error.h"
#include "network/tls_test_util.h"
#include "server/http/auth_gate.h"
#include "server/http/http_server.h"
#include "system/collaborative_system.h"

namespace cslam::http {
namespace {

using Clock = AuthGate::Clock;
using Verdict = AuthGate::Verdict;

TEST(TokensEqual, AcceptsEqualAndRejectsDifferentTokensOfEqualAndDifferentLengths) {
  EXPECT_TRUE(tokens_equal("a-token-of-24-characters", "a-token-of-24-characters"));
  EXPECT_TRUE(tokens_equal("", ""));
  EXPECT_FALSE(tokens_equal("a-token-of-24-characters", "a-token-of-24-characterz"));  // last byte
  EXPECT_FALSE(tokens_equal("a-token-of-24-characters", "b-token-of-24-characters"));  // first byte
  EXPECT_FALSE(tokens_equal("a-token-of-24-characters", "a-token-of-24-character"));   // a prefix
  EXPECT_FALSE(tokens_equal("a-token-of-24-characters", "a-token-of-24-characters-and-more"));
  EXPECT_FALSE(tokens_equal("a-token-of-24-characters", ""));
  EXPECT_FALSE(tokens_equal(std::string("abc\0def", 7), std::string("abc\0xyz", 7)));  // past a NUL
}

TEST(AuthGate, WrongTokensEmptyTheBucketWhichRefillsOverTheWindow) {
  AuthGate gate("a-token-of-24-characters", {3, 60, 16});
  const auto t0 = Clock::now();
  const std::string right = "Bearer a-token-of-24-characters", wrong = "Bearer guess";
  EXPECT_EQ(gate.check("10.0.0.1", right, t0).verdict, Verdict::kOk);
  for (int i = 0; i < 3; ++i) EXPECT_EQ(gate.check("10.0.0.1", wrong, t0).verdict, Verdict::kWrong);
  const auto throttled = gate.check("10.0.0.1", right, t0);  // refused without looking at the token
  EXPECT_EQ(throttled.verdict, Verdict::kThrottled);
  EXPECT_EQ(throttled.retry_after_s, 20);                              // one attempt back after 60 s / 3
  EXPECT_EQ(gate.check("10.0.0.2", right, t0).verdict, Verdict::kOk);  // another address is not affected
  EXPECT_EQ(gate.check("10.0.0.1", right, t0 + std::chrono::seconds(19)).verdict, Verdict::kThrottled);
  EXPECT_EQ(gate.check("10.0.0.1", right, t0 + std::chrono::seconds(21)).verdict, Verdict::kOk);
  EXPECT_EQ(gate.check("10.0.0.1", wrong, t0 + std::chrono::seconds(21)).verdict, Verdict::kWrong);
  EXPECT_EQ(gate.check("10.0.0.1", right, t0 + std::chrono::seconds(22)).verdict, Verdict::kThrottled);
  EXPECT_EQ(gate.stats().wrong, 4u);
  EXPECT_EQ(gate.stats().throttled, 3u);
}

TEST(AuthGate, RequestsWithoutATokenAreRefusedButNotCharged) {
  AuthGate gate("a-token-of-24-characters", {2, 60, 16});
  const auto t0 = Clock::now();
  for (int i = 0; i < 50; ++i) {
    EXPECT_EQ(gate.check("10.0.0.1", "", t0).verdict, Verdict::kMissing);
    EXPECT_EQ(gate.check("10.0.0.1", "Basic dXNlcjpwYXNz", t0).verdict, Verdict::kMissing);
  }
  EXPECT_EQ(gate.check("10.0.0.1", "bearer a-token-of-24-characters", t0).verdict, Verdict::kOk);  // scheme any case
  EXPECT_EQ(gate.tracked(), 0u);
  EXPECT_EQ(gate.stats().missing, 100u);
}

TEST(AuthGate, TheAddressTableIsBoundedAndNewcomersShareOneBucketWhenItIsFull) {
  AuthGate gate("a-token-of-24-characters", {1, 60, 4});
  const auto t0 = Clock::now();
  const std::string right = "Bearer a-token-of-24-characters", wrong = "Bearer guess";
  for (int i = 1; i <= 4; ++i) EXPECT_EQ(gate.check("10.0.0." + std::to_string(i), wrong, t0).verdict, Verdict::kWrong);
  EXPECT_EQ(gate.tracked(), 4u);
  for (int i = 5; i <= 1000; ++i)
    gate.check("10.1." + std::to_string(i / 250) + "." + std::to_string(i % 250), wrong, t0);
  EXPECT_EQ(gate.tracked(), 4u);
  EXPECT_GE(gate.stats().table_full, 1u);
  // The shared bucket is empty: a newcomer is throttled while the table stays full ...
  EXPECT_EQ(gate.check("10.0.2.1", right, t0).verdict, Verdict::kThrottled);
  // ... and once the buckets have refilled, they are dropped and newcomers are served again.
  const auto later = t0 + std::chrono::seconds(61);
  EXPECT_EQ(gate.check("10.0.2.1", right, later).verdict, Verdict::kOk);
  EXPECT_EQ(gate.check("10.0.2.2", wrong, later).verdict, Verdict::kWrong);
  EXPECT_EQ(gate.tracked(), 1u);
}

TEST(AuthGate, AnIpv6HostIsOneAddressPerSlash64) {
  EXPECT_EQ(address_key("2001:db8:1:2:aaaa::1"), address_key("2001:db8:1:2:bbbb::7"));
  EXPECT_NE(address_key("2001:db8:1:2::1"), address_key("2001:db8:1:3::1"));
  EXPECT_EQ(address_key("::ffff:192.0.2.7"), "192.0.2.7");
  EXPECT_EQ(address_key("192.0.2.7"), "192.0.2.7");
  AuthGate gate("a-token-of-24-characters", {1, 60, 16});
  const auto t0 = Clock::now();
  EXPECT_EQ(gate.check("2001:db8:1:2::1", "Bearer guess", t0).verdict, Verdict::kWrong);
  EXPECT_EQ(gate.check("2001:db8:1:2::2", "Bearer a-token-of-24-characters", t0).verdict, Verdict::kThrottled);
}

// config_from() over a real command line, as cslam-server parses it.
HttpConfig parse(std::vector<std::string> args) {
  CliArgs cli("cslam-server", "test");
  declare_options(cli);
  args.insert(args.begin(), "cslam-server");
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  cli.parse(int(argv.size()), argv.data());
  return config_from(cli);
}

// The one-line message of the ConfigError `args` give ("" if none).
std::string config_error(const std::vector<std::string>& args) {
  try {
    parse(args);
  } catch (const ConfigError& e) {
    EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
    return e.what();
  }
  return "";
}

TEST(HttpExposure, BeyondLoopbackATokenAndTlsOrInsecureAreRequired) {
  const std::string token = "a-token-of-24-characters";
  EXPECT_EQ(config_error({}), "");  // loopback: as before
  EXPECT_EQ(config_error({"--http-bind", "127.0.0.2"}), "");
  EXPECT_EQ(config_error({"--http-bind", "0.0.0.0", "--http", "off"}), "");
  EXPECT_NE(config_error({"--http-bind", "0.0.0.0"}).find("--http-token"), std::string::npos);
  EXPECT_NE(config_error({"--http-bind", "::", "--http-insecure"}).find("--http-token"), std::string::npos);
  EXPECT_NE(config_error({"--http-bind", "0.0.0.0", "--http-token", "short", "--http-insecure"}).find("16 characters"),
            std::string::npos);
  const std::string no_tls = config_error({"--http-bind", "0.0.0.0", "--http-token", token});
  EXPECT_NE(no_tls.find("--http-cert"), std::string::npos) << no_tls;
  EXPECT_NE(no_tls.find("--http-insecure"), std::string::npos) << no_tls;
  EXPECT_EQ(config_error({"--http-bind", "0.0.0.0", "--http-token", token, "--http-insecure"}), "");
  // A programmatic config goes through the same check.
  HttpConfig c;
  c.bind = "0.0.0.0";
  SystemConfig sc;
  sc.run_slam = false;
  CollaborativeSystem system(sc);
  EXPECT_THROW(HttpServer server(system, c), ConfigError);
}

TEST(HttpExposure, CertificateAndKeyFilesThatCannotBeUsedAreNamed) {
  test::TempDir dir("cslam_http_exposure");
  const test::CertFiles good = test::make_self_signed(dir.str(), "good");
  const test::CertFiles other = test::make_self_signed(dir.str(), "other");
  std::ofstream(dir / "junk.pem") << "not a certificate\n";
  const std::string token = "a-token-of-24-characters";
  const auto tls = [&](const std::string& cert, const std::string& key) {
    return config_error({"--http-bind", "0.0.0.0", "--http-token", token, "--http-cert", cert, "--http-key", key});
  };
  EXPECT_EQ(tls(good.cert, good.key), "");
  EXPECT_NE(tls(dir / "missing.crt", good.key).find(dir / "missing.crt"), std::string::npos);
  EXPECT_NE(tls(good.cert, dir / "missing.key").find(dir / "missing.key"), std::string::npos);
  const std::string junk = tls(dir / "junk.pem", good.key);
  EXPECT_NE(junk.find(dir / "junk.pem"), std::string::npos) << junk;
  EXPECT_NE(junk.find("not a PEM certificate"), std::string::npos) << junk;
  EXPECT_NE(tls(good.cert, dir / "junk.pem").find(dir / "junk.pem"), std::string::npos);
  const std::string mismatch = tls(good.cert, other.key);
  EXPECT_NE(mismatch.find(other.key), std::string::npos) << mismatch;
  EXPECT_NE(mismatch.find("does not belong"), std::string::npos) << mismatch;
  EXPECT_NE(config_error({"--http-cert", good.cert}).find("go together"), std::string::npos);
  // The token from a file (kept out of the process list).
  std::ofstream(dir / "token") << "  " << token << "  \nsecond line ignored\n";
  EXPECT_EQ(parse({"--http-token-file", dir / "token"}).token, token);
  EXPECT_NE(config_error({"--http-token-file", dir / "none"}).find(dir / "none"), std::string::npos);
}

}  // namespace
}  // namespace cslam::http
