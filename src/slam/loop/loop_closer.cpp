#include "slam/loop/loop_closer.h"

#include "slam/loop/global_ba.h"

#include <shared_mutex>
#include <unordered_set>

#include "slam/bow/vocabulary.h"
#include "core/log.h"
#include "core/stopwatch.h"
#include "core/thread_priority.h"
#include "slam/loop/place_candidates.h"
#include "slam/loop/essential_graph.h"
#include "slam/match/projection_search.h"

namespace cslam {

LoopCloser::LoopCloser(LoopClosingConfig config, std::shared_ptr<Map> map, bool threaded)
    : config_(std::move(config)),
      map_(std::move(map)),
      threaded_(threaded),
      consistency_(config_.consistency),
      worker_(threaded, "loop/c" + std::to_string(map_->client()), [this](const KeyFramePtr& kf) { process(kf); }) {
  worker_.start();
}

LoopCloser::~LoopCloser() { finish(); }

void LoopCloser::insert_keyframe(const KeyFramePtr& kf) {
  if (config_.enabled) worker_.push(kf, config_.queue_capacity);
}

bool LoopCloser::step() { return worker_.step(); }

void LoopCloser::finish() {
  worker_.stop();
  if (gba_thread_.joinable()) gba_thread_.join();  // let a running global BA complete
}

LoopClosingStats LoopCloser::stats() const {
  std::lock_guard<std::mutex> lock(stats_mutex_);
  return stats_;
}

bool LoopCloser::process(const KeyFramePtr& kf) {
  KeyFramePtr candidate;
  OverlapVerifyResult verified;
  if (!detect(kf, candidate, verified)) return false;
  correct(kf, candidate, verified);
  return true;
}

bool LoopCloser::detect(const KeyFramePtr& kf, KeyFramePtr& candidate, OverlapVerifyResult& verified) {
  Stopwatch sw;
  std::vector<ConsistencyChecker::Group> groups;
  {
    std::shared_lock<std::shared_mutex> lock(map_->mutex);
    if (kf->bad || int(map_->num_keyframes()) < config_.min_keyframes) return false;
    if (had_loop_ && kf->id.seq < last_loop_seq_ + std::uint32_t(config_.min_keyframe_gap)) return false;
    const auto covisibles = kf->covisibles();
    if (covisibles.empty()) return false;
    std::unordered_set<KeyFrameId> excluded{kf->id};
    for (KeyFrame* c : covisibles) excluded.insert(c->id);
    groups = query_candidate_groups(*map_, kf->data->bow, min_covisible_score(*kf),
                                    [&](KeyFrameId id) { return excluded.count(id) > 0; });
  }
  const auto consistent = consistency_.update(groups);
  bool found = false;
  if (!consistent.empty()) {
    std::shared_lock<std::shared_mutex> lock(map_->mutex);
    for (KeyFrameId id : consistent) {
      KeyFramePtr cand = map_->keyframe(id);
      if (!cand || cand->bad || kf->bad) continue;
      OverlapVerifyResult v = verify_overlap(*kf, *cand, cand->best_covisibles(10), config_.verify);
      if (v.accepted) {
        candidate = cand;
        verified = v;
        found = true;
        break;
      }
    }
  }
  std::lock_guard<std::mutex> lock(stats_mutex_);
  stats_.query_ms.push_back(sw.ms());
  return found;
}

void LoopCloser::correct(const KeyFramePtr& kf, const KeyFramePtr& candidate, const OverlapVerifyResult& v) {
  stop_global_ba();
  Stopwatch sw;
  LoopEvent event;
  event.query = kf->id;
  event.candidate = candidate->id;
  event.inliers = v.final_inliers;
  event.query_timestamp = kf->timestamp();
  event.candidate_timestamp = candidate->timestamp();
  event.T_query_candidate = v.S_query_candidate.to_se3();
  double pg_ms = 0;
  {
    std::unique_lock<std::shared_mutex> lock(map_->mutex);
    if (kf->bad || candidate->bad) return;
    // Corrected pose of the query keyframe: p_kf = S * p_cand = S * T_cand_w * X.
    const SE3 T_kf_w_corrected = v.S_query_candidate.to_se3() * candidate->T_cam_world;
    const SE3 T_w_kf_old = kf->T_world_cam();
    // Neighbourhood moved rigidly with the query keyframe.
    std::vector<KeyFrame*> neighbourhood = kf->covisibles();
    neighbourhood.push_back(kf.get());
    // Keyframes tracking created that local mapping has not connected yet are the newest ones,
    // next to the query keyframe: they move rigidly with it (no fusion or links until connected).
    std::vector<KeyFrame*> rigid = neighbourhood;
    for (const auto& k : map_->keyframes())
      if (!k->bad && k->awaiting_connection() && k != kf) rigid.push_back(k.get());
    EssentialGraphInput in;
    in.min_covisibility_weight = config_.covisibility_edge_weight;
    std::map<KeyFrame*, SE3, ById> before;
    for (KeyFrame* n : rigid) {
      if (n->bad) continue;
      before[n] = n->T_cam_world;
      const SE3 T_n_kf = n->T_cam_world * T_w_kf_old;
      in.initial_T_cam_world[n] = T_n_kf * T_kf_w_corrected;
      in.measured_T_cam_world[n] = n->T_cam_world;
    }
    event.T_correction = T_kf_w_corrected.inverse() * kf->T_cam_world;
    // Points seen by the neighbourhood move with the keyframe that sees them (once each).
    std::unordered_set<MapPoint*> moved;
    for (KeyFrame* n : rigid) {
      if (n->bad) continue;
      const SE3 delta = in.initial_T_cam_world[n].inverse() * before[n];  // T_w_new * T_old_w
      for (const auto& mp : n->map_points)
        if (mp && !mp->bad && moved.insert(mp.get()).second) mp->position = delta * mp->position;
      n->T_cam_world = in.initial_T_cam_world[n];
    }
    // Fuse the candidate group's points into the corrected neighbourhood; loop edges.
    std::vector<MapPointPtr> loop_points;
    std::unordered_set<MapPoint*> seen;
    std::vector<KeyFrame*> loop_group = candidate->covisibles();
    loop_group.push_back(candidate.get());
    for (KeyFrame* c : loop_group)
      for (const auto& mp : c->map_points)
        if (mp && !mp->bad && seen.insert(mp.get()).second) loop_points.push_back(mp);
    for (KeyFrame* n : neighbourhood)
      if (!n->bad) fuse(*map_, n, loop_points, 4.0);
    std::set<KeyFrame*, ById> before_links(neighbourhood.begin(), neighbourhood.end());
    for (KeyFrame* n : neighbourhood) {
      if (n->bad) continue;
      map_->update_connections(n);
      for (const auto& [other, w] : n->connections)
        if (!before_links.count(other)) in.new_connections[n].insert(other);
    }
    kf->loop_edges.insert(candidate.get());
    candidate->loop_edges.insert(kf.get());
    in.fixed.insert(candidate.get());
    in.new_connections[kf.get()].insert(candidate.get());

    // Essential graph from the corrected state; points follow their reference keyframes.
    Stopwatch pg;
    const EssentialGraph graph = build_essential_graph(*map_, in);
    PoseGraphConfig pgc;
    pgc.fix_scale = true;
    pgc.max_iterations = config_.pose_graph_iterations;
    const PoseGraphResult r = optimize_pose_graph(graph.nodes, graph.edges, pgc);
    pg_ms = pg.ms();
    std::map<KeyFrame*, SE3, ById> pre_opt;
    for (size_t i = 0; i < graph.keyframes.size(); ++i) {
      KeyFrame* k = graph.keyframes[i];
      pre_opt[k] = k->T_cam_world;
      if (r.converged) k->T_cam_world = r.S_world_node[i].to_se3().inverse();
    }
    if (r.converged) points_follow_references(*map_, pre_opt);
    map_->note_big_change();
    map_->note_loop_closed();
    last_loop_seq_ = kf->id.seq;
    had_loop_ = true;
  }
  consistency_.reset();
  event.correction_ms = sw.ms();
  event.pose_graph_ms = pg_ms;
  logger("loop")->info("client {}: loop {} -> {} closed ({} inliers, correction {:.1f} ms, pose graph {:.1f} ms)",
                       map_->client(), kf->id.seq, candidate->id.seq, v.final_inliers, event.correction_ms, pg_ms);
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    stats_.loops.push_back(event);
  }
  if (config_.global_ba) start_global_ba();
}

