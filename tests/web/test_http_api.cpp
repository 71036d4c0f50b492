// The HTTP API of cslam-server against a real CollaborativeSystem (SLAM off, frames counted):
// status JSON schema, per-client view, metrics, and the 404 / 400 / 401 / 503 paths.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include <opencv2/core.hpp>

#include "common/run_program.h"
#include "core/error.h"
#include "geometry/camera.h"
#include "server/http/http_server.h"
#include "server/http/map_routes.h"
#include "system/collaborative_system.h"
// After every Eigen include: <resolv.h> (pulled in by httplib.h) defines a macro _res.
#include <httplib.h>
#include "server/http/json_reply.h"
#include <nlohmann/json.hpp>

namespace cslam::http {
namespace {

using nlohmann::json;

class HttpApiTest : public ::testing::Test {
 protected:
  static SystemConfig system_config() {
    SystemConfig c;
    c.run_slam = false;
    return c;
  }
  void SetUp() override {
    const PinholeCamera cam = camera_tum_fr1();
    system_.add_client({1, "alpha", cam});
    system_.add_client({2, "beta", cam});
    for (std::uint64_t seq = 0; seq < 3; ++seq)
      for (ClientId id : {ClientId(1), ClientId(2)}) {
        if (id == 2 && seq == 2) continue;  // beta: two frames
        RgbdFrame f;
        f.client = id;
        f.seq = seq;
        f.timestamp = 1.0 + 0.1 * double(seq);
        f.bgr = cv::Mat(cam.height, cam.width, CV_8UC3, cv::Scalar(10, 20, 30));
        f.depth = cv::Mat(cam.height, cam.width, CV_16UC1, cv::Scalar(5000));
        ASSERT_TRUE(system_.submit(std::move(f)));
      }
    system_.finish();  // every frame consumed: the counts below are exact
  }
  // Starts an HTTP server on a free loopback port.
  std::unique_ptr<HttpServer> serve(HttpConfig c = {}) {
    c.port = 0;
    c.web_root = std::string(CSLAM_SOURCE_DIR) + "/web";
    auto s = std::make_unique<HttpServer>(system_, c);
    EXPECT_TRUE(s->start());
    return s;
  }
  static httplib::Client client(const HttpServer& s) { return httplib::Client("127.0.0.1", s.port()); }

  CollaborativeSystem system_{system_config()};
};

void expect_json_error(const httplib::Result& r, int status) {
  ASSERT_TRUE(r) << "no response";
  EXPECT_EQ(r->status, status) << r->body;
  EXPECT_NE(r->get_header_value("Content-Type").find("application/json"), std::string::npos);
  const json j = json::parse(r->body);
  ASSERT_TRUE(j.contains("error")) << r->body;
  EXPECT_TRUE(j["error"].is_string());
  EXPECT_FALSE(j["error"].get<std::string>().empty());
}

TEST_F(HttpApiTest, StatusJsonSchema) {
  auto server = serve();
  auto cli = client(*server);
  const auto r = cli.Get("/api/status");
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200);
  const json j = json::parse(r->body);
  EXPECT_EQ(j.at("server"), "cslam-server");
  EXPECT_TRUE(j.at("version").is_string());
  EXPECT_TRUE(j.at("uptime_s").is_number());
  EXPECT_GE(j.at("uptime_s").get<double>(), 0.0);
  EXPECT_TRUE(j.at("fusion_events").is_number_integer());
  ASSERT_TRUE(j.at("clients").is_array());
  ASSERT_EQ(j["clients"].size(), 2u);
  const json& a = j["clients"][0];
  for (const char* key : {"id", "frames_received", "frames_processed", "frames_dropped", "keyframes", "map_points",
                          "group", "queue_depth"})
    EXPECT_TRUE(a.at(key).is_number_integer()) << key;
  for (const char* key : {"fps", "input_fps"}) EXPECT_TRUE(a.at(key).is_number()) << key;
  for (const char* key : {"name", "connection", "tracking"}) EXPECT_TRUE(a.at(key).is_string()) << key;
  EXPECT_TRUE(a.at("link").is_null());  // no network layer in this server
  EXPECT_EQ(a["id"], 1);
  EXPECT_EQ(a["name"], "alpha");
  EXPECT_EQ(a["frames_received"], 3);
  EXPECT_EQ(j["clients"][1]["name"], "beta");
  EXPECT_EQ(j["clients"][1]["frames_received"], 2);
  // Each robot's pose (the viewer places its camera with it; 1a034b0).
  ASSERT_TRUE(a.contains("pose"));
  EXPECT_EQ(a["pose"].at("position").size(), 3u);
  EXPECT_EQ(a["pose"].at("quaternion").size(), 4u);
}

TEST_F(HttpApiTest, ClientByIdHasPoseAndUnknownIdIs404) {
  auto server = serve();
  auto cli = client(*server);
  const auto r = cli.Get("/api/clients/2");
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200);
  const json j = json::parse(r->body);
  EXPECT_EQ(j.at("name"), "beta");
  ASSERT_EQ(j.at("pose").at("position").size(), 3u);
  ASSERT_EQ(j.at("pose").at("quaternion").size(), 4u);
  expect_json_error(cli.Get("/api/clients/99"), 404);
  expect_json_error(cli.Get("/api/clients/abc"), 404);
  expect_json_error(cli.Get("/api/nothing/here"), 404);
  expect_json_error(cli.Get("/api/reconstruction/r77"), 404);
  expect_json_error(cli.Get("/api/reconstruction/r77/cloud.ply"), 404);
}

