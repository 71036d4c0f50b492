#include "slam/tracking/tracker.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <mutex>
#include <shared_mutex>
#include <unordered_map>

#include "core/log.h"
#include "slam/match/projection_search.h"

namespace cslam {

Tracker::Tracker(TrackerConfig config, std::shared_ptr<Map> map, KeyFrameSink* sink)
    : config_(config), map_(std::move(map)), sink_(sink) {}

void Tracker::reset(std::shared_ptr<Map> new_map, KeyFrameSink* sink) {
  map_ = std::move(new_map);
  sink_ = sink;
  state_ = FrameFate::kNotInitialized;
  last_.reset();
  last_full_.reset();
  has_velocity_ = false;
  reference_kf_.reset();
  last_keyframe_.reset();
  local_map_ = {};  // it holds the old map's keyframes
  keyframe_deferred_ = false;
}

StereoIntrinsics Tracker::intrinsics(const FrameData& f) const {
  return {f.camera.fx, f.camera.fy, f.camera.cx, f.camera.cy, f.rgbd.bf};
}

TrackResult Tracker::track(std::shared_ptr<const FrameData> data) {
  Frame frame(std::move(data));
  TrackResult result;
  bool ok = false;
  if (state_ == FrameFate::kNotInitialized) {
    ok = initialize(frame);
    result.initialized_map = ok;
    if (ok) result.keyframe = reference_kf_->id;
    if (!ok) {
      result.wants_depth = !frame.data->keyframe_depth;
      result.state = state_;
      return result;
    }
  } else {
    {
      std::shared_lock<std::shared_mutex> lock(map_->mutex);
      tracked_change_index_ = map_->big_change_index();
      if (state_ == FrameFate::kTracked) {
        update_last_frame();
        if (last_full_ && last_full_->reference && !last_full_->reference->bad)
          last_full_->T_cam_world = last_full_->T_cam_ref * last_full_->reference->T_cam_world;
        if (has_velocity_) ok = track_with_motion_model(frame);
        if (!ok) ok = track_reference_keyframe(frame);
      } else {
        ok = relocalize(frame);
        result.relocalized = ok;
        if (ok) frames_since_reloc_ = 0;
      }
      if (ok) ok = track_local_map(frame);
      if (ok && frame.reference) frame.T_cam_ref = frame.T_cam_world * frame.reference->T_world_cam();
    }
    state_ = ok ? FrameFate::kTracked : FrameFate::kLost;
    if (ok) {
      if (last_ && last_->has_pose) {
        velocity_ = frame.T_cam_world * last_->T_cam_world.inverse();
        velocity_dt_ = frame.data->timestamp - last_->data->timestamp;
        has_velocity_ = true;
      }
      // Drop outliers and visual-odometry-only matches before deciding on a keyframe.
      for (size_t i = 0; i < frame.map_points.size(); ++i) {
        if (frame.map_points[i] && (frame.outlier[i] || frame.map_points[i]->observations.empty())) {
          frame.map_points[i].reset();
          frame.outlier[i] = 0;
        }
      }
      ++frames_since_keyframe_;
      ++frames_since_reloc_;
      calibrate_flow();
      flow_run_ = 0;
      full_inliers_ = last_inliers_;
      full_close_ = 0;
      for (size_t i = 0; i < frame.map_points.size(); ++i)
        if (frame.map_points[i] && frame.data->is_close(int(i))) ++full_close_;
      decide_keyframe(frame, result);
      result.keyframe_due_in = keyframe_due_in(frames_since_keyframe_);
    } else {
      has_velocity_ = false;
    }
  }
  if (!frame.reference) frame.reference = reference_kf_;
  result.state = state_;
  result.ok = ok;
  result.inliers = last_inliers_;
  result.T_cam_world = frame.T_cam_world;
  result.reference = frame.reference;
  last_is_keyframe_ = result.new_keyframe || result.initialized_map;
  if (ok && frame.reference) {
    std::shared_lock<std::shared_mutex> lock(map_->mutex);
    // If the map moved (fusion) after this frame was tracked, the reference keyframe moved with
    // it: the relative pose taken under the tracking lock carries the frame into the new frame.
    if (map_->big_change_index() != tracked_change_index_)
      frame.T_cam_world = frame.T_cam_ref * frame.reference->T_cam_world;
    else if (result.initialized_map)
      frame.T_cam_ref = frame.T_cam_world * frame.reference->T_world_cam();
    result.T_cam_ref = frame.T_cam_ref;
    result.T_cam_world = frame.T_cam_world;
  }
  if (ok) last_ = std::make_unique<Frame>(std::move(frame));
  last_full_.reset();
  return result;
}

bool Tracker::initialize(Frame& frame) {
  int with_depth = 0;
  for (size_t i = 0; i < frame.data->size(); ++i) with_depth += frame.data->has_depth(int(i)) ? 1 : 0;
  if (with_depth < config_.min_init_points) return false;
  frame.data = with_bow(std::move(frame.data));  // a keyframe's words go to the database
  const FrameData& f = *frame.data;
  frame.T_cam_world = SE3();
  frame.has_pose = true;
  KeyFramePtr kf;
  {
    MapWriteLock lock(*map_, /*record_wait=*/true);
    kf = std::make_shared<KeyFrame>(map_->ids().next_keyframe(), frame.data, frame.T_cam_world);
    map_->add_keyframe(kf);
    for (size_t i = 0; i < f.size(); ++i) {
      if (!f.has_depth(int(i))) continue;
      auto mp = std::make_shared<MapPoint>(map_->ids().next_map_point(), f.unproject(int(i)), kf.get(), f.colors[i]);
      mp->first_keyframe_seq = kf->id.seq;
      Map::add_observation(kf.get(), int(i), mp);
      map_->update_map_point(mp.get());
      map_->add_map_point(mp);
      frame.map_points[i] = mp;
    }
  }
  logger("tracking")->info("client {}: map {} initialised with {} points", map_->client(), map_->index(), with_depth);
  frame.reference = kf;
  reference_kf_ = kf;
  last_keyframe_ = kf;
  frames_since_keyframe_ = 0;
  state_ = FrameFate::kTracked;
  last_inliers_ = with_depth;
  if (sink_) sink_->insert_keyframe(kf);
  return true;
}

void Tracker::update_last_frame() {
  if (!last_) return;
  // The reference keyframe may have moved (local BA): refresh the last pose through it.
  if (last_->reference && !last_->reference->bad && last_->has_pose)
    last_->T_cam_world = last_->T_cam_ref * last_->reference->T_cam_world;
  if (last_is_keyframe_) return;
  // Visual-odometry points: back-project close keypoints without a map point.
  const FrameData& f = *last_->data;
  std::vector<std::pair<float, int>> by_depth;
  for (size_t i = 0; i < f.size(); ++i)
    if (f.has_depth(int(i))) by_depth.emplace_back(f.depth[i], int(i));
  std::sort(by_depth.begin(), by_depth.end());
  const SE3 T_world_cam = last_->T_cam_world.inverse();
  const double close = f.rgbd.close_depth(f.camera.fx);
  int n = 0;
  for (const auto& [d, i] : by_depth) {
    bool create = !last_->map_points[i] || last_->map_points[i]->observations.empty();
    if (create) {
      auto mp = std::make_shared<MapPoint>(MapPointId{map_->client(), 0xFFFFFFFFu}, T_world_cam * f.unproject(i),
                                           nullptr, f.colors[i]);
      mp->descriptor = f.features.descriptors[i];
      last_->map_points[i] = mp;
      last_->outlier[i] = 0;
      last_->temporal_points.push_back(mp);
    }
    ++n;
    if (d > close && n > config_.min_new_close_points) break;
  }
}

int Tracker::optimize_frame_pose(Frame& frame) const {
  const FrameData& f = *frame.data;
  std::vector<PoseObservation> obs;
  std::vector<int> index;
  for (size_t i = 0; i < f.size(); ++i) {
    const auto& mp = frame.map_points[i];
    if (!mp) continue;
    PoseObservation o;
    o.p_world = mp->position;
    o.uv = f.features.undistorted[i];
    o.u_right = f.u_right[i];
    o.inv_sigma2 = f.pyramid->inv_sigma2[f.features.keypoints[i].octave];
    obs.push_back(o);
    index.push_back(int(i));
  }
  if (obs.size() < 3) return 0;
  const auto r = optimize_pose(frame.T_cam_world, obs, intrinsics(f));
  frame.T_cam_world = r.T_cam_world;
  frame.has_pose = true;
  for (size_t k = 0; k < index.size(); ++k) frame.outlier[index[k]] = r.inlier[k] ? 0 : 1;
  return r.num_inliers;
}

namespace {
// Removes the matches the pose optimisation rejected; returns how many remaining matches are map
// points (not visual-odometry points of the previous frame).
int drop_outliers_count_map_points(Frame& frame) {
  int good = 0;
  for (size_t i = 0; i < frame.map_points.size(); ++i) {
    if (!frame.map_points[i]) continue;
    if (frame.outlier[i]) {
      frame.map_points[i].reset();
      frame.outlier[i] = 0;
    } else if (!frame.map_points[i]->observations.empty()) {
      ++good;
    }
  }
  return good;
}
}  // namespace

std::optional<SE3> Tracker::predicted_motion(double seconds) const {
  if (state_ != FrameFate::kTracked || !has_velocity_ || !(velocity_dt_ > 0) || !std::isfinite(seconds))
    return std::nullopt;
  return velocity_.scaled(seconds / velocity_dt_);
}

SE3 Tracker::motion_model_pose(double timestamp) const {
  // Constant velocity in time, not per frame: a dropped or skipped frame doubles the motion.
  const double dt = timestamp - last_->data->timestamp;
  const double factor = velocity_dt_ > 0 && dt > 0 ? std::clamp(dt / velocity_dt_, 0.25, 4.0) : 1.0;
  return velocity_.scaled(factor) * last_->T_cam_world;
}

bool Tracker::track_with_motion_model(Frame& frame) {
  frame.T_cam_world = motion_model_pose(frame.data->timestamp);
  frame.has_pose = true;
  // After flow frames, the matches are searched among the last full frame's (all its map points
  // and visual-odometry points; a flow frame follows a thinned set of them).
  const Frame& source = last_full_ ? *last_full_ : *last_;
  int n = search_by_projection(frame, source, config_.motion_radius, true);
  if (n < config_.min_motion_matches) {
    std::fill(frame.map_points.begin(), frame.map_points.end(), nullptr);
    n = search_by_projection(frame, source, 2 * config_.motion_radius, true);
  }
  if (n < config_.min_motion_matches) return false;
  optimize_frame_pose(frame);
  const int good = drop_outliers_count_map_points(frame);
  logger("tracking")->debug("frame {}: motion model {} matches, {} map-point inliers", frame.data->id.seq, n, good);
  return good >= config_.min_pose_inliers;
}

bool Tracker::track_reference_keyframe(Frame& frame) {
  if (!reference_kf_ || reference_kf_->bad) return false;
  std::vector<MapPointPtr> matches;
  frame.data = with_bow(std::move(frame.data));
  const int n = search_by_bow(*reference_kf_, *frame.data, matches, 0.7, true);
  if (n < 15) return false;
  frame.map_points = matches;
  std::fill(frame.outlier.begin(), frame.outlier.end(), 0);
  frame.T_cam_world = last_ ? last_->T_cam_world : reference_kf_->T_cam_world;
  optimize_frame_pose(frame);
  return drop_outliers_count_map_points(frame) >= config_.min_pose_inliers;
}

std::vector<std::pair<KeyFrame*, int>> Tracker::keyframes_sharing(const Frame& frame) {
  // Counted in a hash map, then sorted by id: the order decides ties.
  std::unordered_map<KeyFrame*, int> count;
  count.reserve(64);
  for (size_t i = 0; i < frame.map_points.size(); ++i) {
    const auto& mp = frame.map_points[i];
    if (!mp || mp->bad || frame.outlier[i]) continue;
    for (const auto& [kf, idx] : mp->observations) ++count[kf];
  }
  std::vector<std::pair<KeyFrame*, int>> sharing(count.begin(), count.end());
  std::sort(sharing.begin(), sharing.end(), [](const auto& a, const auto& b) { return ById()(a.first, b.first); });
  return sharing;
}

KeyFrame* Tracker::most_sharing(const std::vector<std::pair<KeyFrame*, int>>& sharing) {
  int best = 0;
  KeyFrame* best_kf = nullptr;
  for (const auto& [kf, n] : sharing)
    if (!kf->bad && n > best) {
      best = n;
      best_kf = kf;
    }
  return best_kf;
}

const std::vector<const MapPointPtr*>& Tracker::update_local_map(const Frame& frame, KeyFramePtr& reference) {
  const std::vector<std::pair<KeyFrame*, int>> sharing = keyframes_sharing(frame);
  std::set<KeyFrame*, ById> chosen;
  for (const auto& [kf, n] : sharing)
    if (!kf->bad) chosen.insert(kf);
  KeyFrame* best_kf = most_sharing(sharing);
  std::vector<KeyFrame*> first_ring(chosen.begin(), chosen.end());
  for (KeyFrame* kf : first_ring) {
    if (int(chosen.size()) >= config_.max_local_keyframes) break;
    for (KeyFrame* n : kf->best_covisibles(10))
      if (!n->bad && chosen.insert(n).second) break;
    for (KeyFrame* c : kf->children)
      if (!c->bad && chosen.insert(c).second) break;
    if (kf->parent && !kf->parent->bad) chosen.insert(kf->parent.get());
  }
  if (best_kf) reference = map_->shared(best_kf);
  LocalMap& local = local_map_;
  std::vector<KeyFramePtr> kfs;
  kfs.reserve(chosen.size());
  for (KeyFrame* kf : chosen)
    if (auto p = map_->shared(kf)) kfs.push_back(std::move(p));
  // The last frame's points stand while the same keyframes (of this map: kfs holds no other)
  // hold the same slots.
  bool same = local.keyframes.size() == kfs.size();
  for (std::size_t k = 0; same && k < kfs.size(); ++k)
    same = local.keyframes[k] == kfs[k] && local.versions[k] == kfs[k]->map_points.version();
  if (same) return local.points;
  local.keyframes = std::move(kfs);
  local.versions.clear();
  for (const auto& kf : local.keyframes) local.versions.push_back(kf->map_points.version());
  local_points_seen_.clear();
  local.points.clear();
  // Deduplicate before reading the point: keyframes share most points, and each first read of a
  // point is a cache miss.
  for (const auto& kf : local.keyframes)
    for (const auto& mp : kf->map_points)
      if (mp && local_points_seen_.insert(mp.get()) && !mp->bad) local.points.push_back(&mp);
  return local.points;
}

bool Tracker::track_local_map(Frame& frame) {
  KeyFramePtr ref;
  const std::vector<const MapPointPtr*>& local_points = update_local_map(frame, ref);
  if (ref) reference_kf_ = ref;
  frame.reference = reference_kf_;
  for (const auto& mp : frame.map_points)
    if (mp) ++mp->visible;
  search_local_points(frame, local_points, frames_since_reloc_ < 2 ? 5.0 : config_.local_map_radius);
  optimize_frame_pose(frame);
  int inliers = 0;
  for (size_t i = 0; i < frame.map_points.size(); ++i) {
    const auto& mp = frame.map_points[i];
    if (!mp) continue;
    if (!frame.outlier[i]) {
      ++mp->found;
      if (!mp->observations.empty()) ++inliers;
    }
  }
  last_inliers_ = inliers;
  logger("tracking")
      ->debug("frame {}: local map {} points, {} inliers, reference keyframe {}", frame.data->id.seq,
              local_points.size(), inliers, reference_kf_ ? int(reference_kf_->id.seq) : -1);
  const int needed = frames_since_reloc_ < std::uint32_t(config_.max_frames_between_keyframes)
                         ? config_.min_local_map_inliers_after_reloc
                         : config_.min_local_map_inliers;
  return inliers >= needed;
}

void Tracker::decide_keyframe(Frame& frame, TrackResult& result) {
  const bool deferred_due = keyframe_deferred_ && last_inliers_ > 15 && sink_ && sink_->accepts_keyframes();
  if (!deferred_due && !need_new_keyframe(frame)) return;
  if (!frame.data->keyframe_depth) {
    keyframe_deferred_ = true;
    result.wants_depth = true;
    return;
  }
  keyframe_deferred_ = false;
  if (pose_listener_ && frame.reference)
    pose_listener_({frame.data->timestamp, frame.reference, frame.T_cam_ref, tracked_change_index_,
                    keyframe_due_in(0)});  // the countdown restarts with this keyframe
  if (const KeyFramePtr kf = create_keyframe(frame)) {
    result.new_keyframe = true;
    result.keyframe = kf->id;
  }
}

int Tracker::keyframe_due_in(std::uint32_t frames_since_keyframe) const {
  if (config_.keyframe_every_frames <= 0 || keyframe_deferred_) return 0;
  return std::max(1, config_.keyframe_every_frames - int(frames_since_keyframe));
}

bool Tracker::need_new_keyframe(const Frame& frame) const {
  if (!sink_ || !sink_->accepts_keyframes()) return false;
  const std::size_t nkfs = map_->num_keyframes();
  if (frames_since_reloc_ < std::uint32_t(config_.max_frames_between_keyframes) &&
      nkfs > std::size_t(config_.max_frames_between_keyframes))
    return false;
  int ref_matches = 0;
  {
    std::shared_lock<std::shared_mutex> lock(map_->mutex);
    if (reference_kf_) ref_matches = reference_kf_->tracked_map_points(nkfs <= 2 ? 2 : config_.ref_min_observations);
  }
  const FrameData& f = *frame.data;
  int tracked_close = 0, untracked_close = 0;
  for (size_t i = 0; i < f.size(); ++i) {
    if (!f.is_close(int(i))) continue;
    if (frame.map_points[i] && !frame.outlier[i])
      ++tracked_close;
    else
      ++untracked_close;
  }
  const bool need_close =
      tracked_close < config_.close_tracked_threshold && untracked_close > config_.close_untracked_threshold;
  const double ratio = nkfs < 2 ? 0.4 : config_.ref_ratio;
  const bool c1a = frames_since_keyframe_ >= std::uint32_t(config_.max_frames_between_keyframes);
  // ORB-SLAM2 takes the ratio rule alone only while local mapping is idle; here the deterministic
  // stand-in is a minimum interval of sensor time since the last keyframe (c1a and c1c still
  // apply at once), so that stepped and threaded runs decide alike.
  const bool c1b =
      frames_since_keyframe_ >= std::uint32_t(config_.min_frames_between_keyframes) &&
      (!last_keyframe_ || f.timestamp - last_keyframe_->data->timestamp >= config_.min_keyframe_interval_s);
  const bool c1c = last_inliers_ < ref_matches * 0.25 || need_close;
  const bool c2 = (last_inliers_ < ref_matches * ratio || need_close) && last_inliers_ > 15;
  logger("tracking")
      ->debug(
          "frame {}: keyframe rule: {} inliers, reference {} points, close tracked {} untracked {} c1a {} c1b {} c1c "
          "{} c2 {}",
          frame.data->id.seq, last_inliers_, ref_matches, tracked_close, untracked_close, c1a, c1b, c1c, c2);
  const bool due =
      config_.keyframe_every_frames > 0 && frames_since_keyframe_ >= std::uint32_t(config_.keyframe_every_frames);
  return (due && last_inliers_ > 15) || ((c1a || c1b || c1c) && c2);
}

KeyFramePtr Tracker::create_keyframe(Frame& frame) {
  frame.data = with_bow(std::move(frame.data));  // a keyframe's words go to the database
  const FrameData& f = *frame.data;
  KeyFramePtr kf;
  {
    MapWriteLock lock(*map_, /*record_wait=*/true);
    if (map_->big_change_index() != tracked_change_index_) return nullptr;  // map moved meanwhile: next frame
    kf = std::make_shared<KeyFrame>(map_->ids().next_keyframe(), frame.data, frame.T_cam_world);
    if (frame.reference && !frame.reference->bad) {
      kf->creation_reference = frame.reference;
      kf->T_cam_creation_ref = frame.T_cam_world * frame.reference->T_world_cam();
    }
    for (size_t i = 0; i < f.size(); ++i)
      if (frame.map_points[i] && !frame.map_points[i]->bad && !frame.outlier[i])
        kf->map_points.set(i, frame.map_points[i]);
    std::vector<std::pair<float, int>> by_depth;
    for (size_t i = 0; i < f.size(); ++i)
      if (f.has_depth(int(i))) by_depth.emplace_back(f.depth[i], int(i));
    std::sort(by_depth.begin(), by_depth.end());
    const SE3 T_world_cam = frame.T_cam_world.inverse();
    const double close = f.rgbd.close_depth(f.camera.fx);
    int n = 0;
    for (const auto& [d, i] : by_depth) {
      const auto& existing = kf->map_points[i];
      if (!existing || existing->observations.empty()) {
        kf->map_points.reset(i);
        auto mp = std::make_shared<MapPoint>(map_->ids().next_map_point(), T_world_cam * f.unproject(i), kf.get(),
                                             f.colors[i]);
        mp->first_keyframe_seq = kf->id.seq;
        Map::add_observation(kf.get(), i, mp);
        map_->update_map_point(mp.get());
        map_->add_map_point(mp);
        frame.map_points[i] = mp;
      }
      ++n;
      if (d > close && n > config_.min_new_close_points) break;
    }
    map_->add_keyframe(kf);
  }
  frame.reference = kf;
  frame.T_cam_ref = SE3();  // the keyframe's pose is this frame's pose
  reference_kf_ = kf;
  last_keyframe_ = kf;
  frames_since_keyframe_ = 0;
  sink_->insert_keyframe(kf);
  return kf;
}

}  // namespace cslam