void LoopCloser::stop_global_ba() {
  gba_abort_ = true;
  if (gba_thread_.joinable()) gba_thread_.join();
  gba_abort_ = false;
}

void LoopCloser::start_global_ba() {
  stop_global_ba();
  if (threaded_)
    gba_thread_ = std::thread([this] {
      name_current_thread("loop-gba/c" + std::to_string(map_->client()));
      lower_current_thread_priority();
      run_global_ba();
    });
  else
    run_global_ba();
}

bool LoopCloser::run_global_ba() {
  Stopwatch sw;
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    ++stats_.global_ba_started;
  }
  GlobalBa gba;
  {
    std::shared_lock<std::shared_mutex> lock(map_->mutex);
    gba.snapshot({map_.get()});
  }
  const BaResult r = gba.solve(config_.global_ba_iterations, &gba_abort_);
  bool applied = false;
  {
    std::unique_lock<std::shared_mutex> lock(map_->mutex);
    applied = gba.apply(r);
  }
  std::lock_guard<std::mutex> lock(stats_mutex_);
  if (applied) {
    ++stats_.global_ba_completed;
    stats_.global_ba_ms.push_back(sw.ms());
  } else {
    ++stats_.global_ba_discarded;
  }
  return applied;
}

}  // namespace cslam
