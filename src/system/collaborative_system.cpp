#include "system/collaborative_system.h"

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <shared_mutex>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/ids_json.h"
#include "core/log.h"
#include "frame/frame_check.h"
#include "geometry/camera.h"
#include "core/stats.h"
#include "eval/stats_json.h"
#include "system/loop_stats_json.h"
#include "system/pose_latency_json.h"
#include "system/client_pipeline.h"
#include "slam/features/orb_extractor.h"
#include "system/system_state.h"

namespace cslam {

const char* tracking_label(FrameFate state) { return state == FrameFate::kTracked ? "tracking" : to_string(state); }

struct CollaborativeSystem::Impl {
  SystemConfig config;
  std::shared_ptr<const Vocabulary> vocabulary;
  std::unique_ptr<FifoSlots> tracking_slots;  // before the clients: their workers hold slots
  std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now();
  mutable std::mutex mutex;  // guards the client table (not the clients' contents)
  std::map<ClientId, std::unique_ptr<ClientPipeline>> clients;
  std::unique_ptr<FusionManager> fusion;
  bool finished = false;

  // The fused group of the client's main map; an unfused client is labelled like its first map.
  GroupId group_of(ClientPipeline& p) const {
    if (!fusion || !p.slam()) return GroupId::from_value(p.info().id);  // counting-only pipelines
    auto map = p.slam()->main_map();
    const GroupId g = map ? fusion->group_of(map.get()) : GroupId();
    return g.valid() ? g : GroupId::of_map(p.info().id, 0);
  }

  // One client's pipeline, wired to fusion (keyframes in, fused groups out) the same way for a
  // newly registered client and for one restored from a snapshot.
  std::unique_ptr<ClientPipeline> make_pipeline(const ClientInfo& info) const {
    KeyFrameListener listener;
    std::function<GroupId(const Map*)> group_of_map;
    if (FusionManager* f = fusion.get()) {
      listener = [f](ClientId c, const std::shared_ptr<Map>& m, const KeyFramePtr& kf) { f->notify(c, m, kf); };
      group_of_map = [f](const Map* m) { return f->group_of(m); };
    }
    return std::make_unique<ClientPipeline>(info, config, vocabulary, std::move(listener), std::move(group_of_map),
                                            tracking_slots.get());
  }
};

CollaborativeSystem::CollaborativeSystem(SystemConfig config) : impl_(std::make_unique<Impl>()) {
  impl_->config = std::move(config);
  if (impl_->config.tracking_slots > 0 && !impl_->config.stepped)
    impl_->tracking_slots = std::make_unique<FifoSlots>(impl_->config.tracking_slots);
  if (impl_->config.run_slam) {
    const std::string path =
        impl_->config.vocabulary_path.empty() ? default_vocabulary_path() : impl_->config.vocabulary_path;
    impl_->vocabulary = std::make_shared<const Vocabulary>(Vocabulary::load(path));
    logger("system")->info("vocabulary {} loaded ({} words)", path, impl_->vocabulary->num_words());
    impl_->fusion = std::make_unique<FusionManager>(impl_->config.fusion, impl_->vocabulary);
    // An extractor reads what it takes from OpenCV (descriptor pattern, cv::resize's rounding)
    // once per process (~10 ms): made here first, so that a client's registration (on the
    // server's receiving thread) does not pay for it.
    OrbExtractor{};
  }
}

CollaborativeSystem::~CollaborativeSystem() { finish(); }

// A re-registering client must keep its projection and its depth units.
static bool same_camera(const PinholeCamera& a, const PinholeCamera& b) {
  return same_projection(a, b) && a.depth_factor == b.depth_factor;
}

void CollaborativeSystem::add_client(const ClientInfo& info) {
  info.camera.validate();
  std::lock_guard<std::mutex> lock(impl_->mutex);
  if (impl_->finished) throw std::logic_error("add_client after finish()");
  auto it = impl_->clients.find(info.id);
  if (it != impl_->clients.end()) {
    if (!same_camera(it->second->info().camera, info.camera))
      throw std::invalid_argument("client " + std::to_string(info.id) + " re-registered with a different camera");
    return;
  }
  impl_->clients.emplace(info.id, impl_->make_pipeline(info));
  logger("system")->info("client {} ('{}') registered, camera {} {}x{}", info.id, info.name, info.camera.name,
                         info.camera.width, info.camera.height);
}

std::size_t CollaborativeSystem::tracking_slot_waiters() const {
  return impl_->tracking_slots ? impl_->tracking_slots->waiting() : 0;
}

bool CollaborativeSystem::has_client(ClientId id) const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->clients.count(id) > 0;
}

