// The /api/map routes of cslam-server on a real HttpServer and StateStore (SLAM off): download
// before and after a write, write on demand, load refused without a token, bad names refused.
#include <filesystem>

#include <gtest/gtest.h>

#include "common/run_program.h"
#include "proto/snapshot_file.h"
#include "server/http/http_server.h"
#include "server/http/map_routes.h"
#include "server/state_store.h"
// After every Eigen include: <resolv.h> (pulled in by httplib.h) defines a macro _res.
#include <httplib.h>
#include <nlohmann/json.hpp>

namespace cslam {
namespace {

struct Served {
  explicit Served(const std::string& state_dir, const std::string& token) {
    server::StateStoreConfig sc;
    sc.dir = state_dir;
    sc.interval_s = 0;  // on demand only
    store = std::make_unique<server::StateStore>(sc, system);
    http::HttpConfig hc;
    hc.port = 0;
    hc.token = token;
    hc.web_root = std::string(CSLAM_SOURCE_DIR) + "/web";
    http_server = std::make_unique<http::HttpServer>(system, hc);
    http::add_map_routes(http_server->routes_server(), *store, token);
    EXPECT_TRUE(http_server->start());
    store->start();
  }
  httplib::Client client(const std::string& token) const {
    httplib::Client c("127.0.0.1", http_server->port());
    if (!token.empty()) c.set_bearer_token_auth(token);
    return c;
  }
  static SystemConfig config() {
    SystemConfig c;
    c.run_slam = false;
    return c;
  }
  CollaborativeSystem system{config()};
  std::unique_ptr<server::StateStore> store;
  std::unique_ptr<http::HttpServer> http_server;
};

TEST(MapHttp, WriteOnDemandThenDownload) {
  test::TempDir dir("cslam_map_http");
  Served s(dir / "state", "");
  auto cli = s.client("");
  const auto before = cli.Get("/api/map/snapshot");
  ASSERT_TRUE(before);
  EXPECT_EQ(before->status, 404) << before->body;
  const auto write = cli.Post("/api/map/snapshot", "", "application/json");
  ASSERT_TRUE(write);
  ASSERT_EQ(write->status, 200) << write->body;
  EXPECT_EQ(nlohmann::json::parse(write->body)["written"], 1);
  const auto after = cli.Get("/api/map/snapshot");
  ASSERT_TRUE(after);
  ASSERT_EQ(after->status, 200);
  EXPECT_EQ(after->body, snapshot::read_bytes(snapshot::current_path(dir / "state")));
  EXPECT_EQ(after->body.rfind("CSLAMSNP", 0), 0u);  // decoding is tested with the codec (no SLAM types here)
  const auto status = cli.Get("/api/map/status");
  ASSERT_TRUE(status);
  EXPECT_EQ(nlohmann::json::parse(status->body)["failed"], 0);
}

TEST(MapHttp, LoadNeedsATokenAndAPlainName) {
  test::TempDir dir("cslam_map_http_load");
  {
    Served open(dir / "state", "");
    const auto r = open.client("").Post("/api/map/load", R"({"file": "a.snapshot"})", "application/json");
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 403) << r->body;
  }
  Served s(dir / "state", "secret");
  const auto anonymous = s.client("").Post("/api/map/load", R"({"file": "a.snapshot"})", "application/json");
  ASSERT_TRUE(anonymous);
  EXPECT_EQ(anonymous->status, 401);
  auto cli = s.client("secret");
  const auto traversal = cli.Post("/api/map/load", R"({"file": "../state/map.snapshot"})", "application/json");
  ASSERT_TRUE(traversal);
  EXPECT_EQ(traversal->status, 422) << traversal->body;
  const auto missing = cli.Post("/api/map/load", R"({"file": "none.snapshot"})", "application/json");
  ASSERT_TRUE(missing);
  EXPECT_EQ(missing->status, 422) << missing->body;
  EXPECT_NE(missing->body.find("none.snapshot"), std::string::npos) << missing->body;
  std::filesystem::create_directories(dir / "state/import");
  std::ofstream(dir / "state/import/bad.snapshot") << "not a snapshot";
  const auto bad = cli.Post("/api/map/load", R"({"file": "bad.snapshot"})", "application/json");
  ASSERT_TRUE(bad);
  EXPECT_EQ(bad->status, 422) << bad->body;
  EXPECT_NE(bad->body.find("not a cslam snapshot"), std::string::npos) << bad->body;
  const auto body = cli.Post("/api/map/load", "{", "application/json");
  ASSERT_TRUE(body);
  EXPECT_EQ(body->status, 400);
}

}  // namespace
}  // namespace cslam