TEST_F(HttpApiTest, BadParametersAre400WithAMessage) {
  auto server = serve();
  auto cli = client(*server);
  expect_json_error(cli.Get("/api/trajectories?format=xml"), 400);
  expect_json_error(cli.Get("/api/trajectories?client=abc"), 400);
  expect_json_error(cli.Get("/api/trajectories?client=1x"), 400);
  expect_json_error(cli.Get("/api/map/points?group=x"), 400);
  expect_json_error(cli.Get("/api/map/points?format=png"), 400);
  expect_json_error(cli.Post("/api/reconstruction?voxel=-1", "", "text/plain"), 400);
  // Well-formed but unknown: 404.
  expect_json_error(cli.Get("/api/trajectories?client=99"), 404);
  expect_json_error(cli.Get("/api/map/points?group=12345"), 404);
  const auto msg = json::parse(cli.Get("/api/trajectories?format=xml")->body)["error"].get<std::string>();
  EXPECT_NE(msg.find("format"), std::string::npos) << msg;
}

TEST_F(HttpApiTest, TrajectoriesPointsEventsAndMetrics) {
  auto server = serve();
  auto cli = client(*server);
  const auto tum = cli.Get("/api/trajectories?client=all&format=tum");
  ASSERT_TRUE(tum);
  EXPECT_EQ(tum->status, 200);
  EXPECT_EQ(tum->body.rfind("# timestamp", 0), 0u);
  const auto traj = cli.Get("/api/trajectories?client=1");
  ASSERT_TRUE(traj);
  EXPECT_EQ(json::parse(traj->body).at("trajectories").size(), 1u);
  const auto points = cli.Get("/api/map/points?format=bin");
  ASSERT_TRUE(points);
  EXPECT_EQ(points->status, 200);
  EXPECT_EQ(points->body.size() % 16, 0u);
  EXPECT_EQ(points->get_header_value("X-Point-Count"), std::to_string(points->body.size() / 16));
  const auto events = cli.Get("/api/fusion/events");
  ASSERT_TRUE(events);
  EXPECT_TRUE(json::parse(events->body).at("events").is_array());
  const auto metrics = cli.Get("/metrics");
  ASSERT_TRUE(metrics);
  EXPECT_EQ(metrics->status, 200);
  EXPECT_NE(metrics->body.find("# TYPE cslam_frames_received_total counter"), std::string::npos);
  EXPECT_NE(metrics->body.find("cslam_frames_received_total{client=\"1\",name=\"alpha\"} 3"), std::string::npos)
      << metrics->body;
  // Exactly one state line is 1 per client (SLAM off: frames count as tracked).
  EXPECT_NE(metrics->body.find("cslam_tracking_state{client=\"2\",state=\"tracking\"} 1"), std::string::npos)
      << metrics->body;
  EXPECT_NE(metrics->body.find("cslam_tracking_state{client=\"2\",state=\"lost\"} 0"), std::string::npos);
  EXPECT_NE(metrics->body.find("cslam_fusion_events_total 0"), std::string::npos);
}

