#include "server/http/dense_routes.h"

#include <charconv>
#include <functional>
#include <memory>
#include <mutex>

#include "cloud/ply_io.h"
#include "dense/mesh_lod.h"
#include "dense/reconstructor.h"
#include "dense/trajectory_recon.h"
#include "navmap/map_server_io.h"
#include "server/dense/dense_products.h"
#include "server/dense/dense_service.h"
// After every Eigen include: <resolv.h> (pulled in by httplib.h) defines a macro _res.
#include "server/http/json_reply.h"

namespace cslam::http {
namespace {

using server::DenseService;
using server::encode_csm1;
using server::largest_group;
using server::submaps_by_group;

// Products of one view version, at most kMaxEntries kept (the oldest dropped).
template <typename T>
class ProductCache {
 public:
  template <typename Make>
  std::shared_ptr<const T> get(const std::string& key, std::uint64_t version, Make make) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      for (const auto& e : entries_)
        if (e.key == key && e.version == version) return e.bytes;
    }
    auto bytes = std::make_shared<const T>(make());  // outside the lock: may take a while
    std::lock_guard<std::mutex> lock(mutex_);
    if (entries_.size() >= kMaxEntries) entries_.erase(entries_.begin());
    entries_.push_back(Entry{key, version, bytes});
    return bytes;
  }

 private:
  static constexpr std::size_t kMaxEntries = 8;
  struct Entry {
    std::string key;
    std::uint64_t version;
    std::shared_ptr<const T> bytes;
  };
  std::mutex mutex_;
  std::vector<Entry> entries_;
};

std::optional<long> strict_long(const std::string& v) {
  long x = 0;
  const auto [end, ec] = std::from_chars(v.data(), v.data() + v.size(), x);
  if (ec != std::errc() || end != v.data() + v.size() || v.empty()) return std::nullopt;
  return x;
}

// The group a request names (?group=G), or the largest one; nullopt after replying with an error.
std::optional<int> requested_group(const httplib::Request& req, httplib::Response& res, const DenseMapView& view) {
  if (!req.has_param("group")) {
    const int g = largest_group(view);
    if (g < 0) json_error(res, 404, "the dense map has no submap yet");
    return g < 0 ? std::nullopt : std::optional<int>(g);
  }
  const auto g = strict_long(req.get_param_value("group"));
  if (!g || *g < -1 || *g > (1L << 30)) {
    json_error(res, 400, "parameter group must be an integer group id, got '" + req.get_param_value("group") + "'");
    return std::nullopt;
  }
  const auto groups = submaps_by_group(view);
  if (!groups.count(int(*g))) {
    json_error(res, 404, "the dense map has no submap in group " + std::to_string(*g));
    return std::nullopt;
  }
  return int(*g);
}

nlohmann::json pose_json(const SE3& T) {
  const auto& t = T.translation();
  const auto& q = T.rotation();
  return {t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w()};
}

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::size_t(p * double(v.size() - 1) + 0.5)];
}

nlohmann::json dense_status_json(const DenseService* dense) {
  if (!dense) return {{"enabled", false}};
  const auto st = dense->stats();
  const auto view = dense->view();
  return {{"enabled", true},
          {"version", view->version},
          {"submaps", view->submaps.size()},
          {"memory_bytes", {{"meshes", view->mesh_bytes}, {"volumes", view->volume_bytes}}},
          {"keyframes_received", st.keyframes_received},
          {"keyframes_integrated", st.integrated},
          {"queue", st.queue},
          {"queue_dropped", st.queue_dropped},
          {"pending", st.pending},
          {"stale_meshes", view->stale_meshes},
          {"distorted_submaps", view->distorted_submaps},
          {"settled", st.queue == 0 && view->settled()},
          {"reintegrated", st.reintegrated},
          {"submaps_moved", st.moved},
          {"culled", st.culled},
          {"missing_images", st.missing_images},
          {"integrate_ms", {{"p50", percentile(st.integrate_ms, 0.5)}, {"max", percentile(st.integrate_ms, 1.0)}}},
          {"cpu_ms", st.integrate_cpu_ms},
          {"last_correction_s", st.last_correction_s},
          {"store",
           {{"keyframes", st.store.keyframes},
            {"payload_bytes", st.store.payload_bytes},
            {"file_bytes", st.store.file_bytes},
            {"max_bytes", st.store.max_bytes},
            {"stored", st.stored},
            {"refused_full", st.store_refused_full},
            {"errors", st.store_errors},
            {"last_error", st.store.last_error}}}};
}

bool not_modified(const httplib::Request& req, httplib::Response& res, const std::string& etag) {
  res.set_header("ETag", etag);
  res.set_header("Cache-Control", "no-cache");
  if (req.get_header_value("If-None-Match") != etag) return false;
  res.status = 304;
  return true;
}

