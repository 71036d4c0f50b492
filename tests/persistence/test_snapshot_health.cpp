// Item 7 of hardening round 2: snapshot failures were only in /api/map/status and the log, so an
// alerting system never heard of a full disk. With a real StateStore and HttpServer (SLAM off):
// /metrics carries successes, failures and the age of the last good snapshot, and /api/health
// turns 503 (with the reason) once writes have failed for longer than the threshold, and back.
#include <filesystem>
#include <thread>

#include <gtest/gtest.h>

#include "common/run_program.h"
#include "proto/snapshot_file.h"
#include "server/http/http_server.h"
#include "server/state_store.h"
// After every Eigen include: <resolv.h> (pulled in by httplib.h) defines a macro _res.
#include <httplib.h>
#include <nlohmann/json.hpp>

namespace cslam {
namespace {

SystemConfig no_slam() {
  SystemConfig c;
  c.run_slam = false;
  return c;
}

// Polls GET path until pred(response) holds (generous deadline; no timing assert).
template <class Pred>
httplib::Result wait_for(httplib::Client& cli, const std::string& path, Pred pred) {
  for (int i = 0; i < 1000; ++i) {
    auto r = cli.Get(path);
    if (r && pred(*r)) return r;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return cli.Get(path);
}

bool has(const std::string& body, const std::string& line) { return body.find(line) != std::string::npos; }

TEST(SnapshotHealth, FailuresAreInMetricsAndHealthTurnsUnhealthyThenRecovers) {
  test::TempDir dir("cslam_snapshot_health");
  const std::string state = dir / "state";
  CollaborativeSystem system(no_slam());
  server::StateStoreConfig sc;
  sc.dir = state;
  sc.interval_s = 0;
  server::StateStore store(sc, system);
  http::HttpConfig hc;
  hc.port = 0;
  hc.web_root = std::string(CSLAM_SOURCE_DIR) + "/web";
  hc.health_snapshot_failing_s = 0.3;
  http::HttpServer http_server(system, hc);
  http_server.set_map_store(&store);
  ASSERT_TRUE(http_server.start());
  httplib::Client cli("127.0.0.1", http_server.port());

  ASSERT_TRUE(store.write());
  auto m = wait_for(cli, "/metrics",
                    [](const auto& r) { return has(r.body, "cslam_snapshot_writes_total{result=\"ok\"} 1"); });
  EXPECT_TRUE(has(m->body, "cslam_snapshot_writes_total{result=\"failed\"} 0")) << m->body;
  EXPECT_TRUE(has(m->body, "cslam_snapshot_last_success_age_seconds ")) << m->body;
  EXPECT_TRUE(has(m->body, "cslam_snapshot_failing_seconds 0\n")) << m->body;
  EXPECT_EQ(cli.Get("/api/health")->status, 200);

  // The disk "fills": the temporary file cannot be created (a folder is in its way; root ignores
  // permissions, so a read-only folder would not do in a container).
  const std::string blocker = snapshot::current_path(state) + ".tmp";
  std::filesystem::create_directories(blocker);
  EXPECT_FALSE(store.write());
  auto h = wait_for(cli, "/api/health", [](const auto& r) { return r.status == 503; });
  ASSERT_TRUE(h);
  EXPECT_EQ(h->status, 503) << h->body;
  const auto j = nlohmann::json::parse(h->body);
  EXPECT_EQ(j.at("status"), "unhealthy");
  ASSERT_EQ(j.at("reasons").size(), 1u);
  EXPECT_TRUE(has(j["reasons"][0].get<std::string>(), "map snapshots have failed for")) << h->body;
  m = cli.Get("/metrics");
  EXPECT_TRUE(has(m->body, "cslam_snapshot_writes_total{result=\"failed\"} 1")) << m->body;
  EXPECT_TRUE(has(m->body, "cslam_snapshot_writes_total{result=\"ok\"} 1")) << m->body;
  EXPECT_FALSE(has(m->body, "cslam_snapshot_failing_seconds 0\n")) << m->body;
  const auto status = nlohmann::json::parse(cli.Get("/api/status")->body);
  EXPECT_EQ(status.at("snapshots").at("failed"), 1);
  EXPECT_TRUE(status.at("snapshots").at("last_success_age_s").is_number());

  // Space again: the next write succeeds and health recovers.
  std::filesystem::remove_all(blocker);
  ASSERT_TRUE(store.write());
  h = wait_for(cli, "/api/health", [](const auto& r) { return r.status == 200; });
  EXPECT_EQ(h->status, 200) << h->body;
  EXPECT_TRUE(has(cli.Get("/metrics")->body, "cslam_snapshot_writes_total{result=\"ok\"} 2"));
}

TEST(SnapshotHealth, WithoutAStateFolderHealthIsOkAndMetricsSayNothing) {
  CollaborativeSystem system(no_slam());
  server::StateStore store(server::StateStoreConfig{}, system);
  http::HttpConfig hc;
  hc.port = 0;
  hc.web_root = std::string(CSLAM_SOURCE_DIR) + "/web";
  http::HttpServer http_server(system, hc);
  http_server.set_map_store(&store);
  ASSERT_TRUE(http_server.start());
  httplib::Client cli("127.0.0.1", http_server.port());
  const auto h = cli.Get("/api/health");
  ASSERT_TRUE(h);
  EXPECT_EQ(h->status, 200);
  EXPECT_EQ(nlohmann::json::parse(h->body).at("snapshots"), "off");
  EXPECT_FALSE(has(cli.Get("/metrics")->body, "cslam_snapshot_writes_total"));
}

}  // namespace
}  // namespace cslam
