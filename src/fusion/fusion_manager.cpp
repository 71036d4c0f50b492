#include "fusion/fusion_manager.h"

#include "slam/loop/place_candidates.h"

#include "slam/loop/global_ba.h"
#include "slam/map/map_locks.h"

#include <algorithm>
#include <shared_mutex>

#include "core/log.h"
#include "core/stopwatch.h"
#include "core/thread_priority.h"

namespace cslam {

void transform_map(Map& map, const SE3& T_new_old) {
  std::unique_lock<std::shared_mutex> lock(map.mutex);
  const SE3 T_old_new = T_new_old.inverse();
  for (const auto& kf : map.keyframes()) kf->T_cam_world = kf->T_cam_world * T_old_new;
  // A rigid move: normals turn with the map; distances and descriptors stay what they were.
  map.for_each_map_point([&](MapPoint& mp) {
    mp.position = T_new_old * mp.position;
    mp.normal = T_new_old.rotation() * mp.normal;
  });
  map.note_big_change();
}

FusionManager::FusionManager(FusionConfig config, std::shared_ptr<const Vocabulary> vocabulary)
    : config_(std::move(config)), vocabulary_(std::move(vocabulary)) {
  if (config_.threaded) thread_ = std::thread([this] { run(); });
}

FusionManager::~FusionManager() { finish(); }

void FusionManager::notify(ClientId client, const std::shared_ptr<Map>& map, const KeyFramePtr& kf) {
  {
    std::lock_guard<std::mutex> lock(state_mutex_);
    if (!group_.count(map.get())) {
      registry_.push_back({client, map});
      group_[map.get()] = GroupId::of_map(client, map->index());
    }
  }
  if (!config_.enabled) return;
  if (!config_.threaded) {
    // Several clients' workers may notify at once: one check at a time, in arrival order.
    std::lock_guard<std::mutex> step(inline_mutex_);
    process({client, map, kf});
    return;
  }
  std::lock_guard<std::mutex> lock(queue_mutex_);
  if (stop_) return;
  if (queue_.size() >= config_.queue_capacity) {
    queue_.pop_front();
    ++dropped_;
  }
  queue_.push_back({client, map, kf});
  // Processed at the next tick of the fixed-rate loop.
}

void FusionManager::finish() {
  {
    std::lock_guard<std::mutex> lock(queue_mutex_);
    stop_ = true;
  }
  queue_cv_.notify_all();
  if (thread_.joinable()) thread_.join();
  // The fusion thread has ended: the group BA it started is ours to join (and is let complete).
  if (group_ba_thread_.joinable()) group_ba_thread_.join();
}

void FusionManager::forget(const std::vector<const Map*>& maps) {
  auto listed = [&maps](const Map* m) { return std::find(maps.begin(), maps.end(), m) != maps.end(); };
  {
    std::unique_lock<std::mutex> lock(queue_mutex_);
    queue_.erase(std::remove_if(queue_.begin(), queue_.end(), [&](const Pending& p) { return listed(p.map.get()); }),
                 queue_.end());
    idle_cv_.wait(lock, [this] { return !processing_; });
  }
  std::lock_guard<std::mutex> lock(state_mutex_);
  registry_.erase(std::remove_if(registry_.begin(), registry_.end(),
                                 [&](const Registered& r) {
                                   const auto m = r.map.lock();
                                   return m && listed(m.get());
                                 }),
                  registry_.end());
  for (const Map* m : maps) group_.erase(m);
  for (auto it = consistency_.begin(); it != consistency_.end();)
    it = listed(it->first.first) || listed(it->first.second) ? consistency_.erase(it) : std::next(it);
  for (auto it = last_link_.begin(); it != last_link_.end();)
    it = listed(it->first.first) || listed(it->first.second) ? last_link_.erase(it) : std::next(it);
  for (const Map* m : maps) {
    keyframes_seen_.erase(m);
    loops_seen_.erase(m);
  }
  seams_.erase(std::remove_if(seams_.begin(), seams_.end(),
                              [&](const StoredSeam& s) {
                                const auto a = s.kept_map.lock(), b = s.moved_map.lock();
                                return (a && listed(a.get())) || (b && listed(b.get()));
                              }),
               seams_.end());
}

GroupId FusionManager::group_of(const Map* map) const {
  std::lock_guard<std::mutex> lock(state_mutex_);
  auto it = group_.find(map);
  return it == group_.end() ? GroupId() : it->second;
}

std::vector<FusionEvent> FusionManager::events() const {
  std::lock_guard<std::mutex> lock(state_mutex_);
  return events_;
}

GroupBaStats FusionManager::group_ba_stats() const {
  std::lock_guard<std::mutex> lock(state_mutex_);
  return group_ba_stats_;
}

std::size_t FusionManager::dropped() const {
  std::lock_guard<std::mutex> lock(const_cast<std::mutex&>(queue_mutex_));
  return dropped_;
}

void FusionManager::run() {
  name_current_thread("fusion");
  lower_current_thread_priority();
  const auto period = std::chrono::duration<double>(1.0 / std::max(0.1, config_.rate_hz));
  std::unique_lock<std::mutex> lock(queue_mutex_);
  for (;;) {
    // Fixed-rate check; finish() wakes it at once.
    queue_cv_.wait_for(lock, period, [&] { return stop_; });
    std::deque<Pending> batch;
    batch.swap(queue_);
    const bool stopping = stop_;
    processing_ = true;
    lock.unlock();
    for (const auto& p : batch) process(p);
    batch.clear();
    lock.lock();
    processing_ = false;
    idle_cv_.notify_all();
    if (stopping && queue_.empty()) return;
  }
}

void FusionManager::process(const Pending& p) {
  const Map& map = *p.map;
  BowVector bow;
  double min_score = 1.0;
  std::uint64_t loops = 0;
  {
    std::shared_lock<std::shared_mutex> lock(p.map->mutex);
    if (p.kf->bad) return;
    const auto covisibles = p.kf->covisibles();
    if (covisibles.empty()) return;
    bow = p.kf->data->bow;
    min_score = min_covisible_score(*p.kf);
    loops = p.map->loops_closed();
  }
  std::vector<Registered> others, same_group;
  GroupId my_group;
  bool readjust = false;
  {
    std::lock_guard<std::mutex> lock(state_mutex_);
    ++keyframes_seen_[&map];
    my_group = group_.at(&map);
    for (const auto& r : registry_) {
      auto m = r.map.lock();
      if (!m || m.get() == &map) continue;
      (group_.at(m.get()) != my_group ? others : same_group).push_back(r);
    }
    // A loop closure moved this map alone, or the group's last BA was discarded because a map
    // moved while it ran: the group's links are to be balanced again.
    std::uint64_t& seen = loops_seen_[&map];
    readjust = !same_group.empty() && (loops != seen || group_ba_pending_.count(my_group) > 0);
    seen = loops;
  }
  if (try_fuse(p, others, bow, min_score)) return;
  if (config_.reencounter.enabled && try_reencounter(p, same_group, bow, min_score)) return;
  if (readjust) start_group_ba(my_group);
}

std::vector<KeyFrameId> FusionManager::consistent_candidates(const Pending& p, Map& other, const BowVector& bow,
                                                             double min_score) {
  std::vector<ConsistencyChecker::Group> groups;
  {
    std::shared_lock<std::shared_mutex> lock(other.mutex);
    groups = query_candidate_groups(other, bow, min_score, [](KeyFrameId) { return false; });
  }
  std::lock_guard<std::mutex> lock(state_mutex_);
  auto key = std::make_pair(static_cast<const Map*>(p.map.get()), static_cast<const Map*>(&other));
  auto it = consistency_.find(key);
  if (it == consistency_.end()) it = consistency_.emplace(key, ConsistencyChecker(config_.consistency)).first;
  return it->second.update(groups);
}

std::optional<FusionManager::Verified> FusionManager::verified_candidate(const Pending& p, Map& other,
                                                                         ClientId other_client, const BowVector& bow,
                                                                         double min_score) {
  const std::vector<KeyFrameId> consistent = consistent_candidates(p, other, bow, min_score);
  if (consistent.empty()) return std::nullopt;
  Verified out;
  out.hit = std::chrono::steady_clock::now();
  for (size_t i = 0; i < consistent.size() && i < config_.max_candidates; ++i) {
    auto locks = lock_maps<std::shared_lock<std::shared_mutex>>({p.map.get(), &other});
    out.candidate = other.keyframe(consistent[i]);
    if (!out.candidate || out.candidate->bad || p.kf->bad) continue;
    out.v = verify_overlap(*p.kf, *out.candidate, out.candidate->best_covisibles(10), config_.verify);
    if (!out.v.accepted) {
      logger("fusion")->debug("client {} kf {} vs client {} kf {}: rejected ({}; bow {} ransac {} refined {} proj {})",
                              p.client, p.kf->id.seq, other_client, out.candidate->id.seq, out.v.reason,
                              out.v.bow_matches, out.v.ransac_inliers, out.v.refined_inliers, out.v.projection_matches);
      continue;
    }
    // T_wq_wc = T_wq_camq * S_camq_camc * T_camc_wc
    out.T_wq_wc = p.kf->T_world_cam() * out.v.S_query_candidate.to_se3() * out.candidate->T_cam_world;
    return out;
  }
  return std::nullopt;
}

bool FusionManager::try_fuse(const Pending& p, const std::vector<Registered>& others, const BowVector& bow,
                             double min_score) {
  for (const auto& other_reg : others) {
    auto other = other_reg.map.lock();
    if (!other) continue;
    const auto found = verified_candidate(p, *other, other_reg.client, bow, min_score);
    if (!found) continue;
    fuse(p, other, other_reg.client, found->candidate, found->T_wq_wc, found->v, found->hit);
    return true;
  }
  return false;
}

FusionEvent FusionManager::link_event(const char* kind, const Pending& p, ClientId other_client, GroupId group,
                                      const KeyFramePtr& candidate, const OverlapVerifyResult& v, const Seam& seam,
                                      std::chrono::steady_clock::time_point hit) const {
  FusionEvent e;
  e.kind = kind;
  e.client_a = p.client;
  e.client_b = other_client;
  e.group = group;
  e.inliers = v.final_inliers;
  e.duration_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - hit).count();
  e.wall_time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  e.query_timestamp = p.kf->timestamp();
  e.candidate_timestamp = candidate->timestamp();
  e.T_query_candidate = v.S_query_candidate.to_se3();
  e.seam_points = int(seam.points.size());
  e.seam_edges = int(seam.edges.size());
  return e;
}