using Req = httplib::Request;
using Res = httplib::Response;

// What the dense handlers read: the service (null: the dense map is off) and the products built
// from its views (meshes and PLY files in one cache, navigation maps in another).
struct DenseContext {
  const DenseService* dense;
  std::shared_ptr<ProductCache<std::string>> products;
  std::shared_ptr<ProductCache<NavMaps>> nav;
};

using DenseHandler = void (*)(const DenseContext&, const Req&, Res&);

// false after replying 503 (the dense map is off).
bool dense_on(const DenseContext& ctx, Res& res) {
  if (!ctx.dense) json_error(res, 503, "the dense map is off (cslam-server --no-dense)");
  return ctx.dense != nullptr;
}

void get_status(const DenseContext& ctx, const Req&, Res& res) { json_reply(res, dense_status_json(ctx.dense)); }

nlohmann::json submap_json(const DenseSubmapView& sm) {
  return {{"id", sm.id},
          {"client", sm.client},
          {"version", sm.version},
          {"pose_version", sm.pose_version},
          {"T_world_submap", pose_json(sm.T_world_submap)},
          {"keyframes", sm.keyframes.size()},
          {"vertices", sm.mesh ? sm.mesh->vertices.size() : std::size_t(0)},
          {"triangles", sm.mesh ? sm.mesh->triangles.size() : std::size_t(0)},
          {"mesh_url", "/api/dense/submaps/" + std::to_string(sm.id) + "/mesh.bin"}};
}

nlohmann::json group_index_json(int group, const std::vector<const DenseSubmapView*>& submaps) {
  nlohmann::json list = nlohmann::json::array();
  std::vector<int> clients;
  for (const DenseSubmapView* sm : submaps) {
    if (std::find(clients.begin(), clients.end(), int(sm->client)) == clients.end()) clients.push_back(sm->client);
    list.push_back(submap_json(*sm));
  }
  return {{"group", group}, {"clients", clients}, {"submaps", std::move(list)}};
}

void get_submap_index(const DenseContext& ctx, const Req& req, Res& res) {
  if (!dense_on(ctx, res)) return;
  const auto view = ctx.dense->view();
  std::optional<long> only;
  if (req.has_param("group")) {
    only = strict_long(req.get_param_value("group"));
    if (!only)
      return json_error(res, 400, "parameter group must be an integer, got '" + req.get_param_value("group") + "'");
  }
  const std::string etag = "\"" + std::to_string(view->version) + (only ? "-" + std::to_string(*only) : "") + "\"";
  if (not_modified(req, res, etag)) return;
  nlohmann::json groups = nlohmann::json::array();
  for (const auto& [group, submaps] : submaps_by_group(*view))
    if (!only || group == *only) groups.push_back(group_index_json(group, submaps));
  const nlohmann::json body = {{"version", view->version}, {"groups", std::move(groups)}};
  res.set_content(body.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace), "application/json");
}

// ?lod=0|1|2 (0 when absent); nullopt after a 400.
std::optional<long> requested_lod(const Req& req, Res& res) {
  if (!req.has_param("lod")) return 0;
  const auto l = strict_long(req.get_param_value("lod"));
  if (!l || *l < 0 || *l > 2) {
    json_error(res, 400, "parameter lod must be 0, 1 or 2");
    return std::nullopt;
  }
  return l;
}

void get_submap_mesh(const DenseContext& ctx, const Req& req, Res& res) {
  if (!dense_on(ctx, res)) return;
  const auto id = strict_long(req.matches[1]);
  const auto lod = requested_lod(req, res);
  if (!lod) return;
  const auto view = ctx.dense->view();
  const DenseSubmapView* sm = nullptr;
  for (const auto& v : view->submaps)
    if (id && long(v.id) == *id) sm = &v;
  if (!sm) return json_error(res, 404, "no submap " + std::string(req.matches[1]) + " (removed, or not yet)");
  if (!sm->mesh) return json_error(res, 404, "submap " + std::string(req.matches[1]) + " has no mesh yet");
  const std::string etag = "\"" + std::to_string(sm->version) + "-" + std::to_string(*lod) + "\"";
  if (not_modified(req, res, etag)) return;
  const std::string key = "csm-" + std::to_string(sm->id) + "-" + std::to_string(*lod);
  const auto bytes = ctx.products->get(key, sm->version, [&] {
    if (*lod == 0) return encode_csm1(*sm->mesh, std::uint32_t(sm->version));
    return encode_csm1(simplify_by_clustering(*sm->mesh, sm->voxel_size * float(1 << *lod)),
                       std::uint32_t(sm->version));
  });
  res.set_content(*bytes, "application/octet-stream");
}

void send_download(Res& res, const std::string& name, const std::string& bytes, const char* type) {
  res.set_header("Content-Disposition", "attachment; filename=\"" + name + "\"");
  res.set_header("Cache-Control", "no-store");
  res.set_content(bytes, type);
}