TEST_F(HttpApiTest, ReconstructionWithoutImagesIs503) {
  auto server = serve();
  auto cli = client(*server);
  expect_json_error(cli.Post("/api/reconstruction", "", "text/plain"), 503);
}

TEST_F(HttpApiTest, TokenRequiredOnEveryApiRequest) {
  HttpConfig c;
  c.token = "s3cret";
  auto server = serve(c);
  auto cli = client(*server);
  expect_json_error(cli.Get("/api/status"), 401);
  expect_json_error(cli.Get("/metrics"), 401);
  expect_json_error(cli.Post("/api/reconstruction", "", "text/plain"), 401);
  expect_json_error(cli.Get("/api/status", {{"Authorization", "Bearer wrong"}}), 401);
  const auto ok = cli.Get("/api/status", {{"Authorization", "Bearer s3cret"}});
  ASSERT_TRUE(ok);
  EXPECT_EQ(ok->status, 200);
  // The page itself carries no data and loads without the token (it asks for it).
  const auto page = cli.Get("/");
  ASSERT_TRUE(page);
  EXPECT_EQ(page->status, 200);
  EXPECT_NE(page->body.find("<html"), std::string::npos);
}

// Beyond loopback the token is mandatory (docs/security.md, "HTTP beyond loopback"): a server
// without one is a configuration error, and with --http-insecure (plain HTTP) every API request,
// reads included, needs it. (Before, only POST did and every GET was open.)
TEST_F(HttpApiTest, BeyondLoopbackEveryApiRequestNeedsTheToken) {
  HttpConfig c;
  c.bind = "0.0.0.0";
  c.insecure = true;
  EXPECT_THROW(HttpServer server(system_, c), ConfigError);
  c.token = "a-token-of-24-characters";
  auto server = serve(c);
  auto cli = client(*server);
  expect_json_error(cli.Get("/api/status"), 401);
  expect_json_error(cli.Get("/api/trajectories?client=all&format=tum"), 401);
  expect_json_error(cli.Post("/api/reconstruction", "", "text/plain"), 401);
  const auto status = cli.Get("/api/status", {{"Authorization", "Bearer a-token-of-24-characters"}});
  ASSERT_TRUE(status);
  EXPECT_EQ(status->status, 200);
}

TEST_F(HttpApiTest, StatusExtraAddsToStatusAndMetrics) {
  HttpConfig c;
  c.port = 0;
  c.web_root = std::string(CSLAM_SOURCE_DIR) + "/web";
  HttpServer server(system_, c);
  server.set_status_extra([](json& status, std::string& metrics) {
    status["dense"] = {{"volumes", 2}};
    metrics += "cslam_dense_volumes 2\n";
  });
  ASSERT_TRUE(server.start());
  auto cli = client(server);
  const auto r = cli.Get("/api/status");
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200);
  EXPECT_EQ(json::parse(r->body).at("dense").at("volumes"), 2);
  const auto m = cli.Get("/metrics");
  ASSERT_TRUE(m);
  EXPECT_NE(m->body.find("cslam_dense_volumes 2\n"), std::string::npos);
  EXPECT_NE(m->body.find("cslam_status_extra_errors_total 0"), std::string::npos);
}