void FusionManager::fuse(const Pending& p, const std::shared_ptr<Map>& other, ClientId other_client,
                         const KeyFramePtr& candidate, const SE3& T_wq_wc, const OverlapVerifyResult& v,
                         std::chrono::steady_clock::time_point hit) {
  // Members of both groups, and which group moves (the one with fewer keyframes).
  std::vector<std::shared_ptr<Map>> group_q, group_c;
  GroupId gq, gc;
  {
    std::lock_guard<std::mutex> lock(state_mutex_);
    gq = group_.at(p.map.get());
    gc = group_.at(other.get());
    if (gq == gc) return;
    for (const auto& r : registry_)
      if (auto m = r.map.lock()) {
        if (group_.at(m.get()) == gq)
          group_q.push_back(m);
        else if (group_.at(m.get()) == gc)
          group_c.push_back(m);
      }
  }
  auto keyframes_of = [](const std::vector<std::shared_ptr<Map>>& g) {
    std::size_t n = 0;
    for (const auto& m : g) {
      std::shared_lock<std::shared_mutex> lock(m->mutex);
      n += m->num_keyframes();
    }
    return n;
  };
  stop_group_ba();  // cut short: what it solved so far is written before the move
  std::unique_lock<std::shared_mutex> moving_maps(links_mutex_);
  const std::size_t kf_q = keyframes_of(group_q), kf_c = keyframes_of(group_c);
  const bool move_candidate_side = kf_c <= kf_q;
  const auto& moving = move_candidate_side ? group_c : group_q;
  const SE3 T_new_old = move_candidate_side ? T_wq_wc : T_wq_wc.inverse();
  for (const auto& m : moving) transform_map(*m, T_new_old);
  // The seam: points both maps hold around the match, linked; cross-map covisibility.
  const std::shared_ptr<Map>& kept_map = move_candidate_side ? p.map : other;
  const std::shared_ptr<Map>& moved_map = move_candidate_side ? other : p.map;
  const KeyFramePtr& kept_kf = move_candidate_side ? p.kf : candidate;
  const KeyFramePtr& moved_kf = move_candidate_side ? candidate : p.kf;
  // Matched under shared locks (the robots keep tracking), linked under unique ones.
  std::vector<SeamLink> pairs;
  {
    auto locks = lock_maps<std::shared_lock<std::shared_mutex>>({kept_map.get(), moved_map.get()});
    if (!kept_kf->bad && !moved_kf->bad) pairs = match_seam(*kept_kf, *moved_kf, config_.seam);
  }
  Seam seam;
  {
    auto locks = lock_maps<std::unique_lock<std::shared_mutex>>({kept_map.get(), moved_map.get()});
    seam = link_seam(*kept_map, *moved_map, pairs, config_.seam);
  }
  const GroupId kept = move_candidate_side ? gq : gc;
  FusionEvent e = link_event("fusion", p, other_client, kept, candidate, v, seam, hit);
  e.keyframes_moved = int(move_candidate_side ? kf_c : kf_q);
  e.keyframes_kept = int(move_candidate_side ? kf_q : kf_c);
  {
    std::lock_guard<std::mutex> lock(state_mutex_);
    for (auto& [m, g] : group_)
      if (g == gq || g == gc) g = kept;
    events_.push_back(e);
    seams_.push_back({kept_map, moved_map, std::move(seam)});
    last_link_[{kept_map.get(), moved_map.get()}] = keyframes_seen_[kept_map.get()];
    last_link_[{moved_map.get(), kept_map.get()}] = keyframes_seen_[moved_map.get()];
  }
  moving_maps.unlock();
  logger("fusion")->info(
      "fused client {} with client {} into group {} ({} keyframes moved onto {}): {} inliers, {} "
      "projection matches, window fit {} inliers over {} keyframes, {} seam points, {} cross-map "
      "covisibility edges, {:.1f} ms",
      p.client, other_client, kept.value(), e.keyframes_moved, e.keyframes_kept, v.final_inliers, v.projection_matches,
      v.window_inliers, v.window_keyframes, e.seam_points, e.seam_edges, e.duration_ms);
  start_group_ba(kept);
}

