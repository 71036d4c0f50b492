#pragma once
// Local mapping of one client map (ORB-SLAM2 class): keyframe insertion, recent map-point culling,
// duplicate fusion with neighbours, local bundle adjustment and redundant keyframe culling.
// Runs in its own thread (threaded = true) or is stepped by the caller (tests, offline runs).
#include <atomic>
#include <list>
#include <mutex>
#include <string>

#include "core/pointer_set.h"
#include "core/queue_worker.h"
#include "core/stats.h"
#include "slam/map/map.h"
#include "slam/mapping/triangulation.h"
#include "optimize/bundle_adjustment.h"
#include "slam/tracking/tracker.h"

namespace cslam {

// How long tracking waits, after handing local mapping a keyframe, before it tracks the next frame
// (threaded mode). Tracking that runs ahead tracks frames against a keyframe whose new points are
// not yet triangulated or fused with the neighbours' duplicates; those frames then create
// duplicate points and keyframes, and which ones depends on thread timing (docs/slam.md).
enum class TrackingWait {
  kNone,       // only the max_pending_keyframes backpressure
  kNewPoints,  // until the keyframe's points are created and fused (local BA runs on meanwhile)
  kKeyframe,   // until local mapping finished the keyframe: the same map states as --sync
};
// "none" | "new-points" | "keyframe"; throws ConfigError otherwise.
TrackingWait parse_tracking_wait(const std::string& name);

// The local BA's solver settings: BaConfig's, except that a stage ends after an accepted step that
// lowered its cost by at most 0.3 % of it. The next keyframe's local BA solves most of the same
// keyframes and points again, so the last small steps are taken then (docs/performance.md:
// 22 % fewer iterations, accuracy unchanged).
inline BaConfig local_ba_defaults() {
  BaConfig c;
  c.min_step_decrease = 3e-3;
  return c;
}

struct LocalMapperConfig {
  int min_observations = 3;  // a recent point seen by fewer keyframes (after 2 keyframes) is culled
  double min_found_ratio = 0.25;
  int fuse_neighbours = 10, fuse_second_neighbours = 5;
  double redundant_ratio = 0.9;       // keyframe culling: share of its close points seen by >= 3 others
  TriangulationConfig triangulation;  // new points from keyframe pairs
  bool local_ba = true;
  int local_ba_max_keyframes = 20;  // free keyframes: the new one and its strongest covisible neighbours
  BaConfig ba = local_ba_defaults();
  // Keyframes waiting or in work before tracking waits to insert another (threaded mode).
  std::size_t max_pending_keyframes = 2;
  TrackingWait tracking_wait = TrackingWait::kNewPoints;
};

struct LocalMapperStats {
  int keyframes_processed = 0, keyframes_culled = 0, points_culled = 0, points_fused = 0, points_triangulated = 0;
  std::vector<double> ba_ms, step_ms;
};

// Called after each processed keyframe (e.g. loop detection, map fusion). Runs on the mapper thread.
using KeyFrameProcessedCallback = std::function<void(const KeyFramePtr&)>;

// Called on the tracking thread around its waits for local mapping (a full queue, or the new
// keyframe's points): a scheduler can lend what the tracking thread holds meanwhile.
struct TrackingWaitHooks {
  std::function<void()> before, after;
};

class LocalMapper : public KeyFrameSink {
 public:
  LocalMapper(LocalMapperConfig config, std::shared_ptr<Map> map, bool threaded);
  ~LocalMapper() override;

  void set_on_processed(KeyFrameProcessedCallback cb) { on_processed_ = std::move(cb); }
  void set_wait_hooks(TrackingWaitHooks hooks) { wait_hooks_ = std::move(hooks); }

  // KeyFrameSink
  void insert_keyframe(const KeyFramePtr& kf) override;
  bool accepts_keyframes() const override { return !stopping_.load(); }

  std::size_t queued() const;

  // Processes one queued keyframe (non-threaded mode). Returns false if none was queued.
  bool step();
  // Processes everything queued, then stops the thread. Idempotent.
  void finish();
  LocalMapperStats stats() const;
  const std::shared_ptr<Map>& map() const { return map_; }

 private:
  void process(const KeyFramePtr& kf);
  void insert_into_map(KeyFrame* kf);
  void cull_map_points(KeyFrame* kf);
  void fuse_with_neighbours(KeyFrame* kf);
  int fuse_into(KeyFrame* target, const std::vector<MapPointPtr>& points);  // matched shared, written unique
  void local_bundle_adjustment(KeyFrame* kf);
  void cull_keyframes(KeyFrame* kf);
  bool is_redundant(const KeyFrame& candidate) const;  // [shared] most of its close points seen by 3 others

  LocalMapperConfig config_;
  std::shared_ptr<Map> map_;
  const bool threaded_;
  std::atomic<bool> stopping_{false};
  // Keyframes whose new points are fused (FIFO order; guarded by the worker's queue mutex). The
  // worker counts the keyframes inserted and fully processed; tracking waits on either.
  std::uint64_t points_done_ = 0;
  std::list<MapPointPtr> recent_points_;
  PointerSet ba_points_seen_;  // local_bundle_adjustment's scratch, reused keyframe to keyframe
  KeyFrameProcessedCallback on_processed_;
  TrackingWaitHooks wait_hooks_;
  mutable std::mutex stats_mutex_;
  LocalMapperStats stats_;
  QueueWorker<KeyFramePtr> worker_;  // last: its thread ends before the members it uses go
};

}  // namespace cslam