TEST(StatusLinkTest, RateOverTheWindowAndRatioOfTheCounters) {
  NetClientStatus net;
  net.counters = {{"bytes_received", 4000}, {"raw_bytes", 20000}, {"frames_light", 7}};
  std::deque<RateSample> samples{{10.0, 0, 0, 1000}};
  json j = link_json(net, samples);
  EXPECT_TRUE(j.at("bytes_per_s").is_null());  // one sample: no rate yet
  EXPECT_DOUBLE_EQ(j.at("compression_ratio").get<double>(), 5.0);
  EXPECT_EQ(j.at("frames_light"), 7);
  EXPECT_EQ(j.at("bytes_received"), 4000);
  EXPECT_EQ(j.at("raw_bytes"), 20000);
  samples.push_back({12.0, 0, 0, 4000});
  j = link_json(net, samples);
  EXPECT_DOUBLE_EQ(j.at("bytes_per_s").get<double>(), 1500.0);
  samples.push_back({13.0, 0, 0, 10});  // a counter that went back (a new session): no rate, not a negative one
  j = link_json(net, samples);
  EXPECT_TRUE(j.at("bytes_per_s").is_null());
  net.counters.clear();  // nothing received yet
  j = link_json(net, {});
  EXPECT_DOUBLE_EQ(j.at("compression_ratio").get<double>(), 0.0);
  EXPECT_TRUE(j.at("bytes_per_s").is_null());
}

TEST_F(HttpApiTest, StatusCarriesEachClientsLinkFromTheReceiverCounters) {
  NetStatusBoard board;
  auto net = std::make_shared<NetStatus>();
  net->clients[1].id = 1;
  net->clients[1].connection = "active";
  net->clients[1].counters = {{"bytes_received", 1000}, {"raw_bytes", 9000}, {"frames_light", 2}};
  board.publish(net);
  HttpConfig c;
  c.port = 0;
  c.web_root = std::string(CSLAM_SOURCE_DIR) + "/web";
  HttpServer server(system_, c);
  server.set_network_status(&board);
  ASSERT_TRUE(server.start());
  const json j = json::parse(client(server).Get("/api/status")->body);
  const json& alpha = j.at("clients").at(0);
  ASSERT_TRUE(alpha.at("link").is_object()) << alpha.dump();
  EXPECT_DOUBLE_EQ(alpha["link"].at("compression_ratio").get<double>(), 9.0);
  EXPECT_EQ(alpha["link"].at("frames_light"), 2);
  EXPECT_TRUE(j.at("clients").at(1).at("link").is_null());  // beta has no session in the receiver's counters
}

TEST_F(HttpApiTest, ThrowingStatusExtraIsCountedAndStatusStillServed) {
  StatusCache cache(system_, {});
  int calls = 0;
  cache.set_extra([&calls](json& status, std::string& metrics) {
    ++calls;
    status["dense"] = "half-written";
    metrics += "cslam_half 1\n";
    if (calls == 1) throw std::runtime_error("dense board gone");
    status["bad"] = std::string("\xff\xfe");  // not UTF-8: refused as well, never in a reply
  });
  cache.refresh();
  auto s = cache.get();
  EXPECT_FALSE(s->status.contains("dense"));  // the contribution's partial edits are dropped
  EXPECT_EQ(s->metrics.find("cslam_half"), std::string::npos);
  EXPECT_NE(s->metrics.find("cslam_status_extra_errors_total 1"), std::string::npos);
  EXPECT_EQ(json::parse(s->status_body).at("clients").size(), 2u);
  cache.refresh();
  s = cache.get();
  EXPECT_FALSE(s->status.contains("bad"));
  EXPECT_NE(s->metrics.find("cslam_status_extra_errors_total 2"), std::string::npos);
  EXPECT_EQ(json::parse(s->status_body).at("status_extra_errors"), 2);
}

// Raw HTTP/1.1 over a socket: the request line goes out byte for byte (no client-side encoding).
std::pair<int, std::string> raw_get(int port, const std::string& target, const std::string& method = "GET") {
  httplib::Client cli("127.0.0.1", port);
  cli.set_url_encode(false);
  const auto r = method == "GET" ? cli.Get(target) : cli.Post(target, "", "text/plain");
  if (!r) return {0, ""};
  return {r->status, r->body};
}