bool CollaborativeSystem::submit(RgbdFrame frame) {
  ClientPipeline* pipeline = nullptr;
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    if (impl_->finished) return false;
    auto it = impl_->clients.find(frame.client);
    if (it == impl_->clients.end()) return false;
    pipeline = it->second.get();
  }
  // The frame's builder checked it (frame/frame_check.h); a malformed one here is a programming error.
  if (const std::string why = frame_problem(frame, pipeline->info().camera); !why.empty())
    throw std::invalid_argument("frame " + std::to_string(frame.seq) + " of client " + std::to_string(frame.client) +
                                ": " + why);
  // Pipelines are only destroyed in the destructor, after finish(): the pointer stays valid.
  return pipeline->submit(std::move(frame));
}

bool CollaborativeSystem::retire_client(ClientId id, const std::string& dir) {
  std::unique_ptr<ClientPipeline> pipeline;
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    auto it = impl_->clients.find(id);
    if (it == impl_->clients.end() || impl_->finished) return it == impl_->clients.end();
    const GroupId group = impl_->group_of(*it->second);
    for (const auto& [other, p] : impl_->clients)
      if (other != id && impl_->group_of(*p) == group) return false;  // fused: the map stays with its group
    pipeline = std::move(it->second);
    impl_->clients.erase(it);
  }
  pipeline->finish();  // no more frames can reach it: joins its worker and SLAM threads
  if (impl_->fusion && pipeline->slam()) {
    std::vector<const Map*> maps;
    for (const auto& m : pipeline->slam()->maps()) maps.push_back(m.get());
    impl_->fusion->forget(maps);
  }
  std::filesystem::create_directories(dir);
  const std::string name = std::to_string(id);
  write_tum_trajectory(dir + "/client_" + name + ".txt", pipeline->trajectory(), "client " + name + " (reclaimed)");
  if (pipeline->slam())
    write_tum_trajectory(dir + "/keyframes_" + name + ".txt", pipeline->keyframe_trajectory(),
                         "client " + name + " keyframes");
  const ClientSnapshot c = pipeline->snapshot();
  nlohmann::json j = {{"id", c.id},
                      {"name", c.name},
                      {"frames_submitted", c.frames_submitted},
                      {"frames_processed", c.frames_processed},
                      {"frames_rejected", c.frames_rejected},
                      {"frames_lost", c.frames_lost},
                      {"keyframes", c.keyframes},
                      {"map_points", c.map_points},
                      {"maps", c.maps},
                      {"reclaimed", true}};
  std::ofstream(dir + "/stats.json") << j.dump(2) << "\n";
  logger("system")->info("client {} retired: outputs in {}", id, dir);
  return true;
}

SystemSnapshot CollaborativeSystem::snapshot() const {
  SystemSnapshot s;
  std::lock_guard<std::mutex> lock(impl_->mutex);
  s.uptime_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - impl_->start).count();
  for (const auto& [id, p] : impl_->clients) {
    s.clients.push_back(p->snapshot());
    s.clients.back().group = impl_->group_of(*p);
  }
  if (impl_->fusion) {
    s.events = impl_->fusion->events();
    s.group_ba = impl_->fusion->group_ba_stats();
  }
  return s;
}

void CollaborativeSystem::finish() {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  if (impl_->finished) return;
  impl_->finished = true;
  for (auto& [id, p] : impl_->clients) p->finish();
  // Every keyframe is mapped now; let fusion look at the last ones, then stop it.
  if (impl_->fusion) impl_->fusion->finish();
  final_global_ba_locked();
}

