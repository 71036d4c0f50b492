#include "slam/mapping/local_mapper.h"

#include <shared_mutex>

#include "core/error.h"
#include "core/stopwatch.h"
#include "slam/match/projection_search.h"

namespace cslam {

LocalMapper::LocalMapper(LocalMapperConfig config, std::shared_ptr<Map> map, bool threaded)
    : config_(std::move(config)),
      map_(std::move(map)),
      threaded_(threaded),
      worker_(threaded, "mapping/c" + std::to_string(map_->client()), [this](const KeyFramePtr& kf) { process(kf); }) {
  worker_.start();
}

LocalMapper::~LocalMapper() { finish(); }

TrackingWait parse_tracking_wait(const std::string& name) {
  if (name == "none") return TrackingWait::kNone;
  if (name == "new-points") return TrackingWait::kNewPoints;
  if (name == "keyframe") return TrackingWait::kKeyframe;
  throw ConfigError("tracking wait '" + name + "' is not none, new-points or keyframe");
}

void LocalMapper::insert_keyframe(const KeyFramePtr& kf) {
  // Backpressure: tracking waits while local mapping is a full queue behind, so that every
  // keyframe tracking decides on is processed completely (no skipped fusion or BA).
  struct Waiting {  // the hooks run around both waits, also when one throws
    const TrackingWaitHooks& hooks;
    explicit Waiting(const TrackingWaitHooks& h) : hooks(h) {
      if (hooks.before) hooks.before();
    }
    ~Waiting() {
      if (hooks.after) hooks.after();
    }
  };
  if (!threaded_) {
    worker_.push_waiting(kf, config_.max_pending_keyframes);
    return;
  }
  const Waiting waiting(wait_hooks_);
  const std::uint64_t n = worker_.push_waiting(kf, config_.max_pending_keyframes);
  if (config_.tracking_wait == TrackingWait::kNone) return;
  const bool whole_keyframe = config_.tracking_wait == TrackingWait::kKeyframe;
  worker_.wait_until([&] { return (whole_keyframe ? worker_.done() : points_done_) >= n; });
}

std::size_t LocalMapper::queued() const { return worker_.queued(); }

bool LocalMapper::step() { return worker_.step(); }

void LocalMapper::finish() {
  stopping_ = true;
  worker_.stop();
}

LocalMapperStats LocalMapper::stats() const {
  std::lock_guard<std::mutex> lock(stats_mutex_);
  return stats_;
}

void LocalMapper::process(const KeyFramePtr& kf) {
  Stopwatch sw;
  {
    MapWriteLock lock(*map_);
    insert_into_map(kf.get());
    cull_map_points(kf.get());
    const auto created = create_new_map_points(*map_, kf.get(), config_.triangulation);
    recent_points_.insert(recent_points_.end(), created.begin(), created.end());
    std::lock_guard<std::mutex> stats_lock(stats_mutex_);
    stats_.points_triangulated += int(created.size());
  }
  fuse_with_neighbours(kf.get());
  worker_.update([&] { ++points_done_; });
  if (config_.local_ba && map_->num_keyframes() > 2) local_bundle_adjustment(kf.get());
  cull_keyframes(kf.get());
  {
    MapWriteLock lock(*map_);
    if (!kf->bad) map_->database.add(kf->id, kf->data->bow);
  }
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    ++stats_.keyframes_processed;
    stats_.step_ms.push_back(sw.ms());
  }
  if (on_processed_) on_processed_(kf);  // the worker then counts the keyframe done
}

void LocalMapper::insert_into_map(KeyFrame* kf) {
  for (size_t i = 0; i < kf->map_points.size(); ++i) {
    auto mp = kf->map_points[i];
    if (!mp) continue;
    if (mp->bad) {
      kf->map_points.reset(i);
      continue;
    }
    if (!mp->in_keyframe(kf)) {
      Map::add_observation(kf, int(i), mp);
      map_->update_map_point(mp.get());
    } else if (mp->first_keyframe_seq == kf->id.seq) {
      recent_points_.push_back(mp);  // created with this keyframe
    }
  }
  map_->update_connections(kf);
  if (kf->parent) kf->creation_reference.reset();  // the spanning tree carries it from now on
}

void LocalMapper::cull_map_points(KeyFrame* kf) {
  int culled = 0;
  for (auto it = recent_points_.begin(); it != recent_points_.end();) {
    const auto& mp = *it;
    const int age = int(kf->id.seq) - int(mp->first_keyframe_seq);
    if (mp->bad) {
      it = recent_points_.erase(it);
    } else if (mp->found_ratio() < config_.min_found_ratio) {
      map_->set_map_point_bad(mp);
      ++culled;
      it = recent_points_.erase(it);
    } else if (age >= 2 && mp->num_obs <= config_.min_observations) {
      map_->set_map_point_bad(mp);
      ++culled;
      it = recent_points_.erase(it);
    } else if (age >= 3) {
      it = recent_points_.erase(it);
    } else {
      ++it;
    }
  }
  std::lock_guard<std::mutex> lock(stats_mutex_);
  stats_.points_culled += culled;
}