// Item 4 of hardening round 2: bytes that are not UTF-8 in an id or a parameter were a 500 (the
// JSON library threw while the error reply echoed them). Every route with a path or query
// parameter: a 400 whose JSON body echoes the bytes as \xHH.
TEST_F(HttpApiTest, BadBytesInIdsAndParametersAre400WithASanitisedEcho) {
  auto server = serve();
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"GET", "/api/reconstruction/%ff"},
      {"GET", "/api/reconstruction/%ff/cloud.ply"},
      {"GET", "/api/reconstruction/%ff%fe/mesh.ply"},
      {"GET", "/api/clients/%ff%fe"},
      {"GET", "/api/clients/a%00b"},
      {"GET", "/api/trajectories?format=%ff%fe"},
      {"GET", "/api/trajectories?client=%ff"},
      {"GET", "/api/trajectories?%ff=1"},
      {"GET", "/api/map/points?group=%ff"},
      {"GET", "/api/map/points?format=%c0%af"},  // overlong '/'
      {"GET", "/api/map/snapshot?x=%ed%a0%80"},  // a surrogate
      {"GET", "/api/nothing/%ff"},
      {"GET", "/metrics?x=%ff"},
      {"POST", "/api/reconstruction?voxel=%ff"},
      {"POST", "/api/reconstruction?group=%fe"},
  };
  for (const auto& [method, target] : cases) {
    const auto [status, body] = raw_get(server->port(), target, method);
    EXPECT_EQ(status, 400) << method << " " << target << ": " << body;
    json j;
    ASSERT_NO_THROW(j = json::parse(body)) << target << ": " << body;
    const std::string error = j.value("error", "");
    EXPECT_TRUE(error.find("\\x") != std::string::npos) << target << ": " << error;
    EXPECT_NE(error.find("UTF-8"), std::string::npos) << target << ": " << error;
  }
  // Valid UTF-8 that names nothing is a plain 404 echoing it.
  const auto [status, body] = raw_get(server->port(), "/api/clients/%c3%a9");
  EXPECT_EQ(status, 404);
  EXPECT_NE(json::parse(body).value("error", "").find("\xc3\xa9"), std::string::npos) << body;
  // The status still answers.
  EXPECT_EQ(client(*server).Get("/api/status")->status, 200);
}

// The error path itself cannot throw: a handler throwing with bad bytes in its message.
TEST_F(HttpApiTest, ErrorRepliesNeverThrowOnBadBytes) {
  HttpConfig c;
  c.port = 0;
  c.web_root = std::string(CSLAM_SOURCE_DIR) + "/web";
  HttpServer server(system_, c);
  server.routes_server().Get("/test/throw", [](const httplib::Request&, httplib::Response&) {
    throw std::runtime_error("bad \xff\xfe bytes");
  });
  server.routes_server().Get("/test/reply", [](const httplib::Request&, httplib::Response& res) {
    json_reply(res, {{"name", std::string("\xff")}});
  });
  ASSERT_TRUE(server.start());
  auto cli = client(server);
  const auto thrown = cli.Get("/test/throw");
  ASSERT_TRUE(thrown);
  EXPECT_EQ(thrown->status, 500);
  EXPECT_NE(json::parse(thrown->body).value("error", "").find("bad \\xff\\xfe bytes"), std::string::npos)
      << thrown->body;
  const auto replied = cli.Get("/test/reply");
  ASSERT_TRUE(replied);
  EXPECT_EQ(replied->status, 200);
  EXPECT_EQ(json::parse(replied->body).value("name", ""), "\xef\xbf\xbd");  // U+FFFD
  EXPECT_TRUE(is_clean_text("caf\xc3\xa9"));
  EXPECT_FALSE(is_clean_text("\xf4\x90\x80\x80"));  // above U+10FFFF
  EXPECT_EQ(sanitized(std::string(300, 'a'), 10), "aaaaaaaaaa...");
}

// Item 6 over HTTP: a request over --recon-max-mb is a 413 carrying the estimate.
TEST_F(HttpApiTest, ReconstructionOverTheBudgetIs413WithTheEstimate) {
  const test::TempDir temp("cslam_http_recon_datasets");
  const std::string dir = temp.str();
  std::filesystem::create_directories(dir + "/alpha");
  std::ofstream(dir + "/alpha/rgb.txt") << "# no images needed: refused before any is read\n";
  HttpConfig c;
  c.datasets_dir = dir;
  c.recon.max_mb = 50;
  auto server = serve(c);
  auto cli = client(*server);
  const auto r = cli.Post("/api/reconstruction?voxel=0.002&stride=1&mesh=1&group=" +
                              std::to_string(json::parse(cli.Get("/api/clients/1")->body).at("group").get<int>()),
                          "", "text/plain");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 413) << r->body;
  const json j = json::parse(r->body);
  EXPECT_GT(j.at("estimate_mb").get<double>(), 50.0);
  EXPECT_EQ(j.at("max_mb"), 50.0);
  EXPECT_NE(j.at("error").get<std::string>().find("--recon-max-mb"), std::string::npos);
  json status;
  for (int i = 0; i < 500; ++i) {  // the status is refreshed 5 times per second
    status = json::parse(cli.Get("/api/status")->body);
    if (status.at("reconstruction").at("refused_over_budget") == 1) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  EXPECT_EQ(status.at("reconstruction").at("refused_over_budget"), 1);
  EXPECT_NE(cli.Get("/metrics")->body.find("cslam_recon_jobs_total{outcome=\"refused_over_budget\"} 1"),
            std::string::npos);
}