void CollaborativeSystem::final_global_ba_locked() {
  if (impl_->config.slam.final_global_ba_iterations <= 0) return;
  // Maps fused with others are left as the group BA after their last fusion made them: a second
  // group BA at the end made the stepped synthetic demo worse (combined ATE 0.0066 -> 0.0080 m)
  // and fr1/desk K = 3 better (0.0164 -> 0.0154 m), so there is no case for it. The rest: one
  // global BA each.
  std::map<GroupId, int> maps_in_group;
  auto group_of = [this](const Map& m) { return impl_->fusion ? impl_->fusion->group_of(&m) : GroupId(); };
  for (const auto& [id, p] : impl_->clients)
    if (p->slam())
      for (const auto& m : p->slam()->maps())
        if (const GroupId g = group_of(*m); g.valid()) ++maps_in_group[g];
  auto fused = [&](const Map& m) {
    const GroupId g = group_of(m);
    return g.valid() && maps_in_group[g] > 1;
  };
  for (const auto& [id, p] : impl_->clients)
    if (p->slam()) p->slam()->final_global_ba(fused);
}

std::map<GroupId, std::vector<ClientId>> CollaborativeSystem::groups() const {
  std::map<GroupId, std::vector<ClientId>> out;
  std::lock_guard<std::mutex> lock(impl_->mutex);
  for (const auto& [id, p] : impl_->clients) out[impl_->group_of(*p)].push_back(id);
  return out;
}

std::map<ClientId, Trajectory> CollaborativeSystem::trajectories() const {
  std::map<ClientId, Trajectory> out;
  std::lock_guard<std::mutex> lock(impl_->mutex);
  for (const auto& [id, p] : impl_->clients) out[id] = p->trajectory();
  return out;
}

std::vector<ViewerPoint> CollaborativeSystem::map_points(GroupId group, std::size_t max_points) const {
  std::vector<std::pair<ClientId, std::shared_ptr<Map>>> maps;
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    for (const auto& [id, p] : impl_->clients)
      if (p->slam() && impl_->group_of(*p) == group)
        if (auto m = p->slam()->main_map()) maps.emplace_back(id, m);
  }
  std::vector<ViewerPoint> out;
  std::size_t total = 0;
  for (const auto& [id, m] : maps) {
    std::shared_lock<std::shared_mutex> lock(m->mutex);
    total += m->num_map_points();
  }
  const std::size_t step = max_points == 0 ? 1 : std::max<std::size_t>(1, (total + max_points - 1) / max_points);
  for (const auto& [id, m] : maps) {
    std::shared_lock<std::shared_mutex> lock(m->mutex);
    std::size_t i = 0;
    m->for_each_map_point([&](const MapPoint& mp) {
      if (i++ % step != 0 || mp.bad) return;
      ViewerPoint v;
      v.x = float(mp.position.x());
      v.y = float(mp.position.y());
      v.z = float(mp.position.z());
      v.b = mp.color[0];
      v.g = mp.color[1];
      v.r = mp.color[2];
      v.client = id;
      out.push_back(v);
    });
  }
  return out;
}

Trajectory CollaborativeSystem::keyframe_trajectory(ClientId client) const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  auto it = impl_->clients.find(client);
  return it == impl_->clients.end() ? Trajectory{} : it->second->keyframe_trajectory();
}

std::vector<KeyframePose> CollaborativeSystem::keyframe_poses() const {
  struct MapOf {
    std::shared_ptr<Map> map;
    GroupId group;
  };
  std::vector<MapOf> maps;
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    for (const auto& [id, p] : impl_->clients) {
      if (!p->slam()) continue;
      const auto main = p->slam()->main_map();
      for (const auto& m : p->slam()->maps()) {
        const GroupId fused = impl_->fusion ? impl_->fusion->group_of(m.get()) : GroupId();
        // An unfused main map is labelled like the client's group in the status.
        maps.push_back({m, fused.valid() ? fused : GroupId::of_map(id, m == main ? 0 : m->index())});
      }
    }
  }
  std::vector<KeyframePose> out;
  for (const auto& [m, group] : maps) {
    std::shared_lock<std::shared_mutex> lock(m->mutex);
    for (const auto& kf : m->keyframes())
      if (!kf->bad) out.push_back({kf->id, group.value(), m->index(), kf->T_world_cam()});
  }
  std::sort(out.begin(), out.end(), [](const KeyframePose& a, const KeyframePose& b) { return a.id < b.id; });
  return out;
}

