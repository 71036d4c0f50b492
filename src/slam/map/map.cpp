#include "slam/map/map.h"

#include <algorithm>
#include <chrono>
#include <limits>

#include <boost/container/small_vector.hpp>

namespace cslam {

MapWriteLock::MapWriteLock(Map& map, bool record_wait) : lock_(map.mutex, std::defer_lock) {
  const auto start = std::chrono::steady_clock::now();
  auto done_waiting = [&] {
    if (map.writers_waiting_.fetch_sub(1) == 1) {
      // Last waiting writer: wake readers waiting for it (the mutex makes the wake-up not lost).
      { std::lock_guard<std::mutex> guard(map.writers_mutex_); }
      map.writers_cv_.notify_all();
    }
  };
  map.writers_waiting_.fetch_add(1);
  try {
    lock_.lock();
  } catch (...) {  // never counted as waiting forever
    done_waiting();
    throw;
  }
  done_waiting();
  if (record_wait && map.write_waits_.size() < Map::kMaxRecordedWaits)
    map.write_waits_.push_back(
        {start, std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count()});
}

void Map::wait_until_no_writer_waits() const {
  std::unique_lock<std::mutex> guard(writers_mutex_);
  writers_cv_.wait(guard, [&] { return writers_waiting_.load() == 0; });
}

void Map::add_keyframe(const KeyFramePtr& kf) {
  keyframes_[kf->id] = kf;
  if (!origin_) origin_ = kf;
}

void Map::add_map_point(const MapPointPtr& mp) { map_points_[mp->id] = mp; }

std::vector<KeyFramePtr> Map::keyframes() const {
  std::vector<KeyFramePtr> out;
  out.reserve(keyframes_.size());
  for (const auto& [id, kf] : keyframes_) out.push_back(kf);
  std::sort(out.begin(), out.end(), [](const KeyFramePtr& a, const KeyFramePtr& b) { return a->id < b->id; });
  return out;
}

std::vector<MapPointPtr> Map::map_points() const {
  std::vector<MapPointPtr> out;
  out.reserve(map_points_.size());
  for (const auto& [id, mp] : map_points_) out.push_back(mp);
  return out;
}

KeyFramePtr Map::keyframe(KeyFrameId id) const {
  auto it = keyframes_.find(id);
  return it == keyframes_.end() ? nullptr : it->second;
}

MapPointPtr Map::map_point(MapPointId id) const {
  auto it = map_points_.find(id);
  return it == map_points_.end() ? nullptr : it->second;
}

KeyFramePtr Map::shared(KeyFrame* kf) const {
  if (!kf) return nullptr;
  auto it = keyframes_.find(kf->id);
  return it == keyframes_.end() ? nullptr : it->second;
}

void Map::add_observation(KeyFrame* kf, int index, const MapPointPtr& mp) {
  if (mp->observations.count(kf)) return;
  mp->observations[kf] = index;
  ++mp->observations_version;
  mp->num_obs += kf->data->u_right[index] >= 0 ? 2 : 1;
  kf->map_points.set(std::size_t(index), mp);
}

void Map::erase_observation(KeyFrame* kf, const MapPointPtr& mp) {
  auto it = mp->observations.find(kf);
  if (it == mp->observations.end()) return;
  const int idx = it->second;
  mp->num_obs -= kf->data->u_right[idx] >= 0 ? 2 : 1;
  mp->observations.erase(it);
  ++mp->observations_version;
  if (kf->map_points[idx] == mp) kf->map_points.reset(std::size_t(idx));
  if (mp->reference == kf) mp->reference = mp->observations.empty() ? nullptr : mp->observations.begin()->first;
  if (mp->num_obs <= 2) set_map_point_bad(mp);
}

void Map::set_map_point_bad(const MapPointPtr& mp) {
  if (mp->bad) return;
  mp->bad = true;
  for (const auto& [kf, idx] : mp->observations)
    if (kf->map_points[idx] == mp) kf->map_points.reset(std::size_t(idx));
  mp->observations.clear();
  ++mp->observations_version;
  map_points_.erase(mp->id);
}

void Map::replace_map_point(const MapPointPtr& from, const MapPointPtr& into) {
  if (from == into || from->bad) return;
  const auto obs = from->observations;
  for (const auto& [kf, idx] : obs) {
    if (!into->in_keyframe(kf)) {
      kf->map_points.reset(std::size_t(idx));
      add_observation(kf, idx, into);
    } else if (kf->map_points[idx] == from) {
      kf->map_points.reset(std::size_t(idx));
    }
  }
  into->found += from->found;
  into->visible += from->visible;
  from->observations.clear();
  ++from->observations_version;
  from->bad = true;
  from->replaced = into;
  map_points_.erase(from->id);
  update_map_point(into.get());
}

void Map::update_connections(KeyFrame* kf) {
  std::map<KeyFrame*, int, ById> counter;
  for (const auto& mp : kf->map_points) {
    if (!mp || mp->bad) continue;
    for (const auto& [other, idx] : mp->observations)
      if (other != kf) ++counter[other];
  }
  if (counter.empty()) return;
  constexpr int kThreshold = 15;
  int best_w = 0;
  KeyFrame* best = nullptr;
  std::vector<std::pair<int, KeyFrame*>> edges;
  for (const auto& [other, w] : counter) {
    if (w > best_w) {
      best_w = w;
      best = other;
    }
    if (w >= kThreshold) edges.emplace_back(w, other);
  }
  if (edges.empty()) edges.emplace_back(best_w, best);
  kf->connections.clear();
  for (const auto& [w, other] : edges) {
    kf->connections[other] = w;
    other->connections[kf] = w;
    auto& oc = other->ordered_connections;
    oc.erase(std::remove_if(oc.begin(), oc.end(), [&](const auto& e) { return e.second == kf; }), oc.end());
    oc.emplace_back(w, kf);
    std::stable_sort(oc.begin(), oc.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  }
  std::stable_sort(edges.begin(), edges.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  kf->ordered_connections = edges;
  if (kf->first_connection && origin_.get() != kf) {
    kf->parent = shared(edges.front().second);
    if (kf->parent) kf->parent->children.insert(kf);
    kf->first_connection = false;
  }
}

void Map::set_keyframe_bad(KeyFrame* kf) {
  if (kf->bad || kf == origin_.get()) return;
  if (kf->no_erase > 0) {
    kf->erase_requested = true;
    return;
  }
  // Every keyframe that still lists it, not only its own partners: a keyframe whose connections
  // were recomputed without this one kept its edge to it (the graph is updated one side at a
  // time), and a culled keyframe is freed once no frame refers to it.
  for (const auto& [id, other] : keyframes_) {
    if (other.get() == kf) continue;
    if (other->connections.erase(kf) == 0) continue;
    auto& oc = other->ordered_connections;
    oc.erase(std::remove_if(oc.begin(), oc.end(), [&](const auto& e) { return e.second == kf; }), oc.end());
  }
  for (size_t i = 0; i < kf->map_points.size(); ++i)
    if (auto mp = kf->map_points[i]) erase_observation(kf, mp);
  kf->connections.clear();
  kf->ordered_connections.clear();
  for (KeyFrame* l : kf->loop_edges) l->loop_edges.erase(kf);
  kf->loop_edges.clear();

  // Reattach children: greedily pick, among children, the link of highest covisibility weight to
  // a keyframe already in the tree (starting with this keyframe's parent).
  std::set<KeyFrame*, ById> candidates;
  if (kf->parent) candidates.insert(kf->parent.get());
  while (!kf->children.empty()) {
    int best_w = -1;
    KeyFrame *best_child = nullptr, *best_parent = nullptr;
    for (KeyFrame* child : kf->children) {
      if (child->bad) continue;
      for (const auto& [w, cov] : child->ordered_connections) {
        if (candidates.count(cov) && w > best_w) {
          best_w = w;
          best_child = child;
          best_parent = cov;
        }
      }
    }
    if (!best_child) break;
    best_child->parent = shared(best_parent);
    best_parent->children.insert(best_child);
    candidates.insert(best_child);
    kf->children.erase(best_child);
  }
  for (KeyFrame* child : kf->children) {
    child->parent = kf->parent;
    if (kf->parent) kf->parent->children.insert(child);
  }
  kf->children.clear();
  if (kf->parent) {
    kf->parent->children.erase(kf);
    kf->T_cam_parent = kf->T_cam_world * kf->parent->T_world_cam();
  }
  kf->bad = true;
  database.erase(kf->id);
  keyframes_.erase(kf->id);
}

void Map::update_map_point(MapPoint* mp) const {
  if (mp->bad || mp->observations.empty()) return;
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  for (const auto& [kf, idx] : mp->observations) normal += (mp->position - kf->center()).normalized();
  mp->normal = normal.normalized();
  KeyFrame* ref = mp->reference ? mp->reference : mp->observations.begin()->first;
  auto ref_it = mp->observations.find(ref);
  if (ref_it == mp->observations.end()) {
    ref = mp->observations.begin()->first;
    ref_it = mp->observations.begin();
    mp->reference = ref;
  }
  const auto& pyr = *ref->data->pyramid;
  if (mp->scale_keypoint != ref_it->second || mp->scale_keyframe != ref->id) {
    mp->reference_scale = pyr.scale[ref->data->features.keypoints[ref_it->second].octave];
    mp->scale_keyframe = ref->id;
    mp->scale_keypoint = ref_it->second;
  }
  const double dist = (mp->position - ref->center()).norm();
  mp->max_distance = dist * mp->reference_scale;
  mp->min_distance = mp->max_distance / pyr.scale[pyr.num_levels - 1];

  // Distinctive descriptor: the one with the least median distance to the others. It depends on
  // the set of observations alone (keyframe descriptors never change).
  if (mp->descriptor_version == mp->observations_version) return;
  mp->descriptor_version = mp->observations_version;
  // Scratch on the stack up to 32 observations: this runs for every point whose observations
  // changed, thousands per keyframe.
  boost::container::small_vector<const Descriptor*, 32> descs;
  for (const auto& [kf, idx] : mp->observations) descs.push_back(&kf->data->features.descriptors[idx]);
  const size_t n = descs.size();
  if (n == 1) {
    mp->descriptor = *descs[0];
    return;
  }
  boost::container::small_vector<int, 32 * 32> d(n * n, 0);
  boost::container::small_vector<int, 32> row(n);
  for (size_t i = 0; i < n; ++i)
    for (size_t j = i + 1; j < n; ++j) d[i * n + j] = d[j * n + i] = hamming_distance(*descs[i], *descs[j]);
  int best_median = std::numeric_limits<int>::max();
  size_t best = 0;
  for (size_t i = 0; i < n; ++i) {
    std::copy(d.begin() + std::ptrdiff_t(i * n), d.begin() + std::ptrdiff_t((i + 1) * n), row.begin());
    std::nth_element(row.begin(), row.begin() + std::ptrdiff_t((n - 1) / 2), row.end());
    if (row[(n - 1) / 2] < best_median) {
      best_median = row[(n - 1) / 2];
      best = i;
    }
  }
  mp->descriptor = *descs[best];
}

}  // namespace cslam
