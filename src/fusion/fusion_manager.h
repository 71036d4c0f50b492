#pragma once
// Map fusion across clients (the paper's contribution): a thread that checks at a fixed rate
// whether new keyframes of one client's map overlap another client's map (BoW query of the other
// map's database above the keyframe's own covisibility score, 3-consecutive consistency, RANSAC
// SE3/Sim3, projection check) and, when they do, moves every map of the smaller group into the
// other group's frame. Tracking goes on: frame poses are kept relative to reference keyframes.
#include <chrono>
#include <condition_variable>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#include "bow/vocabulary.h"
#include "fusion/fusion_event.h"
#include "fusion/overlap_verifier.h"
#include "loop/consistency.h"
#include "map/map.h"

namespace cslam {

struct FusionConfig {
  bool enabled = true;
  double rate_hz = 4.0;              // check rate of the fusion thread
  int consistency = 3;               // consecutive consistent detections needed
  std::size_t max_candidates = 3;    // verified per detection
  std::size_t queue_capacity = 512;  // pending keyframes (oldest dropped beyond)
  OverlapVerifyConfig verify;
};

// Moves a whole map by T_new_old (keyframe poses and points); requires no lock held by the caller.
void transform_map(Map& map, const SE3& T_new_old);

class FusionManager {
 public:
  FusionManager(FusionConfig config, std::shared_ptr<const Vocabulary> vocabulary);
  ~FusionManager();
  FusionManager(const FusionManager&) = delete;
  FusionManager& operator=(const FusionManager&) = delete;

  // Called by local-mapping threads after a keyframe is processed.
  void notify(ClientId client, const std::shared_ptr<Map>& map, const KeyFramePtr& kf);
  // Processes what is queued, then stops the thread. Idempotent.
  void finish();

  int group_of(const Map* map) const;  // -1 if unknown
  std::vector<FusionEvent> events() const;
  std::size_t dropped() const;

 private:
  struct Pending {
    ClientId client;
    std::shared_ptr<Map> map;
    KeyFramePtr kf;
  };
  struct Registered {
    ClientId client;
    std::weak_ptr<Map> map;
  };
  void run();
  void process(const Pending& p);
  void fuse(const Pending& p, const std::shared_ptr<Map>& other, ClientId other_client, const SE3& T_wq_wc,
            const OverlapVerifyResult& v, double candidate_time, std::chrono::steady_clock::time_point hit);

  FusionConfig config_;
  std::shared_ptr<const Vocabulary> vocabulary_;
  const std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();

  std::mutex queue_mutex_;
  std::condition_variable queue_cv_;
  std::deque<Pending> queue_;
  bool stop_ = false;
  std::size_t dropped_ = 0;

  mutable std::mutex state_mutex_;  // groups, registry, events
  std::vector<Registered> registry_;
  std::map<const Map*, int> group_;
  std::map<std::pair<const Map*, const Map*>, ConsistencyChecker> consistency_;
  std::vector<FusionEvent> events_;
  std::thread thread_;
};

}  // namespace cslam