void CollaborativeSystem::write_outputs(const std::string& dir) const {
  std::filesystem::create_directories(dir);
  const auto trajs = trajectories();
  const auto snap = snapshot();
  nlohmann::json stats;
  stats["uptime_s"] = snap.uptime_s;
  stats["clients"] = nlohmann::json::array();
  for (const auto& c : snap.clients) {
    const std::string id = std::to_string(c.id);
    write_tum_trajectory(dir + "/client_" + id + ".txt", trajs.at(c.id),
                         "client " + id + ", frame of group " + std::to_string(c.group.value()));
    nlohmann::json cj = {{"id", c.id},
                         {"name", c.name},
                         {"frames_submitted", c.frames_submitted},
                         {"frames_processed", c.frames_processed},
                         {"frames_rejected", c.frames_rejected},
                         {"frames_lost", c.frames_lost},
                         {"frames_skipped", c.frames_skipped},
                         {"frames_flow", c.frames_flow},
                         {"pose_latency_ms", pose_latency_json(c)},
                         {"trajectory_poses", trajs.at(c.id).size()},
                         {"keyframes", c.keyframes},
                         {"map_points", c.map_points},
                         {"maps", c.maps},
                         {"group", c.group},
                         {"tracking", tracking_label(c.tracking)}};
    std::lock_guard<std::mutex> lock(impl_->mutex);
    const auto& p = impl_->clients.at(c.id);
    if (impl_->config.run_slam) {
      write_tum_trajectory(dir + "/keyframes_" + id + ".txt", p->keyframe_trajectory(), "client " + id + " keyframes");
      const auto t = p->timings();
      std::vector<double> total;
      for (size_t i = 0; i < t.track_ms.size(); ++i) total.push_back(t.track_ms[i] + t.extract_ms[i]);
      cj["extract_plus_track_ms"] = summary_json(total);
      cj["local_ba_ms"] = summary_json(t.mapper.ba_ms);
      add_loop_stats(cj, t.loop);
    }
    stats["clients"].push_back(cj);
  }
  // Fused groups: one combined trajectory each; clients alone stay in their own frame.
  const auto group_members = groups();
  stats["groups"] = nlohmann::json::array();
  for (const auto& [g, members] : group_members) {
    stats["groups"].push_back({{"group", g}, {"clients", members}, {"fused", members.size() > 1}});
    if (members.size() < 2) continue;
    Trajectory combined;
    for (ClientId c : members) combined.insert(combined.end(), trajs.at(c).begin(), trajs.at(c).end());
    sort_by_time(combined);
    write_tum_trajectory(dir + "/fused_" + std::to_string(g.value()) + ".txt", combined,
                         "fused group " + std::to_string(g.value()));
  }
  for (auto& cj : stats["clients"]) {
    cj["fused"] = group_members.at(cj["group"].get<GroupId>()).size() > 1;
  }
  stats["fusion_events"] = nlohmann::json::array();
  for (const auto& e : snap.events)
    stats["fusion_events"].push_back({{"time_s", e.wall_time_s},
                                      {"client_a", e.client_a},
                                      {"client_b", e.client_b},
                                      {"group", e.group},
                                      {"inliers", e.inliers},
                                      {"duration_ms", e.duration_ms},
                                      {"kind", e.kind},
                                      {"query_timestamp", e.query_timestamp},
                                      {"candidate_timestamp", e.candidate_timestamp},
                                      {"seam_points", e.seam_points},
                                      {"seam_edges", e.seam_edges},
                                      {"keyframes_moved", e.keyframes_moved},
                                      {"keyframes_kept", e.keyframes_kept},
                                      {"T_query_candidate", format_tum_line({0.0, e.T_query_candidate})}});
  stats["group_ba"] = {
      {"started", snap.group_ba.started},         {"completed", snap.group_ba.completed},
      {"discarded", snap.group_ba.discarded},     {"cut_short", snap.group_ba.cut_short},
      {"ms", summary_json(snap.group_ba.ms)},     {"last_keyframes", snap.group_ba.last_keyframes},
      {"last_points", snap.group_ba.last_points}, {"last_linked_points", snap.group_ba.last_linked_points}};
  std::ofstream(dir + "/stats.json") << stats.dump(2) << "\n";
}