// A group's fused cloud or mesh as PLY, built once per view version.
void send_group_ply(const DenseContext& ctx, const Req& req, Res& res, bool mesh) {
  if (!dense_on(ctx, res)) return;
  const auto view = ctx.dense->view();
  const auto group = requested_group(req, res, *view);
  if (!group) return;
  const auto submaps = submaps_by_group(*view).at(*group);
  const std::string key = std::string(mesh ? "mesh-" : "cloud-") + std::to_string(*group);
  const auto bytes = ctx.products->get(key, view->version, [&]() -> std::string {
    try {
      return mesh ? ply_mesh_bytes(server::group_mesh(submaps)) : ply_bytes(server::group_cloud(submaps));
    } catch (const std::invalid_argument&) {
      return {};
    }
  });
  if (bytes->empty()) return json_error(res, 404, "group " + std::to_string(*group) + " has no dense surface yet");
  const std::string name = std::string(mesh ? "dense_mesh_" : "dense_cloud_") + std::to_string(*group) + ".ply";
  send_download(res, name, *bytes, "application/octet-stream");
}

void get_cloud_ply(const DenseContext& ctx, const Req& req, Res& res) { send_group_ply(ctx, req, res, false); }
void get_mesh_ply(const DenseContext& ctx, const Req& req, Res& res) { send_group_ply(ctx, req, res, true); }

std::string base64(const std::int8_t* data, std::size_t n) {
  static const char* k = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  const auto* b = reinterpret_cast<const unsigned char*>(data);
  std::string out;
  out.reserve((n + 2) / 3 * 4);
  for (std::size_t i = 0; i < n; i += 3) {
    const unsigned v = unsigned(b[i]) << 16 | (i + 1 < n ? unsigned(b[i + 1]) << 8 : 0u) | (i + 2 < n ? b[i + 2] : 0u);
    out += k[(v >> 18) & 63];
    out += k[(v >> 12) & 63];
    out += i + 1 < n ? k[(v >> 6) & 63] : '=';
    out += i + 2 < n ? k[v & 63] : '=';
  }
  return out;
}

// Replies with the group's navigation maps, or an error; the maps are built once per version.
void with_nav_maps(const DenseContext& ctx, const Req& req, Res& res,
                   const std::function<void(int, const NavMaps&)>& reply) {
  if (!dense_on(ctx, res)) return;
  const auto view = ctx.dense->view();
  const auto group = requested_group(req, res, *view);
  if (!group) return;
  const auto maps = ctx.nav->get("nav-" + std::to_string(*group), view->version,
                                 [&] { return server::group_nav_maps(submaps_by_group(*view).at(*group)); });
  reply(*group, *maps);
}

void get_occupancy_json(const DenseContext& ctx, const Req& req, Res& res) {
  with_nav_maps(ctx, req, res, [&](int group, const NavMaps& m) {
    if (m.grid.empty()) return json_error(res, 404, "no occupancy grid yet: " + m.grid_error);
    json_reply(
        res,
        {{"group", group},
         {"resolution", m.grid.resolution},
         {"width", m.grid.width},
         {"height", m.grid.height},
         {"T_world_grid", pose_json(m.grid.T_world_grid)},
         {"up", {m.up.x(), m.up.y(), m.up.z()}},
         {"floor", m.floor},
         {"cells",
          {{"occupied", m.stats.cells_occupied}, {"free", m.stats.cells_free}, {"unknown", m.stats.cells_unknown}}},
         {"data", base64(m.grid.cells.data(), m.grid.cells.size())}});
  });
}

void get_occupancy_pgm(const DenseContext& ctx, const Req& req, Res& res) {
  with_nav_maps(ctx, req, res, [&](int group, const NavMaps& m) {
    if (m.grid.empty()) return json_error(res, 404, "no occupancy grid yet: " + m.grid_error);
    send_download(res, "occupancy_" + std::to_string(group) + ".pgm", to_pgm(m.grid), "image/x-portable-graymap");
  });
}

void get_occupancy_yaml(const DenseContext& ctx, const Req& req, Res& res) {
  with_nav_maps(ctx, req, res, [&](int group, const NavMaps& m) {
    if (m.grid.empty()) return json_error(res, 404, "no occupancy grid yet: " + m.grid_error);
    const std::string g = std::to_string(group);
    send_download(res, "occupancy_" + g + ".yaml", to_map_yaml(m.grid, "occupancy_" + g + ".pgm"), "text/yaml");
  });
}

void get_octomap(const DenseContext& ctx, const Req& req, Res& res) {
  with_nav_maps(ctx, req, res, [&](int group, const NavMaps& m) {
    if (m.octomap_bt.empty()) return json_error(res, 404, "no OctoMap yet: " + m.octomap_error);
    send_download(res, "octomap_" + std::to_string(group) + ".bt", m.octomap_bt, "application/octet-stream");
  });
}

}  // namespace

