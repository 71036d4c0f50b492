#pragma once
// Map fusion across clients (the paper's contribution): a thread that checks at a fixed rate
// whether new keyframes of one client's map overlap another client's map (BoW query of the other
// map's database above the keyframe's own covisibility score, 3-consecutive consistency, RANSAC
// SE3/Sim3, projection check) and, when they do, moves every map of the smaller group into the
// other group's frame, links the points the two maps share around the match (seam), and runs a
// global BA over every map of the new group in the background, linked points estimated as one.
// Maps of one group keep being matched against each other: a verified place pair between them is
// a re-encounter (fusion/reencounter.h): the query map's drift is corrected, the seam there
// linked, and the group BA runs again. Tracking goes on: frame poses are kept relative to
// reference keyframes.
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <shared_mutex>
#include <thread>
#include <vector>

#include "slam/bow/vocabulary.h"
#include "fusion/fusion_event.h"
#include "fusion/fusion_state.h"
#include "slam/loop/overlap_verifier.h"
#include "fusion/reencounter.h"
#include "fusion/seam.h"
#include "slam/loop/consistency.h"
#include "slam/map/map.h"
#include "optimize/bundle_adjustment.h"

namespace cslam {

class GlobalBa;

struct FusionConfig {
  bool enabled = true;
  // false: no thread; every keyframe is checked inside notify() and the group BA runs there too,
  // so a run stepped frame by frame is deterministic.
  bool threaded = true;
  double rate_hz = 4.0;              // check rate of the fusion thread
  int consistency = 3;               // consecutive consistent detections needed
  std::size_t max_candidates = 3;    // verified per detection
  std::size_t queue_capacity = 512;  // pending keyframes (oldest dropped beyond)
  OverlapVerifyConfig verify;
  SeamConfig seam;
  bool group_ba = true;  // global BA over a fused group after each fusion
  int group_ba_iterations = 10;
  ReencounterConfig reencounter;  // place pairs between maps already in one group
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
  // Processes what is queued, lets a running group BA complete, then stops the threads. Idempotent.
  void finish();

  // Forgets maps whose client was retired (its mapping threads joined, so no more notify() for
  // them): drops their queued keyframes, waits for a batch being processed, then removes them
  // from the registry, groups, consistency state and seams. Call only for maps of an unfused client.
  void forget(const std::vector<const Map*>& maps);

  GroupId group_of(const Map* map) const;  // invalid if unknown
  // Persistence (fusion_manager_state.cpp): registers a restored map in its saved group (its
  // poses are already in that group's frame); invalid: a group of its own.
  void restore_group(ClientId client, const std::shared_ptr<Map>& map, GroupId group);
  // The seams of every group and the pairs' last links, as values (points and keyframes gone bad
  // are left out). Call under hold_links() together with the maps' export for one consistent state.
  FusionState export_state() const;
  // After every map of the state was restored and registered (restore_group): its seams and last
  // links. Throws InputError(source, ...) if they name maps, points or keyframes not restored.
  void restore_state(const FusionState& state, const std::string& source);
  // While held, no fusion, re-encounter or group BA moves a map or links points: a snapshot that
  // exports every client's maps under it sees each group in one frame.
  std::shared_lock<std::shared_mutex> hold_links() const;
  std::vector<FusionEvent> events() const;
  GroupBaStats group_ba_stats() const;
  std::size_t dropped() const;
  // Runs the group BA of `map`'s group now on the calling thread (tests). False if discarded.
  bool run_group_ba(const Map* map);

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
  void fuse(const Pending& p, const std::shared_ptr<Map>& other, ClientId other_client, const KeyFramePtr& candidate,
            const SE3& T_wq_wc, const OverlapVerifyResult& v, std::chrono::steady_clock::time_point hit);
  void reencounter(const Pending& p, const std::shared_ptr<Map>& other, ClientId other_client,
                   const KeyFramePtr& candidate, const OverlapVerifyResult& v,
                   std::chrono::steady_clock::time_point hit);
  // The event of a link (fusion or re-encounter) between the query keyframe and `candidate`; the
  // caller adds which keyframes moved and which stayed.
  FusionEvent link_event(const char* kind, const Pending& p, ClientId other_client, GroupId group,
                         const KeyFramePtr& candidate, const OverlapVerifyResult& v, const Seam& seam,
                         std::chrono::steady_clock::time_point hit) const;
  // Fusion, then re-encounters, with the maps of the other groups / of the query's own group.
  // Each true if it linked the query's map (and started the group BA).
  bool try_fuse(const Pending& p, const std::vector<Registered>& others, const BowVector& bow, double min_score);
  bool try_reencounter(const Pending& p, const std::vector<Registered>& same_group, const BowVector& bow,
                       double min_score);
  // The first of `other`'s consistent candidates (at most config_.max_candidates tried) that
  // verify_overlap accepts against the query keyframe, with T_wq_wc = the query map's world from
  // the candidate map's. Both maps are held shared only while one candidate is verified.
  struct Verified {
    KeyFramePtr candidate;
    OverlapVerifyResult v;
    SE3 T_wq_wc;
    std::chrono::steady_clock::time_point hit;  // when the consistent candidates were found
  };
  std::optional<Verified> verified_candidate(const Pending& p, Map& other, ClientId other_client, const BowVector& bow,
                                             double min_score);
  // Consistent candidates of `other` for the query keyframe (pair-wise consistency state).
  std::vector<KeyFrameId> consistent_candidates(const Pending& p, Map& other, const BowVector& bow, double min_score);
  void start_group_ba(GroupId group);
  bool run_group_ba_of(GroupId group);
  BaResult solve_group_ba(GlobalBa& gba);  // at kGroupBaNice on a thread of its own when threaded
  void stop_group_ba();
  struct StoredSeam {
    std::weak_ptr<Map> kept_map, moved_map;
    Seam seam;
  };

  FusionConfig config_;
  std::shared_ptr<const Vocabulary> vocabulary_;
  const std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();

  std::mutex queue_mutex_;
  std::mutex inline_mutex_;  // threaded = false: serialises notify() across client workers
  std::condition_variable queue_cv_;
  std::deque<Pending> queue_;
  bool stop_ = false;
  bool processing_ = false;  // a batch is being processed (forget() waits for it)
  std::condition_variable idle_cv_;
  std::size_t dropped_ = 0;

  // Held exclusively while a fusion, a re-encounter or a group BA changes maps; shared by
  // hold_links(). Taken before any map lock, never while one is held.
  mutable std::shared_mutex links_mutex_;
  mutable std::mutex state_mutex_;  // groups, registry, events
  std::vector<Registered> registry_;
  std::map<const Map*, GroupId> group_;
  std::map<std::pair<const Map*, const Map*>, ConsistencyChecker> consistency_;
  std::vector<FusionEvent> events_;
  std::vector<StoredSeam> seams_;
  std::map<const Map*, int> keyframes_seen_;        // keyframes processed per map (fusion thread)
  std::map<const Map*, std::uint64_t> loops_seen_;  // Map::loops_closed() when last processed
  std::set<GroupId> group_ba_pending_;              // groups whose last group BA was discarded (a map moved meanwhile)
  // keyframes_seen_ of the query map when the pair (query, other) last fused or re-encountered
  std::map<std::pair<const Map*, const Map*>, int> last_link_;
  GroupBaStats group_ba_stats_;
  std::thread thread_;
  std::thread group_ba_thread_;  // owned by the fusion thread (started, aborted, joined there)
  std::atomic<bool> group_ba_abort_{false};
};

}  // namespace cslam
