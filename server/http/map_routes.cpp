#include "server/http/map_routes.h"

#include <fstream>
#include <sstream>

#include "core/error.h"
#include "core/log.h"
#include "server/http/json_reply.h"

namespace cslam::http {

namespace {

using Req = httplib::Request;
using Res = httplib::Response;

const char* const kLoadBodyError = "body must be JSON {\"file\": \"NAME\"} (a file in the state folder's import/)";

void get_snapshot(MapStore& store, Res& res) {
  const auto path = store.snapshot_file();
  if (!path) return json_error(res, 404, "no snapshot written yet (POST /api/map/snapshot writes one)");
  std::ifstream in(*path, std::ios::binary);
  if (!in) return json_error(res, 404, "snapshot file " + *path + " cannot be read");
  std::ostringstream ss;
  ss << in.rdbuf();
  res.set_header("Cache-Control", "no-store");
  res.set_header("Content-Disposition", "attachment; filename=\"map.snapshot\"");
  res.set_content(ss.str(), "application/octet-stream");
}

void get_status(MapStore& store, Res& res) { json_reply(res, nlohmann::json::parse(store.stats_json())); }

void post_snapshot(MapStore& store, Res& res) {
  const std::string error = store.write_now(30.0);
  if (!error.empty()) return json_error(res, 503, "snapshot not written: " + error);
  json_reply(res, nlohmann::json::parse(store.stats_json()));
}

void post_load(MapStore& store, const std::string& token, const Req& req, Res& res) {
  if (token.empty()) return json_error(res, 403, "POST /api/map/load needs the server to run with --http-token");
  nlohmann::json body;
  try {
    body = nlohmann::json::parse(req.body);
  } catch (const std::exception&) {
    return json_error(res, 400, kLoadBodyError);
  }
  if (!body.is_object() || !body.contains("file") || !body["file"].is_string())
    return json_error(res, 400, kLoadBodyError);
  try {
    const std::size_t n = store.load(body["file"].get<std::string>());
    json_reply(res, {{"loaded_clients", n}});
  } catch (const InputError& e) {
    json_error(res, 422, e.what());
  }
}

}  // namespace

void add_map_routes(httplib::Server& server, MapStore& store, const std::string& token) {
  server.Get("/api/map/snapshot", [&store](const Req&, Res& res) { get_snapshot(store, res); });
  server.Get("/api/map/status", [&store](const Req&, Res& res) { get_status(store, res); });
  server.Post("/api/map/snapshot", [&store](const Req&, Res& res) { post_snapshot(store, res); });
  server.Post("/api/map/load", [&store, token](const Req& req, Res& res) { post_load(store, token, req, res); });
}

}  // namespace cslam::http
