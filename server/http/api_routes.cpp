// The state routes of the JSON API (api_routes.h) and the registration of every API route.
#include "server/http/api_routes.h"

#include <algorithm>
#include <cstring>
#include <sstream>

#include "dense/trajectory_recon.h"
// After every Eigen include: <resolv.h> (pulled in by httplib.h) defines a macro _res.
#include "server/http/api_params.h"
#include "server/http/request_router.h"

namespace cslam::http {
namespace {

using Req = httplib::Request;
using Res = httplib::Response;

void get_status(const ApiContext& ctx, const Req&, Res& res) {
  res.set_header("Cache-Control", "no-store");
  res.set_content(ctx.cache.get()->status_body, "application/json");
}

void get_client(const ApiContext& ctx, const Req& req, Res& res) {
  const auto state = ctx.cache.get();
  const std::string id = req.matches[1];
  for (const auto& [cid, j] : state->clients)
    if (std::to_string(cid) == id) return json_reply(res, j);
  json_error(res, 404, "unknown client " + id);
}

void get_fusion_events(const ApiContext& ctx, const Req&, Res& res) {
  res.set_header("Cache-Control", "no-store");
  res.set_content(ctx.cache.get()->events_body, "application/json");
}

// ?client=all (the default) or one client id; nullopt after a 404.
std::optional<std::vector<ClientId>> trajectory_clients(const CachedState& state, const Req& req, Res& res) {
  const std::string client = param_or(req, "client", "all");
  std::vector<ClientId> ids;
  if (client == "all") {
    for (const auto& [id, t] : state.trajectories) ids.push_back(id);
    return ids;
  }
  const long id = *int_param(req, "client", 0, 65535);
  if (!state.trajectories.count(ClientId(id))) {
    json_error(res, 404, "unknown client " + client);
    return std::nullopt;
  }
  ids.push_back(ClientId(id));
  return ids;
}

int group_of(const CachedState& state, ClientId id) {
  const auto it = state.group_of.find(id);
  return it == state.group_of.end() ? -1 : it->second.value();
}

void reply_trajectories_tum(const CachedState& state, const std::vector<ClientId>& ids, Res& res) {
  std::ostringstream o;
  o << "# timestamp x y z qx qy qz qw (camera-to-world, fused frame of each client's group)\n";
  for (ClientId id : ids) {
    o << "# client " << id << " group " << group_of(state, id) << "\n";
    for (const StampedPose& p : state.trajectories.at(id))
      if (tum_stamp_ok(p.timestamp)) o << format_tum_line(p) << "\n";
  }
  res.set_content(o.str(), "text/plain; charset=utf-8");
}

nlohmann::json trajectory_json(ClientId id, int group, const Trajectory& t) {
  nlohmann::json poses = nlohmann::json::array();
  for (const StampedPose& p : t) {
    const auto& x = p.T_world_cam.translation();
    const auto& q = p.T_world_cam.rotation();
    poses.push_back({p.timestamp, x.x(), x.y(), x.z(), q.x(), q.y(), q.z(), q.w()});
  }
  return {{"client", id}, {"group", group}, {"poses", std::move(poses)}};
}

void reply_trajectories_json(const CachedState& state, const std::vector<ClientId>& ids, Res& res) {
  nlohmann::json list = nlohmann::json::array();
  for (ClientId id : ids) list.push_back(trajectory_json(id, group_of(state, id), state.trajectories.at(id)));
  json_reply(res, {{"trajectories", std::move(list)}, {"pose_fields", {"t", "x", "y", "z", "qx", "qy", "qz", "qw"}}});
}

void get_trajectories(const ApiContext& ctx, const Req& req, Res& res) {
  const auto state = ctx.cache.get();
  const std::string format = param_or(req, "format", "json");
  if (format != "tum" && format != "json")
    throw std::invalid_argument("format must be tum or json, got '" + format + "'");
  const auto ids = trajectory_clients(*state, req, res);
  if (!ids) return;
  if (format == "tum") return reply_trajectories_tum(*state, *ids, res);
  reply_trajectories_json(*state, *ids, res);
}

struct SelectedPoints {
  std::vector<const ViewerPoint*> points;
  std::vector<int> groups;  // of each point
};

SelectedPoints select_points(const CachedState& state, std::optional<long> group) {
  SelectedPoints out;
  for (const auto& [g, list] : state.points) {
    if (group && g.value() != *group) continue;
    for (const ViewerPoint& p : *list) {
      out.points.push_back(&p);
      out.groups.push_back(g.value());
    }
  }
  return out;
}

// 16 bytes per point, little-endian: float32 x y z, uint8 r g b, uint8 client.
void reply_points_bin(const SelectedPoints& selected, Res& res) {
  std::string body(selected.points.size() * 16, '\0');
  for (std::size_t i = 0; i < selected.points.size(); ++i) {
    const ViewerPoint& p = *selected.points[i];
    char* o = body.data() + i * 16;
    std::memcpy(o, &p.x, 4);
    std::memcpy(o + 4, &p.y, 4);
    std::memcpy(o + 8, &p.z, 4);
    const std::uint8_t tail[4] = {p.r, p.g, p.b, std::uint8_t(std::min<int>(p.client, 255))};
    std::memcpy(o + 12, tail, 4);
  }
  res.set_content(body, "application/octet-stream");
}

void reply_points_json(const SelectedPoints& selected, Res& res) {
  nlohmann::json list = nlohmann::json::array();
  for (std::size_t i = 0; i < selected.points.size(); ++i) {
    const ViewerPoint& p = *selected.points[i];
    list.push_back({p.x, p.y, p.z, p.r, p.g, p.b, p.client, selected.groups[i]});
  }
  json_reply(res, {{"fields", {"x", "y", "z", "r", "g", "b", "client", "group"}}, {"points", std::move(list)}});
}

void get_map_points(const ApiContext& ctx, const Req& req, Res& res) {
  const auto state = ctx.cache.get();
  const std::string format = param_or(req, "format", "json");
  if (format != "bin" && format != "json")
    throw std::invalid_argument("format must be bin or json, got '" + format + "'");
  const auto group = int_param(req, "group", -1, 1 << 30);
  if (group && !state->groups.count(GroupId::from_value(int(*group))))
    return json_error(res, 404, "unknown group " + std::to_string(*group));
  const SelectedPoints selected = select_points(*state, group);
  res.set_header("X-Point-Count", std::to_string(selected.points.size()));
  if (format == "bin") return reply_points_bin(selected, res);
  reply_points_json(selected, res);
}

void get_metrics(const ApiContext& ctx, const Req&, Res& res) {
  res.set_content(ctx.cache.get()->metrics, "text/plain; version=0.0.4; charset=utf-8");
}

// Healthy unless map snapshots have been failing for longer than the threshold (a full disk an
// alerting system must hear of); 503 with the reasons otherwise.
void get_health(const ApiContext& ctx, const Req&, Res& res) {
  const auto state = ctx.cache.get();
  const double threshold_s = ctx.config.health_snapshot_failing_s;
  nlohmann::json reasons = nlohmann::json::array();
  if (state->snapshots_on && state->snapshot_failing_for_s > threshold_s)
    reasons.push_back("map snapshots have failed for " + std::to_string(int(state->snapshot_failing_for_s)) +
                      " s (threshold " + std::to_string(int(threshold_s)) + " s): " + state->snapshot_last_error);
  const bool healthy = reasons.empty();
  json_reply(res,
             {{"status", healthy ? "ok" : "unhealthy"},
              {"reasons", reasons},
              {"uptime_s", state->uptime_s},
              {"snapshots", state->snapshots_on ? "on" : "off"},
              {"snapshot_failing_for_s", state->snapshot_failing_for_s}},
             healthy ? 200 : 503);
}

}  // namespace

std::vector<ApiRoute> state_routes() {
  using M = ApiRoute::Method;
  return {
      {M::kGet, "/api/status", get_status, false},
      {M::kGet, R"(/api/clients/([^/]+))", get_client, true},
      {M::kGet, "/api/fusion/events", get_fusion_events, false},
      {M::kGet, "/api/trajectories", get_trajectories, true},
      {M::kGet, "/api/map/points", get_map_points, true},
      {M::kGet, "/metrics", get_metrics, false},
      {M::kGet, "/api/health", get_health, false},
  };
}

void add_api_routes(httplib::Server& server, const ApiContext& context, const std::vector<ApiRoute>& routes) {
  for (const ApiRoute& route : routes) {
    httplib::Server::Handler handler = [context, f = route.handler](const Req& req, Res& res) { f(context, req, res); };
    if (route.guarded) handler = guarded(std::move(handler));
    if (route.method == ApiRoute::Method::kPost)
      server.Post(route.pattern, std::move(handler));
    else
      server.Get(route.pattern, std::move(handler));
  }
}

void HttpServer::api_routes() {
  const ApiContext context{cache_, jobs_, config_, held_frames_};
  add_api_routes(*server_, context, state_routes());
  add_api_routes(*server_, context, recon_routes());
}

}  // namespace cslam::http