void FusionManager::stop_group_ba() {
  group_ba_abort_ = true;
  if (group_ba_thread_.joinable()) group_ba_thread_.join();
  group_ba_abort_ = false;
}

void FusionManager::start_group_ba(GroupId group) {
  stop_group_ba();
  if (!config_.group_ba) return;
  if (!config_.threaded) {
    run_group_ba_of(group);
    return;
  }
  group_ba_thread_ = std::thread([this, group] {
    name_current_thread("group-ba");
    run_group_ba_of(group);
  });
}

BaResult FusionManager::solve_group_ba(GlobalBa& gba) {
  if (!config_.threaded) return gba.solve(config_.group_ba_iterations, &group_ba_abort_, true);
  // Only the solve runs at the lowest priority: the snapshot before it and the writes after it
  // hold the maps' locks that the robots' tracking waits on.
  BaResult r;
  run_at_lower_priority(kGroupBaNice, "group-ba",
                        [&] { r = gba.solve(config_.group_ba_iterations, &group_ba_abort_, true); });
  return r;
}

bool FusionManager::run_group_ba(const Map* map) {
  const GroupId g = group_of(map);
  return g.valid() && run_group_ba_of(g);
}

bool FusionManager::run_group_ba_of(GroupId group) {
  Stopwatch sw;
  std::vector<std::shared_ptr<Map>> members;  // kept alive for the run
  std::vector<std::pair<MapPointPtr, MapPointPtr>> links;
  {
    std::lock_guard<std::mutex> lock(state_mutex_);
    for (const auto& r : registry_)
      if (auto m = r.map.lock())
        if (group_.at(m.get()) == group) members.push_back(m);
    for (const auto& s : seams_) {
      auto a = s.kept_map.lock(), b = s.moved_map.lock();
      if (!a || !b || group_.at(a.get()) != group || group_.at(b.get()) != group) continue;
      for (const auto& l : s.seam.points) links.emplace_back(l.kept, l.moved);
    }
    ++group_ba_stats_.started;
  }
  if (members.size() < 2) return false;
  // The largest map first: its origin holds the gauge.
  std::vector<Map*> maps;
  for (const auto& m : members) maps.push_back(m.get());
  GlobalBa gba;
  {
    auto locks = lock_maps<std::shared_lock<std::shared_mutex>>(maps);
    std::stable_sort(maps.begin(), maps.end(),
                     [](const Map* a, const Map* b) { return a->num_keyframes() > b->num_keyframes(); });
    gba.snapshot(maps, links);
  }
  // Cut short by the next fusion or re-encounter, it still writes what it solved so far: every
  // accepted step lowered the cost, and the next BA starts from there (nothing solved is thrown
  // away when links come faster than a whole BA takes).
  const BaResult r = solve_group_ba(gba);
  const bool progress = !r.partial || r.final_cost < r.initial_cost;
  // Written map by map, each under its own exclusive lock (a robot's tracking waits only while its
  // map is written); the links' lock keeps snapshots from seeing the group half written.
  bool applied = false;
  double locked_ms = 0;  // the longest exclusive hold of one map
  if (progress) {
    std::unique_lock<std::shared_mutex> moving_maps(links_mutex_);
    applied = true;
    for (std::size_t m = 0; m < maps.size(); ++m) {
      std::unique_lock<std::shared_mutex> lock(maps[m]->mutex);
      Stopwatch locked;
      // A map that had a big change meanwhile (its loop correction) keeps it; the group is
      // balanced again at its next keyframe (group_ba_pending_).
      applied = gba.apply_map(m, r) && applied;
      locked_ms = std::max(locked_ms, locked.ms());
    }
  }
  std::lock_guard<std::mutex> lock(state_mutex_);
  if (applied)
    group_ba_pending_.erase(group);
  else if (!r.aborted)
    group_ba_pending_.insert(group);  // a map moved meanwhile: again at the next keyframe
  if (applied && r.partial) ++group_ba_stats_.cut_short;
  if (applied) {
    ++group_ba_stats_.completed;
    group_ba_stats_.ms.push_back(sw.ms());
    group_ba_stats_.last_keyframes = int(gba.num_keyframes());
    group_ba_stats_.last_points = int(gba.num_points());
    group_ba_stats_.last_linked_points = int(links.size());
    logger("fusion")->info(
        "group {} global BA{}: {} maps, {} keyframes, {} points ({} linked), {} iterations, {:.0f} ms, locked {:.1f} "
        "ms",
        group.value(), r.partial ? " (cut short, progress kept)" : "", maps.size(), gba.num_keyframes(),
        gba.num_points(), links.size(), r.iterations, sw.ms(), locked_ms);
  } else {
    ++group_ba_stats_.discarded;
    logger("fusion")->info("group {} global BA discarded ({}) after {:.0f} ms", group.value(),
                           progress ? "a map moved meanwhile; the others took it" : "cut short before its first step",
                           sw.ms());
  }
  return applied;
}

}  // namespace cslam
