// The reconstruction routes of the JSON API (api_routes.h): POST /api/reconstruction starts a
// dense reconstruction job of a group, GET /api/reconstruction/ID reports it, .../cloud.ply and
// .../mesh.ply download its products.
#include <filesystem>
#include <optional>

#include "dense/trajectory_recon.h"
#include "io/dataset_camera.h"
#include "server/http/api_routes.h"
// After every Eigen include: <resolv.h> (pulled in by httplib.h) defines a macro _res.
#include "server/http/api_params.h"

namespace cslam::http {
namespace {

using Req = httplib::Request;
using Res = httplib::Response;

void reply_started(const ApiContext& ctx, Res& res, int group, const ReconStart& started) {
  if (started.outcome == ReconStart::Outcome::kBusy) return json_error(res, 409, started.message);
  if (started.outcome == ReconStart::Outcome::kOverBudget)
    return json_reply(res,
                      {{"error", started.message},
                       {"status", 413},
                       {"estimate_mb", started.estimate.total_mb()},
                       {"max_mb", ctx.jobs.config().max_mb}},
                      413);
  json_reply(res,
             {{"job", started.id},
              {"group", group},
              {"status_url", "/api/reconstruction/" + started.id},
              {"estimate_mb", started.estimate.total_mb()}},
             202);
}

// ?group=G, or the largest group; nullopt after replying 404 / 409.
std::optional<int> recon_group(const CachedState& state, const Req& req, Res& res) {
  int group = -1;
  if (const auto g = int_param(req, "group", -1, 1 << 30)) {
    group = int(*g);
    if (!state.groups.count(GroupId::from_value(group))) {
      json_error(res, 404, "unknown group " + std::to_string(group));
      return std::nullopt;
    }
    return group;
  }
  for (const auto& [g, members] : state.groups)
    if (group < 0 || members.size() > state.groups.at(GroupId::from_value(group)).size()) group = g.value();
  if (group < 0) {
    json_error(res, 409, "no client yet");
    return std::nullopt;
  }
  return group;
}

// ?voxel=, ?stride=, ?mesh=; throws std::invalid_argument or ConfigError (400).
DenseConfig recon_config(const Req& req) {
  DenseConfig dc;
  dc.voxel_size = double_param(req, "voxel", 0.002, 1.0).value_or(0.02);
  dc.stride = int(int_param(req, "stride", 1, 64).value_or(4));
  dc.build_mesh = int_param(req, "mesh", 0, 1).value_or(1) == 1;
  dc.tsdf.voxel_size = float(dc.voxel_size);
  dc.tsdf.truncation = float(4 * dc.voxel_size);
  dc.threads = 1;  // leave the cores to SLAM
  dc.tsdf.threads = 1;
  dc.validate();
  return dc;
}

// Without --datasets-dir: the keyframes the server keeps.
void start_from_held_frames(const ApiContext& ctx, Res& res, int group, const DenseConfig& dc) {
  if (!ctx.held_frames)
    return json_error(res, 503,
                      "reconstruction needs the clients' images: the dense map is off (--no-dense) and "
                      "there is no --datasets-dir");
  const auto held = ctx.held_frames(group);
  if (!held) return json_error(res, 409, "group " + std::to_string(group) + " has no stored keyframes yet");
  reply_started(ctx, res, group,
                ctx.jobs.start(group, held->reconstruct, estimate_recon_memory(held->estimate_inputs, dc), dc));
}

// The client's dataset folder under --datasets-dir: DIR/<name>, DIR/robot_K or DIR/client_K (the
// first with an rgb.txt), or "".
std::string dataset_dir(const CachedState& state, const std::filesystem::path& root, ClientId id) {
  const std::string name = state.clients.count(id) ? state.clients.at(id).value("name", "") : "";
  std::vector<std::filesystem::path> candidates;
  if (!name.empty()) candidates.push_back(root / name);
  candidates.push_back(root / ("robot_" + std::to_string(id)));
  candidates.push_back(root / ("client_" + std::to_string(id)));
  for (const auto& p : candidates)
    if (std::filesystem::exists(p / "rgb.txt")) return p.string();
  return "";
}

// With --datasets-dir: the group's clients' folders at their current poses.
void start_from_datasets(const ApiContext& ctx, const CachedState& state, Res& res, int group, const DenseConfig& dc) {
  const std::filesystem::path root(ctx.config.datasets_dir);
  std::vector<DatasetPoses> sources;
  for (ClientId id : state.groups.at(GroupId::from_value(group))) {
    const auto traj = state.trajectories.find(id);
    if (traj == state.trajectories.end() || traj->second.empty()) continue;
    const std::string dir = dataset_dir(state, root, id);
    if (dir.empty())
      return json_error(res, 409, "no dataset folder for client " + std::to_string(id) + " under " + root.string());
    sources.push_back({dir, traj->second, dataset_camera(dir, ctx.config.recon_camera).camera});
  }
  if (sources.empty()) return json_error(res, 409, "group " + std::to_string(group) + " has no poses yet");
  reply_started(ctx, res, group, ctx.jobs.start(group, std::move(sources), dc));
}

void post_reconstruction(const ApiContext& ctx, const Req& req, Res& res) {
  const auto state = ctx.cache.get();
  const auto group = recon_group(*state, req, res);
  if (!group) return;
  const DenseConfig dc = recon_config(req);
  if (ctx.config.datasets_dir.empty()) return start_from_held_frames(ctx, res, *group, dc);
  start_from_datasets(ctx, *state, res, *group, dc);
}

void get_reconstruction(const ApiContext& ctx, const Req& req, Res& res) {
  const auto v = ctx.jobs.view(req.matches[1]);
  if (!v) return json_error(res, 404, "unknown reconstruction job " + std::string(req.matches[1]));
  nlohmann::json j = {{"job", v->id},
                      {"group", v->group},
                      {"state", v->state},
                      {"progress", v->progress},
                      {"frames_done", v->frames_done},
                      {"frames_total", v->frames_total},
                      {"frames_used", v->frames_used},
                      {"points", v->points},
                      {"triangles", v->triangles},
                      {"message", v->message},
                      {"elapsed_s", v->elapsed_s},
                      {"estimate_mb", v->estimate_mb},
                      {"peak_growth_mb", v->peak_growth_mb},
                      {"bytes_held", v->bytes_held}};
  if (v->state == "done") {
    j["cloud_url"] = "/api/reconstruction/" + v->id + "/cloud.ply";
    if (v->triangles > 0) j["mesh_url"] = "/api/reconstruction/" + v->id + "/mesh.ply";
  }
  json_reply(res, j);
}

void send_ply(const ApiContext& ctx, const Req& req, Res& res, bool mesh) {
  const std::string id = req.matches[1];
  const auto v = ctx.jobs.view(id);
  if (!v) return json_error(res, 404, "unknown reconstruction job " + id);
  const auto bytes = mesh ? ctx.jobs.mesh_ply(id) : ctx.jobs.cloud_ply(id);
  if (!bytes)
    return json_error(res, v->state == "done" ? 404 : 409,
                      "job " + id + " is " + v->state + (v->state == "done" ? " without a mesh" : ""));
  res.set_header("Content-Disposition", "attachment; filename=\"" + id + (mesh ? "_mesh" : "_cloud") + ".ply\"");
  res.set_content(*bytes, "application/octet-stream");
}

void get_cloud_ply(const ApiContext& ctx, const Req& req, Res& res) { send_ply(ctx, req, res, false); }
void get_mesh_ply(const ApiContext& ctx, const Req& req, Res& res) { send_ply(ctx, req, res, true); }

}  // namespace

std::vector<ApiRoute> recon_routes() {
  using M = ApiRoute::Method;
  return {
      {M::kPost, "/api/reconstruction", post_reconstruction, true},
      {M::kGet, R"(/api/reconstruction/([^/]+))", get_reconstruction, true},
      {M::kGet, R"(/api/reconstruction/([^/]+)/cloud\.ply)", get_cloud_ply, true},
      {M::kGet, R"(/api/reconstruction/([^/]+)/mesh\.ply)", get_mesh_ply, true},
  };
}

}  // namespace cslam::http
