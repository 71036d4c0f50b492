#include "dense/live_dense_map.h"

#include <algorithm>
#include <cmath>

#include "core/stopwatch.h"

namespace cslam {

namespace {

constexpr double kDegree = M_PI / 180.0;

double angle_of(const SE3& T) { return 2.0 * std::acos(std::min(1.0, std::abs(T.rotation().w()))); }

}  // namespace

LiveDenseMap::LiveDenseMap(LiveDenseConfig config) : config_(config) {
  config_.validate();
  publish();
}

void LiveDenseMap::set_camera(ClientId client, const PinholeCamera& camera) {
  auto& table = rays_[client];
  if (!table || !same_projection(table->camera(), camera)) table = std::make_unique<RayTable>(camera);
}

void LiveDenseMap::add_keyframe(KeyFrameId id, std::optional<DenseImages> images, double now_s,
                                const SE3& T_cam_depthcam) {
  pending_.push_back({id, now_s, std::move(images), T_cam_depthcam});
  // Bounded: beyond max_pending_images the oldest waiting keyframes let go of their images (the
  // loader finds them again when their turn comes).
  std::size_t with_images = 0;
  for (auto it = pending_.rbegin(); it != pending_.rend(); ++it)
    if (it->images && ++with_images > config_.max_pending_images) it->images.reset();
}

DenseStepResult LiveDenseMap::step(const std::vector<KeyframePose>& poses, double now_s, const DenseImageLoader& loader,
                                   const DenseStepBudget& budget) {
  return run_step(poses, now_s, false, loader, budget);
}

DenseStepResult LiveDenseMap::flush(const std::vector<KeyframePose>& poses, const DenseImageLoader& loader) {
  DenseStepResult r = run_step(poses, 0.0, true, loader, {1 << 30, 1 << 30});
  for (auto& [client, id] : open_) submaps_.at(id)->close();
  open_.clear();
  remesh_due(0.0, true, r);
  ++version_;
  publish();
  return r;
}

DenseStepResult LiveDenseMap::run_step(const std::vector<KeyframePose>& poses, double now_s, bool all,
                                       const DenseImageLoader& loader, const DenseStepBudget& budget) {
  DenseStepResult r;
  PoseIndex index;
  for (const KeyframePose& p : poses) {
    index.emplace(p.id, &p);
    auto& newest = newest_listed_[p.id.client];
    newest = std::max(newest, p.id.seq);
  }
  std::vector<std::pair<double, SubmapId>> distorted;
  find_culled(index, r);
  apply_poses(index, r, distorted);
  if (r.moved > 0 || r.removed > 0) publish();  // corrections reach readers before the slower work below
  const int due_left = integrate_pending(index, now_s, all, loader, budget.max_integrations, r);
  // New keyframes first: a submap is rebuilt only when no keyframe waits that is due.
  std::sort(distorted.rbegin(), distorted.rend());  // most distorted first
  distorted_left_ = distorted.size();
  for (const auto& [deviation, id] : distorted) {
    if (due_left > 0 || r.reintegrated >= budget.max_reintegrations) break;
    const auto it = submaps_.find(id);
    if (it != submaps_.end()) reintegrate(*it->second, index, loader, r);
    --distorted_left_;  // rebuilt, or gone
  }
  remesh_due(now_s, all, r);
  publish();
  return r;
}

void LiveDenseMap::find_culled(const PoseIndex& poses, DenseStepResult& r) {
  // Local mapping processes a client's keyframes in id order: one that is not listed while a
  // newer keyframe of its client is has been culled (a pending one may simply not be mapped yet).
  auto culled = [&](KeyFrameId id) {
    const auto newest = newest_listed_.find(id.client);
    return !poses.count(id) && newest != newest_listed_.end() && newest->second > id.seq;
  };
  for (auto it = pending_.begin(); it != pending_.end();) {
    if (culled(it->id)) {
      r.culled.push_back(it->id);
      it = pending_.erase(it);
    } else {
      ++it;
    }
  }
  for (auto it = submaps_.begin(); it != submaps_.end();) {
    DenseSubmap& s = *it->second;
    std::vector<KeyFrameId> gone;
    for (const auto& m : s.members())
      if (culled(m.id)) gone.push_back(m.id);
    for (KeyFrameId id : gone) {
      s.forget(id);
      r.culled.push_back(id);
    }
    if (s.members().empty()) {  // nothing left that can place it
      if (open_.count(submap_client(s.id())) && open_.at(submap_client(s.id())) == s.id())
        open_.erase(submap_client(s.id()));
      last_mesh_s_.erase(s.id());
      it = submaps_.erase(it);
      ++r.removed;
      ++version_;
    } else {
      ++it;
    }
  }
}

void LiveDenseMap::apply_poses(const PoseIndex& poses, DenseStepResult& r,
                               std::vector<std::pair<double, SubmapId>>& distorted) {
  for (auto& [id, submap] : submaps_) {
    const DenseSubmap::Member* ref = nullptr;
    const KeyframePose* ref_pose = nullptr;
    for (const auto& m : submap->members()) {
      const auto it = poses.find(m.id);
      if (it != poses.end()) {
        ref = &m;
        ref_pose = it->second;
        break;
      }
    }
    if (!ref) continue;  // none of its keyframes listed right now: stays where it is
    const SE3 T_world_submap = ref_pose->T_world_cam * ref->T_submap_kf.inverse();
    const std::uint64_t before = submap->pose_version();
    submap->set_pose(T_world_submap, ref_pose->group);
    if (submap->pose_version() != before) {
      ++r.moved;
      ++version_;
    }
    double worst = 0;  // largest displacement of a member's observed surface relative to the submap
    for (const auto& m : submap->members()) {
      const auto it = poses.find(m.id);
      if (it == poses.end()) continue;
      const SE3 error = (T_world_submap * m.T_submap_kf).inverse() * it->second->T_world_cam;
      worst = std::max(worst, error.translation().norm() + angle_of(error) * m.median_depth);
    }
    r.max_deviation_m = std::max(r.max_deviation_m, worst);
    if (worst > config_.reintegrate_displacement) distorted.emplace_back(worst, id);
  }
}

int LiveDenseMap::integrate_pending(const PoseIndex& poses, double now_s, bool all, const DenseImageLoader& loader,
                                    int budget, DenseStepResult& r) {
  std::sort(pending_.begin(), pending_.end(), [](const Pending& a, const Pending& b) { return a.id < b.id; });
  int due_left = 0;
  for (auto it = pending_.begin(); it != pending_.end();) {
    const auto pose = poses.find(it->id);
    const bool due = all || now_s - it->added_s >= config_.integration_delay_s;
    if (pose == poses.end() || !due || !rays_.count(it->id.client)) {
      ++it;  // not mapped yet, too young, or no camera yet
      continue;
    }
    if (r.integrated >= budget) {  // due, but over this step's budget
      ++due_left;
      ++it;
      continue;
    }
    std::optional<DenseImages> images = std::move(it->images);
    if (!images && loader) images = loader(it->id);
    if (!images || images->bgr.empty() || images->depth.empty()) {
      ++r.missing_images;
    } else if (integrate_one(*pose->second, *images, it->T_cam_depthcam, r)) {
      ++r.integrated;
    }
    it = pending_.erase(it);
  }
  return due_left;
}

bool LiveDenseMap::integrate_one(const KeyframePose& pose, const DenseImages& images, const SE3& T_cam_depthcam,
                                 DenseStepResult& r) {
  const ClientId client = pose.id.client;
  const RayTable& rays = *rays_.at(client);
  if (images.bgr.type() != CV_8UC3 || images.depth.type() != CV_16UC1 || images.bgr.cols != rays.camera().width ||
      images.bgr.rows != rays.camera().height || images.depth.size() != images.bgr.size()) {
    ++r.missing_images;
    return false;
  }
  DenseSubmap* open = nullptr;
  if (const auto it = open_.find(client); it != open_.end()) {
    DenseSubmap& s = *submaps_.at(it->second);
    const SE3 d = s.T_world_first().inverse() * pose.T_world_cam;
    const bool fits =
        s.map() == pose.map && s.group() == pose.group && int(s.members().size()) < config_.keyframes_per_submap &&
        d.translation().norm() <= config_.submap_max_distance && angle_of(d) <= config_.submap_max_angle_deg * kDegree;
    if (fits) {
      open = &s;
    } else {  // the window is complete
      s.close();
      ++r.remeshed;
      open_.erase(it);
    }
  }
  if (!open) {
    const SubmapId id = make_submap_id(client, next_index_[client]++);
    auto submap = std::make_unique<DenseSubmap>(id, pose.group, pose.map, pose.T_world_cam, config_);
    open = submap.get();
    submaps_.emplace(id, std::move(submap));
    open_[client] = id;
  }
  const Stopwatch timer;
  open->integrate(pose.id, pose.T_world_cam, images, rays, T_cam_depthcam);
  r.integrate_ms.push_back(timer.ms());
  ++integrated_;
  ++version_;
  return true;
}

void LiveDenseMap::reintegrate(DenseSubmap& submap, const PoseIndex& poses, const DenseImageLoader& loader,
                               DenseStepResult& r) {
  std::vector<std::optional<DenseImages>> images;
  std::vector<DenseSubmap::Reintegration> members;
  images.reserve(submap.members().size());
  int group = submap.group();
  for (const auto& m : submap.members()) {
    const auto it = poses.find(m.id);
    if (it == poses.end() || !rays_.count(m.id.client)) continue;
    images.push_back(loader ? loader(m.id) : std::nullopt);
    if (!images.back()) ++r.missing_images;
    if (members.empty()) group = it->second->group;
    members.push_back({m.id, it->second->T_world_cam, images.back() ? &*images.back() : nullptr,
                       rays_.at(m.id.client).get(), m.T_cam_depthcam});
  }
  if (members.empty()) return;
  submap.reintegrate(members, group);
  ++r.reintegrated;
  ++version_;
}

void LiveDenseMap::remesh_due(double now_s, bool all, DenseStepResult& r) {
  for (auto& [id, submap] : submaps_) {
    if (!submap->open() || !submap->mesh_stale()) continue;
    auto& last = last_mesh_s_[id];
    if (!all && now_s - last < config_.mesh_interval_s) continue;
    submap->remesh();
    last = now_s;
    ++r.remeshed;
    ++version_;
  }
}

void LiveDenseMap::publish() {
  auto v = std::make_shared<DenseMapView>();
  v->version = version_;
  for (const auto& [id, submap] : submaps_) {
    v->submaps.push_back(submap->view());
    v->mesh_bytes += v->submaps.back().mesh_bytes;
    v->volume_bytes += v->submaps.back().volume_bytes;
    v->stale_meshes += submap->mesh_stale();  // only an open one's: closing and rebuilding re-mesh
  }
  v->distorted_submaps = distorted_left_;
  v->keyframes_integrated = integrated_;
  v->keyframes_pending = pending_.size();
  std::lock_guard<std::mutex> lock(view_mutex_);
  view_ = std::move(v);
}

std::shared_ptr<const DenseMapView> LiveDenseMap::view() const {
  std::lock_guard<std::mutex> lock(view_mutex_);
  return view_;
}

}  // namespace cslam