SystemState CollaborativeSystem::export_state() const {
  std::vector<ClientPipeline*> pipelines;
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    for (const auto& [id, p] : impl_->clients)
      if (p->slam()) pipelines.push_back(p.get());
  }
  SystemState state;
  // No fusion, re-encounter or group BA moves a map meanwhile: every group is in one frame.
  std::shared_lock<std::shared_mutex> links;
  if (impl_->fusion) links = impl_->fusion->hold_links();
  for (ClientPipeline* p : pipelines) {
    ClientSlamState cs = p->slam()->export_state();
    const auto maps = p->slam()->maps();
    for (auto& ms : cs.maps)
      if (impl_->fusion && std::size_t(ms.index) < maps.size())
        ms.group = impl_->fusion->group_of(maps[ms.index].get()).value();
    state.clients.push_back(std::move(cs));
  }
  if (impl_->fusion) state.fusion = impl_->fusion->export_state();
  links = {};
  keep_fusion_within_maps(state);
  return state;
}

void CollaborativeSystem::restore_state(const SystemState& state, const std::string& source) {
  if (!impl_->config.run_slam)
    throw ConfigError(source + ": loading a snapshot needs SLAM (not --no-slam; --state-reset starts empty)");
  auto check_new = [&](ClientId id) {  // under impl_->mutex
    if (impl_->finished) throw std::logic_error("restore_state after finish()");
    if (impl_->clients.count(id)) throw InputError(source, "client " + std::to_string(id) + " is already registered");
  };
  for (const ClientSlamState& cs : state.clients) {
    cs.info.camera.validate();
    {
      std::lock_guard<std::mutex> lock(impl_->mutex);
      check_new(cs.info.id);
    }
    // Built and restored without the client table's lock (restoring recomputes BoW vectors):
    // frames of other clients keep flowing meanwhile.
    FusionManager* fusion = impl_->fusion.get();
    auto pipeline = impl_->make_pipeline(cs.info);
    pipeline->slam()->restore_state(cs, source);
    // Groups first: the maps are registered with fusion before any of their keyframes can be.
    // (A failed insert below leaves only expired weak entries behind.)
    const auto maps = pipeline->slam()->maps();
    if (fusion)
      for (std::size_t i = 0; i < maps.size() && i < cs.maps.size(); ++i)
        fusion->restore_group(cs.info.id, maps[i], GroupId::from_value(cs.maps[i].group));
    {
      std::lock_guard<std::mutex> lock(impl_->mutex);
      check_new(cs.info.id);
      impl_->clients.emplace(cs.info.id, std::move(pipeline));
    }
    logger("system")->info("client {} ('{}') restored", cs.info.id, cs.info.name);
  }
  // The seams hold the restored groups together in their global BA and re-encounters.
  if (impl_->fusion) impl_->fusion->restore_state(state.fusion, source);
}

void CollaborativeSystem::start_new_session(ClientId id) {
  ClientPipeline* pipeline = nullptr;
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    auto it = impl_->clients.find(id);
    if (it == impl_->clients.end() || !it->second->slam()) return;
    pipeline = it->second.get();
  }
  pipeline->start_new_session();
}

void CollaborativeSystem::offer_keyframes_to_fusion() {
  if (!impl_->fusion) return;
  std::vector<std::pair<ClientId, std::shared_ptr<Map>>> maps;
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    for (const auto& [id, p] : impl_->clients)
      if (p->slam())
        for (const auto& m : p->slam()->maps()) maps.emplace_back(id, m);
  }
  for (const auto& [id, m] : maps) {
    std::vector<KeyFramePtr> kfs;
    {
      std::shared_lock<std::shared_mutex> lock(m->mutex);
      kfs = m->keyframes();
    }
    for (const auto& kf : kfs) impl_->fusion->notify(id, m, kf);
  }
}

}  // namespace cslam