// Item 7: snapshot writes in /metrics and /api/health (a store reporting failures).
class FakeStore : public MapStore {
 public:
  std::optional<std::string> snapshot_file() const override { return std::nullopt; }
  std::string write_now(double) override { return "no"; }
  std::size_t load(const std::string&) override { return 0; }
  std::string stats_json() const override { return stats.dump(); }
  json stats = {{"state_dir", "/state"},     {"written", 3},    {"failed", 0}, {"failing_for_s", 0.0},
                {"last_success_age_s", 4.5}, {"last_error", ""}};
};

TEST_F(HttpApiTest, SnapshotFailuresAreInMetricsAndTurnHealthUnhealthy) {
  FakeStore store;
  HttpConfig c;
  c.port = 0;
  c.web_root = std::string(CSLAM_SOURCE_DIR) + "/web";
  c.health_snapshot_failing_s = 60;
  {
    HttpServer server(system_, c);
    server.set_map_store(&store);
    ASSERT_TRUE(server.start());
    auto cli = client(server);
    const auto metrics = cli.Get("/metrics")->body;
    EXPECT_NE(metrics.find("cslam_snapshot_writes_total{result=\"ok\"} 3"), std::string::npos) << metrics;
    EXPECT_NE(metrics.find("cslam_snapshot_writes_total{result=\"failed\"} 0"), std::string::npos);
    EXPECT_NE(metrics.find("cslam_snapshot_last_success_age_seconds 4.5"), std::string::npos);
    const auto health = cli.Get("/api/health");
    EXPECT_EQ(health->status, 200) << health->body;
    EXPECT_EQ(json::parse(health->body).at("status"), "ok");
  }
  store.stats["failed"] = 7;
  store.stats["failing_for_s"] = 61.0;
  store.stats["last_error"] = "No space left on device";
  HttpServer server(system_, c);
  server.set_map_store(&store);
  ASSERT_TRUE(server.start());
  auto cli = client(server);
  const auto metrics = cli.Get("/metrics")->body;
  EXPECT_NE(metrics.find("cslam_snapshot_writes_total{result=\"failed\"} 7"), std::string::npos) << metrics;
  EXPECT_NE(metrics.find("cslam_snapshot_failing_seconds 61"), std::string::npos) << metrics;
  const auto health = cli.Get("/api/health");
  ASSERT_TRUE(health);
  EXPECT_EQ(health->status, 503) << health->body;
  const json h = json::parse(health->body);
  EXPECT_EQ(h.at("status"), "unhealthy");
  ASSERT_EQ(h.at("reasons").size(), 1u);
  EXPECT_NE(h["reasons"][0].get<std::string>().find("No space left on device"), std::string::npos);
}

TEST(HttpConfigTest, BadPortIsAConfigError) {
  CliArgs cli("t", "t");
  declare_options(cli);
  const char* argv[] = {"t", "--http", "80a"};
  ASSERT_TRUE(cli.parse(3, const_cast<char**>(argv)));
  EXPECT_THROW(config_from(cli), ConfigError);
  CliArgs off("t", "t");
  declare_options(off);
  const char* argv2[] = {"t", "--http", "off"};
  ASSERT_TRUE(off.parse(3, const_cast<char**>(argv2)));
  EXPECT_FALSE(config_from(off).enabled);
}

}  // namespace
}  // namespace cslam::http