void add_dense_status(const DenseService* dense, nlohmann::json& status, std::string& metrics) {
  const nlohmann::json j = dense_status_json(dense);
  status["dense"] = j;
  if (!dense) return;
  const auto line = [&metrics](const char* name, const char* type, const nlohmann::json& v, const char* help) {
    metrics += std::string("# HELP ") + name + " " + help + "\n# TYPE " + name + " " + type + "\n" + name + " " +
               v.dump() + "\n";
  };
  line("cslam_dense_submaps", "gauge", j["submaps"], "TSDF submaps of the live dense map");
  line("cslam_dense_queue", "gauge", j["queue"], "keyframes waiting for the dense worker");
  line("cslam_dense_pending", "gauge", j["pending"], "keyframes waiting to be integrated");
  line("cslam_dense_stale_meshes", "gauge", j["stale_meshes"], "open submaps whose mesh lags their volume");
  line("cslam_dense_distorted_submaps", "gauge", j["distorted_submaps"], "submaps waiting to be re-integrated");
  line("cslam_dense_keyframes_integrated_total", "counter", j["keyframes_integrated"], "keyframes fused into submaps");
  line("cslam_dense_queue_dropped_total", "counter", j["queue_dropped"], "keyframes the full dense queue turned away");
  line("cslam_dense_reintegrations_total", "counter", j["reintegrated"], "submaps rebuilt after their keyframes moved");
  line("cslam_dense_integrate_ms_p50", "gauge", j["integrate_ms"]["p50"], "integration time per keyframe (ms, median)");
  line("cslam_dense_store_keyframes", "gauge", j["store"]["keyframes"], "keyframes in the image store");
  line("cslam_dense_store_bytes", "gauge", j["store"]["payload_bytes"], "image bytes in the store");
  line("cslam_dense_store_refused_full_total", "counter", j["store"]["refused_full"],
       "keyframe images refused: store full");
  line("cslam_dense_store_errors_total", "counter", j["store"]["errors"], "failed store writes");
}

HttpServer::HeldFramesSource held_frames_source(const DenseService* dense) {
  return [dense](int group) -> std::optional<HttpServer::HeldFrames> {
    if (!dense) return std::nullopt;
    auto keyframes = std::make_shared<const std::vector<KeyframePose>>(dense->group_keyframes(group));
    if (keyframes->empty()) return std::nullopt;
    HttpServer::HeldFrames held;
    std::map<ClientId, DatasetPoses> per_client;  // for the estimate: poses and the camera
    for (const KeyframePose& k : *keyframes) {
      auto [it, fresh] = per_client.try_emplace(k.id.client);
      if (fresh)
        if (const auto stored = dense->stored_keyframe(k.id)) it->second.camera = stored->camera;
      it->second.poses.push_back({0.0, k.T_world_cam});
    }
    for (auto& [client, source] : per_client) held.estimate_inputs.push_back(std::move(source));
    held.reconstruct = [dense, keyframes](const DenseConfig& config, const DenseProgressCallback& progress) {
      DenseReconstructor recon(config);
      DenseProgress p;
      p.total = int(keyframes->size());
      for (const KeyframePose& k : *keyframes) {
        if (const auto stored = dense->stored_keyframe(k.id)) {
          if (recon.integrate(k.T_world_cam, stored->images.bgr, stored->images.depth, stored->camera).used) ++p.used;
        } else {
          recon.count_skipped(SkipReason::kNoImage);
        }
        ++p.done;
        if (progress) progress(p);
      }
      return recon.finish();
    };
    return held;
  };
}

void add_dense_routes(httplib::Server& server, const DenseService* dense) {
  const DenseContext context{dense, std::make_shared<ProductCache<std::string>>(),
                             std::make_shared<ProductCache<NavMaps>>()};
  const std::pair<const char*, DenseHandler> routes[] = {
      {"/api/dense/status", get_status},
      {"/api/dense/submaps", get_submap_index},
      {R"(/api/dense/submaps/(\d+)/mesh\.bin)", get_submap_mesh},
      {"/api/dense/cloud.ply", get_cloud_ply},
      {"/api/dense/mesh.ply", get_mesh_ply},
      {"/api/dense/occupancy.json", get_occupancy_json},
      {"/api/dense/occupancy.pgm", get_occupancy_pgm},
      {"/api/dense/occupancy.yaml", get_occupancy_yaml},
      {"/api/dense/octomap.bt", get_octomap},
  };
  for (const auto& [pattern, handler] : routes)
    server.Get(pattern, [context, f = handler](const Req& req, Res& res) { f(context, req, res); });
}

}  // namespace cslam::http
