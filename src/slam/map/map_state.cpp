#include "slam/map/map_state.h"

#include <algorithm>
#include <shared_mutex>
#include <sstream>
#include <unordered_map>
#include <unordered_set>

#include "slam/bow/vocabulary.h"
#include "core/error.h"

namespace cslam {

namespace {
// Checks for a waiting writer this often while copying (a few tens of microseconds of copy).
constexpr std::size_t kKeyFramesPerCheck = 32, kPointsPerCheck = 256;
}  // namespace

MapState export_map_state(const Map& map) {
  MapState s;
  export_map_state(map, s, false);
  return s;
}

MapState export_map_state_yielding(const Map& map, int max_yields, const std::function<void()>& under_lock) {
  using Clock = std::chrono::steady_clock;
  std::vector<std::pair<Clock::time_point, Clock::time_point>> holds;
  for (int yields = 0;; ++yields) {
    MapState s;
    {
      std::shared_lock<std::shared_mutex> lock(map.mutex);
      const Clock::time_point start = Clock::now();
      if (export_map_state(map, s, yields < max_yields)) {
        if (under_lock) under_lock();
        lock.unlock();
        holds.emplace_back(start, Clock::now());
        s.export_yields = yields;
        s.export_forced = yields >= max_yields;
        s.export_holds = std::move(holds);
        return s;
      }
      lock.unlock();
      holds.emplace_back(start, Clock::now());
    }
    // Abandoned: the lock is free for the writer; the partial copy is dropped without the lock.
    s = MapState();
    map.wait_until_no_writer_waits();
  }
}

bool export_map_state(const Map& map, MapState& s, bool yield_to_writers) {
  // Runs under the map's shared lock: plain copies only (ids instead of pointers, no lookups,
  // no sorting); tidy_map_state does the rest without the lock.
  auto writer_waits = [&] { return yield_to_writers && map.writers_waiting() > 0; };
  if (writer_waits()) return false;
  s = MapState();
  s.client = map.client();
  s.index = map.index();
  if (auto o = map.origin(); o && !o->bad) s.origin = o->id;
  const auto keyframes = map.keyframes();
  s.keyframes.reserve(keyframes.size());
  std::size_t visited = 0;
  for (const auto& kf : keyframes) {
    if (++visited % kKeyFramesPerCheck == 0 && writer_waits()) return false;
    if (kf->bad) continue;
    KeyFrameState k;
    k.id = kf->id;
    k.data = kf->data;
    k.T_cam_world = kf->T_cam_world;
    if (kf->parent && !kf->parent->bad) k.parent = kf->parent->id;
    k.connections.reserve(kf->ordered_connections.size());
    for (const auto& [w, other] : kf->ordered_connections)
      if (!other->bad) k.connections.emplace_back(other->id, w);
    for (KeyFrame* l : kf->loop_edges)
      if (!l->bad) k.loop_edges.push_back(l->id);
    k.first_connection = kf->first_connection;
    if (kf->awaiting_connection() && !kf->creation_reference->bad) {
      k.creation_reference = kf->creation_reference->id;
      k.T_cam_creation_ref = kf->T_cam_creation_ref;
    }
    s.keyframes.push_back(std::move(k));
  }
  // Points: one flat array of observations for all of them (no allocation per point under the
  // lock); split into per-point vectors in tidy_map_state.
  s.points.resize(map.num_map_points());
  s.flat_observations.clear();
  s.flat_observations.reserve(map.num_map_points() * 8);
  std::size_t n = 0;
  visited = 0;
  const bool complete = map.for_each_map_point_while([&](const MapPoint& mp) {
    if (++visited % kPointsPerCheck == 0 && writer_waits()) return false;
    if (mp.bad) return true;
    MapPointState& p = s.points[n++];
    p.id = mp.id;
    p.position = mp.position;
    p.normal = mp.normal;
    p.descriptor = mp.descriptor;
    p.min_distance = mp.min_distance;
    p.max_distance = mp.max_distance;
    p.flat_begin = s.flat_observations.size();
    for (const auto& [kf, idx] : mp.observations)
      if (!kf->bad) s.flat_observations.emplace_back(kf->id, idx);
    p.flat_end = s.flat_observations.size();
    if (mp.reference && !mp.reference->bad) p.reference = mp.reference->id;
    p.visible = mp.visible;
    p.found = mp.found;
    p.color = mp.color;
    p.first_keyframe_seq = mp.first_keyframe_seq;
    return true;
  });
  if (!complete) return false;
  s.points.resize(n);
  return true;
}

void tidy_map_state(MapState& s) {
  // Links inside this map only (cross-map seams belong to map fusion; a keyframe culled meanwhile
  // is not among the exported ones).
  std::unordered_set<KeyFrameId> ids;
  for (const auto& k : s.keyframes) ids.insert(k.id);
  auto known = [&](KeyFrameId id) { return ids.count(id) > 0; };
  if (s.origin && !known(*s.origin)) s.origin.reset();
  for (auto& k : s.keyframes) {
    if (k.parent && !known(*k.parent)) k.parent.reset();
    k.connections.erase(
        std::remove_if(k.connections.begin(), k.connections.end(), [&](const auto& c) { return !known(c.first); }),
        k.connections.end());
    k.loop_edges.erase(
        std::remove_if(k.loop_edges.begin(), k.loop_edges.end(), [&](KeyFrameId l) { return !known(l); }),
        k.loop_edges.end());
    std::sort(k.loop_edges.begin(), k.loop_edges.end());
    if (k.creation_reference && !known(*k.creation_reference)) k.creation_reference.reset();
  }
  for (auto& p : s.points) {
    if (p.flat_end > p.flat_begin)
      p.observations.assign(s.flat_observations.begin() + long(p.flat_begin),
                            s.flat_observations.begin() + long(p.flat_end));
    p.flat_begin = p.flat_end = 0;
    p.observations.erase(
        std::remove_if(p.observations.begin(), p.observations.end(), [&](const auto& o) { return !known(o.first); }),
        p.observations.end());
    std::sort(p.observations.begin(), p.observations.end());
    bool ref_observed = false;
    if (p.reference)
      for (const auto& [id, idx] : p.observations) ref_observed |= id == *p.reference;
    if (!ref_observed) p.reference.reset();
  }
  s.points.erase(
      std::remove_if(s.points.begin(), s.points.end(), [](const MapPointState& p) { return p.observations.empty(); }),
      s.points.end());
  std::sort(s.points.begin(), s.points.end(),
            [](const MapPointState& a, const MapPointState& b) { return a.id < b.id; });
  s.flat_observations.clear();
  s.flat_observations.shrink_to_fit();
}

void derive_frame_data(FrameData& f, const Vocabulary* vocabulary, int bow_levels_up) {
  f.grid = FeatureGrid(f.features, f.bounds);
  f.bow.clear();
  f.feature_vector.clear();
  f.pending_bow = {};
  if (vocabulary && !vocabulary->empty())
    vocabulary->transform(f.features.descriptors, f.bow, f.feature_vector, bow_levels_up);
}

namespace {

void check_frame_data(const FrameData& d, const std::string& source, KeyFrameId id) {
  const std::size_t n = d.features.keypoints.size();
  auto bad = [&](const std::string& what) {
    std::ostringstream os;
    os << "keyframe " << id << ": " << what;
    throw InputError(source, os.str());
  };
  if (d.features.undistorted.size() != n || d.features.descriptors.size() != n || d.depth.size() != n ||
      d.u_right.size() != n || d.colors.size() != n)
    bad("per-keypoint arrays differ in length");
  if (!d.pyramid || d.pyramid->num_levels < 1 || int(d.pyramid->scale.size()) != d.pyramid->num_levels ||
      int(d.pyramid->sigma2.size()) != d.pyramid->num_levels ||
      int(d.pyramid->inv_sigma2.size()) != d.pyramid->num_levels)
    bad("scale pyramid missing or inconsistent");
  for (const auto& kp : d.features.keypoints)
    if (kp.octave < 0 || kp.octave >= d.pyramid->num_levels) bad("keypoint level out of range");
  if (!(d.bounds[1] > d.bounds[0]) || !(d.bounds[3] > d.bounds[2])) bad("empty image bounds");
}

}  // namespace

std::shared_ptr<Map> restore_map(const MapState& state, std::shared_ptr<IdAllocator> ids, const std::string& source) {
  auto map = std::make_shared<Map>(state.client, state.index, std::move(ids));
  std::unique_lock<std::shared_mutex> lock(map->mutex);
  std::unordered_map<KeyFrameId, KeyFramePtr> kfs;
  auto fail = [&](auto id, const std::string& what) {
    std::ostringstream os;
    os << "map " << state.client << "/" << state.index << ": " << id << " " << what;
    throw InputError(source, os.str());
  };
  for (const auto& k : state.keyframes) {
    if (!k.data) fail(k.id, "has no frame data");
    if (k.id.client != state.client) fail(k.id, "belongs to another client");
    check_frame_data(*k.data, source, k.id);
    if (!kfs.emplace(k.id, std::make_shared<KeyFrame>(k.id, k.data, k.T_cam_world)).second) fail(k.id, "appears twice");
  }
  auto find = [&](KeyFrameId id, KeyFrameId from) -> KeyFramePtr {
    auto it = kfs.find(id);
    if (it == kfs.end()) fail(from, "links to unknown keyframe");
    return it->second;
  };
  if (state.origin)
    map->add_keyframe(find(*state.origin, *state.origin));
  else if (!state.keyframes.empty())
    fail(state.keyframes.front().id, "map has keyframes but no origin");
  for (const auto& k : state.keyframes) {
    const KeyFramePtr& kf = kfs.at(k.id);
    map->add_keyframe(kf);
    if (k.parent) {
      kf->parent = find(*k.parent, k.id);
      if (kf->parent == kf) fail(k.id, "is its own parent");
      kf->parent->children.insert(kf.get());
    }
    for (const auto& [other, w] : k.connections) {
      KeyFrame* o = find(other, k.id).get();
      kf->connections[o] = w;
      kf->ordered_connections.emplace_back(w, o);
    }
    std::stable_sort(kf->ordered_connections.begin(), kf->ordered_connections.end(),
                     [](const auto& a, const auto& b) { return a.first > b.first; });
    for (KeyFrameId l : k.loop_edges) kf->loop_edges.insert(find(l, k.id).get());
    kf->first_connection = k.first_connection;
    if (k.creation_reference) {
      kf->creation_reference = find(*k.creation_reference, k.id);
      kf->T_cam_creation_ref = k.T_cam_creation_ref;
    }
  }
  std::unordered_map<MapPointId, bool> seen;
  for (const auto& p : state.points) {
    if (!seen.emplace(p.id, true).second) fail(p.id, "appears twice");
    if (p.observations.empty()) fail(p.id, "has no observations");
    KeyFrame* ref = p.reference ? find(*p.reference, kfs.begin()->first).get() : nullptr;
    auto mp = std::make_shared<MapPoint>(p.id, p.position, ref, p.color);
    mp->normal = p.normal;
    mp->descriptor = p.descriptor;
    mp->min_distance = p.min_distance;
    mp->max_distance = p.max_distance;
    mp->visible = std::max(1, p.visible);
    mp->found = std::max(0, p.found);
    mp->first_keyframe_seq = p.first_keyframe_seq;
    for (const auto& [kid, idx] : p.observations) {
      const KeyFramePtr& kf = find(kid, kid);
      if (idx < 0 || std::size_t(idx) >= kf->data->size()) fail(p.id, "observation index out of range");
      if (kf->map_points[idx]) fail(p.id, "observation slot taken by another point");
      Map::add_observation(kf.get(), idx, mp);
    }
    if (!mp->reference) mp->reference = mp->observations.begin()->first;
    map->add_map_point(mp);
  }
  // Keyframes tracking had created but local mapping not yet connected: connect them now.
  for (const auto& k : state.keyframes) {
    KeyFrame* kf = kfs.at(k.id).get();
    if (kf->first_connection && map->origin().get() != kf) map->update_connections(kf);
  }
  for (const auto& [id, kf] : kfs)
    if (!kf->data->bow.empty()) map->database.add(id, kf->data->bow);
  return map;
}

}  // namespace cslam
