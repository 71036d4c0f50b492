#pragma once
// Loop closing for one client map (ORB-SLAM2 class): for each keyframe local mapping finished,
// a BoW query of the map's own database (excluding covisible keyframes, above the lowest score
// of the keyframe's covisible neighbours), 3-consecutive consistency, geometric verification
// (RANSAC SE3 + refinement + projection check), then correction: the loop neighbourhood is moved
// by the loop transform, duplicated points are fused, loop edges added, the essential graph is
// optimised (Ceres) and points follow their reference keyframes. A global BA then runs in the
// background, interrupted by a new loop or a fusion.
#include <atomic>
#include <memory>
#include <mutex>
#include <thread>

#include "core/queue_worker.h"
#include "slam/loop/overlap_verifier.h"
#include "slam/loop/consistency.h"
#include "slam/map/map.h"
#include "optimize/bundle_adjustment.h"

namespace cslam {

struct LoopClosingConfig {
  bool enabled = true;
  int min_keyframes = 10;     // no detection before the map has this many keyframes
  int min_keyframe_gap = 10;  // keyframes between two loops
  int consistency = 3;
  OverlapVerifyConfig verify;
  int covisibility_edge_weight = 100;
  int pose_graph_iterations = 20;
  bool global_ba = true;
  int global_ba_iterations = 10;
  std::size_t queue_capacity = 64;
};

struct LoopEvent {
  KeyFrameId query, candidate;
  int inliers = 0;
  double correction_ms = 0, pose_graph_ms = 0;
  SE3 T_correction;       // corrected * before^-1 of the query keyframe (camera-to-world)
  SE3 T_query_candidate;  // verified camera-to-camera transform (p_query = T * p_candidate)
  double query_timestamp = 0, candidate_timestamp = 0;
};

struct LoopClosingStats {
  std::vector<LoopEvent> loops;
  std::vector<double> query_ms;      // detection per keyframe
  std::vector<double> global_ba_ms;  // completed global BAs
  int global_ba_started = 0, global_ba_completed = 0, global_ba_discarded = 0;
};

class LoopCloser {
 public:
  LoopCloser(LoopClosingConfig config, std::shared_ptr<Map> map, bool threaded);
  ~LoopCloser();

  void insert_keyframe(const KeyFramePtr& kf);
  // Processes one queued keyframe (non-threaded mode). False if none.
  bool step();
  // Processes what is queued, waits for the global BA, stops the threads. Idempotent.
  void finish();
  LoopClosingStats stats() const;

  // Detection + correction of one keyframe (what the thread does); returns true if a loop closed.
  bool process(const KeyFramePtr& kf);
  // Runs a global BA now on the calling thread (tests). Returns false if it was discarded.
  bool run_global_ba();

 private:
  bool detect(const KeyFramePtr& kf, KeyFramePtr& candidate, OverlapVerifyResult& verified);
  void correct(const KeyFramePtr& kf, const KeyFramePtr& candidate, const OverlapVerifyResult& verified);
  void start_global_ba();
  void stop_global_ba();

  LoopClosingConfig config_;
  std::shared_ptr<Map> map_;
  const bool threaded_;
  ConsistencyChecker consistency_;
  std::uint32_t last_loop_seq_ = 0;
  bool had_loop_ = false;

  std::thread gba_thread_;
  std::atomic<bool> gba_abort_{false};

  mutable std::mutex stats_mutex_;
  LoopClosingStats stats_;

  QueueWorker<KeyFramePtr> worker_;  // last: its thread ends before the members it uses go
};

}  // namespace cslam
