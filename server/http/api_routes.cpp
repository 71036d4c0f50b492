// The JSON API of the HTTP server (see README "HTTP API"): every handler reads one immutable
// StatusCache snapshot or the reconstruction job table; none calls into the SLAM system.
#include <cstring>
#include <filesystem>
#include <optional>
#include <sstream>

#include "core/error.h"
#include "dense/trajectory_recon.h"
#include "io/dataset_camera.h"
#include "server/http/http_server.h"
// After every Eigen include: <resolv.h> (pulled in by httplib.h) defines a macro _res.
#include "server/http/json_reply.h"

namespace cslam::http {
namespace {

// A strictly parsed integer parameter: nullopt if absent; throws std::invalid_argument if malformed.
std::optional<long> int_param(const httplib::Request& req, const std::string& name, long lo, long hi) {
  if (!req.has_param(name.c_str())) return std::nullopt;
  const std::string v = req.get_param_value(name.c_str());
  std::size_t used = 0;
  long x = 0;
  try {
    x = std::stol(v, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (v.empty() || used != v.size() || x < lo || x > hi)
    throw std::invalid_argument("parameter " + name + " must be an integer in [" + std::to_string(lo) + ", " +
                                std::to_string(hi) + "], got '" + v + "'");
  return x;
}

std::optional<double> double_param(const httplib::Request& req, const std::string& name, double lo, double hi) {
  if (!req.has_param(name.c_str())) return std::nullopt;
  const std::string v = req.get_param_value(name.c_str());
  std::size_t used = 0;
  double x = 0;
  try {
    x = std::stod(v, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (v.empty() || used != v.size() || !(x >= lo && x <= hi))
    throw std::invalid_argument("parameter " + name + " must be a number in [" + std::to_string(lo) + ", " +
                                std::to_string(hi) + "], got '" + v + "'");
  return x;
}

std::string param_or(const httplib::Request& req, const char* name, const std::string& fallback) {
  return req.has_param(name) ? req.get_param_value(name) : fallback;
}

// Runs a handler body. Input is checked first (a request part that is not clean UTF-8 text is
// a 400 with a sanitised echo, before any handler can echo it); std::invalid_argument and
// ConfigError become a 400 with their message, anything else a 500. The error path cannot throw
// (json_error sanitises and catches).
template <typename F>
httplib::Server::Handler guarded(F f) {
  return [f](const httplib::Request& req, httplib::Response& res) {
    if (const auto bad = unclean_request_part(req)) return json_error(res, 400, *bad);
    for (std::size_t i = 1; i < req.matches.size(); ++i)
      if (!is_clean_text(req.matches[i].str()))
        return json_error(res, 400, "id is not valid UTF-8 text: '" + sanitized(req.matches[i].str()) + "'");
    try {
      f(req, res);
    } catch (const std::invalid_argument& e) {
      json_error(res, 400, e.what());
    } catch (const ConfigError& e) {
      json_error(res, 400, e.what());
    } catch (const std::exception& e) {
      json_error(res, 500, std::string("internal error: ") + e.what());
    } catch (...) {
      json_error(res, 500, "internal error");
    }
  };
}

void write_trajectory_json(nlohmann::json& out, ClientId id, int group, const Trajectory& t) {
  nlohmann::json poses = nlohmann::json::array();
  for (const StampedPose& p : t) {
    const auto& x = p.T_world_cam.translation();
    const auto& q = p.T_world_cam.rotation();
    poses.push_back({p.timestamp, x.x(), x.y(), x.z(), q.x(), q.y(), q.z(), q.w()});
  }
  out.push_back({{"client", id}, {"group", group}, {"poses", std::move(poses)}});
}

}  // namespace

void HttpServer::reply_started(httplib::Response& res, int group, const ReconStart& started) const {
  if (started.outcome == ReconStart::Outcome::kBusy) return json_error(res, 409, started.message);
  if (started.outcome == ReconStart::Outcome::kOverBudget)
    return json_reply(res, {{"error", started.message}, {"status", 413}, {"estimate_mb", started.estimate.total_mb()},
                            {"max_mb", jobs_.config().max_mb}}, 413);
  json_reply(res, {{"job", started.id}, {"group", group}, {"status_url", "/api/reconstruction/" + started.id},
                   {"estimate_mb", started.estimate.total_mb()}}, 202);
}

void HttpServer::api_routes() {
  httplib::Server& s = *server_;

  s.Get("/api/status", [this](const httplib::Request&, httplib::Response& res) {
    res.set_header("Cache-Control", "no-store");
    res.set_content(cache_.get()->status_body, "application/json");
  });

  s.Get(R"(/api/clients/([^/]+))", guarded([this](const httplib::Request& req, httplib::Response& res) {
    const auto state = cache_.get();
    const std::string id = req.matches[1];
    for (const auto& [cid, j] : state->clients)
      if (std::to_string(cid) == id) return json_reply(res, j);
    json_error(res, 404, "unknown client " + id);
  }));

  s.Get("/api/fusion/events", [this](const httplib::Request&, httplib::Response& res) {
    res.set_header("Cache-Control", "no-store");
    res.set_content(cache_.get()->events_body, "application/json");
  });

  s.Get("/api/trajectories", guarded([this](const httplib::Request& req, httplib::Response& res) {
    const auto state = cache_.get();
    const std::string client = param_or(req, "client", "all"), format = param_or(req, "format", "json");
    if (format != "tum" && format != "json") throw std::invalid_argument("format must be tum or json, got '" + format + "'");
    std::vector<ClientId> ids;
    if (client == "all") {
      for (const auto& [id, t] : state->trajectories) ids.push_back(id);
    } else {
      const long id = *int_param(req, "client", 0, 65535);
      if (!state->trajectories.count(ClientId(id))) return json_error(res, 404, "unknown client " + client);
      ids.push_back(ClientId(id));
    }
    auto group_of = [&state](ClientId id) {
      const auto it = state->group_of.find(id);
      return it == state->group_of.end() ? -1 : it->second;
    };
    if (format == "tum") {
      std::ostringstream o;
      o << "# timestamp x y z qx qy qz qw (camera-to-world, fused frame of each client's group)\n";
      for (ClientId id : ids) {
        o << "# client " << id << " group " << group_of(id) << "\n";
        for (const StampedPose& p : state->trajectories.at(id))
          if (tum_stamp_ok(p.timestamp)) o << format_tum_line(p) << "\n";
      }
      res.set_content(o.str(), "text/plain; charset=utf-8");
      return;
    }
    nlohmann::json list = nlohmann::json::array();
    for (ClientId id : ids) write_trajectory_json(list, id, group_of(id), state->trajectories.at(id));
    json_reply(res, {{"trajectories", std::move(list)}, {"pose_fields", {"t", "x", "y", "z", "qx", "qy", "qz", "qw"}}});
  }));

  s.Get("/api/map/points", guarded([this](const httplib::Request& req, httplib::Response& res) {
    const auto state = cache_.get();
    const std::string format = param_or(req, "format", "json");
    if (format != "bin" && format != "json") throw std::invalid_argument("format must be bin or json, got '" + format + "'");
    const auto group = int_param(req, "group", -1, 1 << 30);
    if (group && !state->groups.count(int(*group))) return json_error(res, 404, "unknown group " + std::to_string(*group));
    std::vector<const ViewerPoint*> points;
    std::vector<int> groups;
    for (const auto& [g, list] : state->points) {
      if (group && g != *group) continue;
      for (const ViewerPoint& p : *list) {
        points.push_back(&p);
        groups.push_back(g);
      }
    }
    res.set_header("X-Point-Count", std::to_string(points.size()));
    if (format == "bin") {  // 16 bytes per point, little-endian: float32 x y z, uint8 r g b, uint8 client
      std::string body(points.size() * 16, '\0');
      for (std::size_t i = 0; i < points.size(); ++i) {
        const ViewerPoint& p = *points[i];
        char* o = body.data() + i * 16;
        std::memcpy(o, &p.x, 4);
        std::memcpy(o + 4, &p.y, 4);
        std::memcpy(o + 8, &p.z, 4);
        const std::uint8_t tail[4] = {p.r, p.g, p.b, std::uint8_t(std::min<int>(p.client, 255))};
        std::memcpy(o + 12, tail, 4);
      }
      res.set_content(body, "application/octet-stream");
      return;
    }
    nlohmann::json list = nlohmann::json::array();
    for (std::size_t i = 0; i < points.size(); ++i) {
      const ViewerPoint& p = *points[i];
      list.push_back({p.x, p.y, p.z, p.r, p.g, p.b, p.client, groups[i]});
    }
    json_reply(res, {{"fields", {"x", "y", "z", "r", "g", "b", "client", "group"}}, {"points", std::move(list)}});
  }));

  s.Get("/metrics", [this](const httplib::Request&, httplib::Response& res) {
    res.set_content(cache_.get()->metrics, "text/plain; version=0.0.4; charset=utf-8");
  });

  // Healthy unless map snapshots have been failing for longer than the threshold (a full disk
  // an alerting system must hear of); 503 with the reasons otherwise.
  s.Get("/api/health", [this](const httplib::Request&, httplib::Response& res) {
    const auto state = cache_.get();
    nlohmann::json reasons = nlohmann::json::array();
    if (state->snapshots_on && state->snapshot_failing_for_s > config_.health_snapshot_failing_s)
      reasons.push_back("map snapshots have failed for " + std::to_string(int(state->snapshot_failing_for_s)) +
                        " s (threshold " + std::to_string(int(config_.health_snapshot_failing_s)) +
                        " s): " + state->snapshot_last_error);
    const bool healthy = reasons.empty();
    json_reply(res, {{"status", healthy ? "ok" : "unhealthy"}, {"reasons", reasons}, {"uptime_s", state->uptime_s},
                     {"snapshots", state->snapshots_on ? "on" : "off"}, {"snapshot_failing_for_s", state->snapshot_failing_for_s}},
               healthy ? 200 : 503);
  });

  s.Post("/api/reconstruction", guarded([this](const httplib::Request& req, httplib::Response& res) {
    const auto state = cache_.get();
    int group = -1;
    if (const auto g = int_param(req, "group", -1, 1 << 30)) {
      group = int(*g);
      if (!state->groups.count(group)) return json_error(res, 404, "unknown group " + std::to_string(group));
    } else {  // the largest group
      for (const auto& [g, members] : state->groups)
        if (group < 0 || members.size() > state->groups.at(group).size()) group = g;
      if (group < 0) return json_error(res, 409, "no client yet");
    }
    DenseConfig dc;
    dc.voxel_size = double_param(req, "voxel", 0.002, 1.0).value_or(0.02);
    dc.stride = int(int_param(req, "stride", 1, 64).value_or(4));
    dc.build_mesh = int_param(req, "mesh", 0, 1).value_or(1) == 1;
    dc.tsdf.voxel_size = float(dc.voxel_size);
    dc.tsdf.truncation = float(4 * dc.voxel_size);
    dc.threads = 1;  // leave the cores to SLAM
    dc.tsdf.threads = 1;
    dc.validate();  // ConfigError: 400
    if (config_.datasets_dir.empty()) {  // the keyframes the server keeps
      if (!held_frames_)
        return json_error(res, 503, "reconstruction needs the clients' images: the dense map is off (--no-dense) and "
                                    "there is no --datasets-dir");
      const auto held = held_frames_(group);
      if (!held) return json_error(res, 409, "group " + std::to_string(group) + " has no stored keyframes yet");
      return reply_started(res, group, jobs_.start(group, held->reconstruct, estimate_recon_memory(held->estimate_inputs, dc), dc));
    }
    std::vector<DatasetPoses> sources;
    for (ClientId id : state->groups.at(group)) {
      const auto traj = state->trajectories.find(id);
      if (traj == state->trajectories.end() || traj->second.empty()) continue;
      const std::filesystem::path root(config_.datasets_dir);
      const std::string name = state->clients.count(id) ? state->clients.at(id).value("name", "") : "";
      std::vector<std::filesystem::path> candidates;
      if (!name.empty()) candidates.push_back(root / name);
      candidates.push_back(root / ("robot_" + std::to_string(id)));
      candidates.push_back(root / ("client_" + std::to_string(id)));
      std::string dir;
      for (const auto& p : candidates)
        if (std::filesystem::exists(p / "rgb.txt")) {
          dir = p.string();
          break;
        }
      if (dir.empty()) return json_error(res, 409, "no dataset folder for client " + std::to_string(id) + " under " + root.string());
      sources.push_back({dir, traj->second, dataset_camera(dir, config_.recon_camera).camera});
    }
    if (sources.empty()) return json_error(res, 409, "group " + std::to_string(group) + " has no poses yet");
    reply_started(res, group, jobs_.start(group, std::move(sources), dc));
  }));

  s.Get(R"(/api/reconstruction/([^/]+))", guarded([this](const httplib::Request& req, httplib::Response& res) {
    const auto v = jobs_.view(req.matches[1]);
    if (!v) return json_error(res, 404, "unknown reconstruction job " + std::string(req.matches[1]));
    nlohmann::json j = {{"job", v->id},         {"group", v->group},          {"state", v->state},
                        {"progress", v->progress}, {"frames_done", v->frames_done}, {"frames_total", v->frames_total},
                        {"frames_used", v->frames_used}, {"points", v->points}, {"triangles", v->triangles},
                        {"message", v->message},   {"elapsed_s", v->elapsed_s},
                        {"estimate_mb", v->estimate_mb}, {"peak_growth_mb", v->peak_growth_mb}, {"bytes_held", v->bytes_held}};
    if (v->state == "done") {
      j["cloud_url"] = "/api/reconstruction/" + v->id + "/cloud.ply";
      if (v->triangles > 0) j["mesh_url"] = "/api/reconstruction/" + v->id + "/mesh.ply";
    }
    json_reply(res, j);
  }));

  auto download = [this](bool mesh) {
    return guarded([this, mesh](const httplib::Request& req, httplib::Response& res) {
      const std::string id = req.matches[1];
      const auto v = jobs_.view(id);
      if (!v) return json_error(res, 404, "unknown reconstruction job " + id);
      const auto bytes = mesh ? jobs_.mesh_ply(id) : jobs_.cloud_ply(id);
      if (!bytes) return json_error(res, v->state == "done" ? 404 : 409, "job " + id + " is " + v->state + (v->state == "done" ? " without a mesh" : ""));
      res.set_header("Content-Disposition", "attachment; filename=\"" + id + (mesh ? "_mesh" : "_cloud") + ".ply\"");
      res.set_content(*bytes, "application/octet-stream");
    });
  };
  s.Get(R"(/api/reconstruction/([^/]+)/cloud\.ply)", download(false));
  s.Get(R"(/api/reconstruction/([^/]+)/mesh\.ply)", download(true));
}

}  // namespace cslam::http
