// The HTTP API of cslam-server against a real CollaborativeSystem (SLAM off, frames counted):
// status JSON schema, per-client view, metrics, and the 404 / 400 / 401 / 403 / 503 paths.
#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include "core/error.h"
#include "geometry/camera.h"
#include "server/http/http_server.h"
#include "system/collaborative_system.h"
// After every Eigen include: <resolv.h> (pulled in by httplib.h) defines a macro _res.
#include <httplib.h>
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
  for (const char* key : {"id", "frames_received", "frames_processed", "frames_dropped", "keyframes", "map_points", "group",
                          "queue_depth"})
    EXPECT_TRUE(a.at(key).is_number_integer()) << key;
  for (const char* key : {"fps", "input_fps"}) EXPECT_TRUE(a.at(key).is_number()) << key;
  for (const char* key : {"name", "connection", "tracking"}) EXPECT_TRUE(a.at(key).is_string()) << key;
  EXPECT_TRUE(a.contains("bandwidth_mbps"));
  EXPECT_EQ(a["id"], 1);
  EXPECT_EQ(a["name"], "alpha");
  EXPECT_EQ(a["frames_received"], 3);
  EXPECT_EQ(j["clients"][1]["name"], "beta");
  EXPECT_EQ(j["clients"][1]["frames_received"], 2);
  EXPECT_FALSE(a.contains("pose"));  // the pose is in /api/clients/{id}
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
  EXPECT_NE(metrics->body.find("cslam_frames_received_total{client=\"1\",name=\"alpha\"} 3"), std::string::npos) << metrics->body;
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

TEST_F(HttpApiTest, PostBeyondLoopbackNeedsAToken) {
  HttpConfig c;
  c.bind = "0.0.0.0";
  auto server = serve(c);
  auto cli = client(*server);
  expect_json_error(cli.Post("/api/reconstruction", "", "text/plain"), 403);
  const auto status = cli.Get("/api/status");
  ASSERT_TRUE(status);
  EXPECT_EQ(status->status, 200);  // reads stay open without a token
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