void LocalMapper::fuse_with_neighbours(KeyFrame* kf) {
  // Read and matched under the shared lock; each target's writes under the unique one, so that
  // tracking reads between them. Only this thread culls keyframes, so the targets stay valid.
  std::set<KeyFrame*, ById> targets;
  std::vector<MapPointPtr> own;
  {
    std::shared_lock<std::shared_mutex> lock(map_->mutex);
    for (KeyFrame* n : kf->best_covisibles(config_.fuse_neighbours)) {
      if (n->bad || n == kf) continue;
      targets.insert(n);
      for (KeyFrame* n2 : n->best_covisibles(config_.fuse_second_neighbours))
        if (!n2->bad && n2 != kf) targets.insert(n2);
    }
    for (const auto& mp : kf->map_points)
      if (mp && !mp->bad) own.push_back(mp);
  }
  int fused = 0;
  for (KeyFrame* t : targets) fused += fuse_into(t, own);
  std::vector<MapPointPtr> theirs;
  {
    std::shared_lock<std::shared_mutex> lock(map_->mutex);
    std::set<MapPoint*> seen;
    for (KeyFrame* t : targets)
      for (const auto& mp : t->map_points)
        if (mp && !mp->bad && seen.insert(mp.get()).second) theirs.push_back(mp);
  }
  fused += fuse_into(kf, theirs);
  {
    MapWriteLock lock(*map_);
    for (const auto& mp : kf->map_points)
      if (mp && !mp->bad) map_->update_map_point(mp.get());
    map_->update_connections(kf);
  }
  std::lock_guard<std::mutex> lock(stats_mutex_);
  stats_.points_fused += fused;
}

int LocalMapper::fuse_into(KeyFrame* target, const std::vector<MapPointPtr>& points) {
  std::vector<FuseMatch> matches;
  std::uint64_t change_index = 0;
  {
    std::shared_lock<std::shared_mutex> lock(map_->mutex);
    change_index = map_->big_change_index();
    matches = match_for_fuse(target, points);
  }
  MapWriteLock lock(*map_);
  // The map was moved meanwhile (fusion, loop correction): the matches are in the old frame.
  if (map_->big_change_index() != change_index) matches = match_for_fuse(target, points);
  return apply_fuse(*map_, target, matches);
}

void LocalMapper::cull_keyframes(KeyFrame* kf) {
  // Each candidate is judged under the shared lock and culled under the unique one. Other
  // threads only add to a candidate's points' observations meanwhile, so a redundant one stays so.
  std::vector<KeyFrame*> candidates;
  {
    std::shared_lock<std::shared_mutex> lock(map_->mutex);
    if (kf->bad) return;
    candidates = kf->covisibles();
  }
  int culled = 0;
  for (KeyFrame* cand : candidates) {
    {
      std::shared_lock<std::shared_mutex> lock(map_->mutex);
      if (cand->bad || cand == map_->origin().get() || cand == kf || !is_redundant(*cand)) continue;
    }
    MapWriteLock lock(*map_);
    if (cand->bad) continue;
    map_->set_keyframe_bad(cand);
    ++culled;
  }
  std::lock_guard<std::mutex> lock(stats_mutex_);
  stats_.keyframes_culled += culled;
}

bool LocalMapper::is_redundant(const KeyFrame& cand) const {
  const FrameData& f = *cand.data;
  auto counted = [&](size_t i) {
    const auto& mp = cand.map_points[i];
    return mp && !mp->bad && f.is_close(int(i));
  };
  int points = 0;
  for (size_t i = 0; i < cand.map_points.size(); ++i) points += counted(i) ? 1 : 0;
  // Culled when more than redundant_ratio of the points are redundant; the count stops as soon
  // as the points not (yet) found redundant rule that out (most candidates are kept).
  const double needed = config_.redundant_ratio * points;
  int redundant = 0, other = 0;
  for (size_t i = 0; i < cand.map_points.size() && points - other > needed; ++i) {
    if (!counted(i)) continue;
    const MapPoint& mp = *cand.map_points[i];
    bool point_redundant = false;
    if (mp.num_obs > 3) {
      const int level = f.features.keypoints[i].octave;
      int seen_by = 0;
      for (const auto& [okf, idx] : mp.observations) {
        if (okf == &cand) continue;
        if (okf->data->features.keypoints[idx].octave <= level + 1 && ++seen_by >= 3) break;
      }
      point_redundant = seen_by >= 3;
    }
    if (point_redundant)
      ++redundant;
    else
      ++other;
  }
  return points > 0 && redundant > needed;
}

}  // namespace cslam
