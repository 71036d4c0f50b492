// FusionManager's persistence hooks (declared in fusion/fusion_manager.h): the restored maps'
// groups, the seams that hold each group together and the pairs' last links.
#include <shared_mutex>

#include "core/error.h"
#include "fusion/fusion_manager.h"
#include "slam/map/map_locks.h"

namespace cslam {

namespace {

std::string name_of(MapKey k) { return "map " + std::to_string(k.index) + " of client " + std::to_string(k.client); }

}  // namespace

void FusionManager::restore_group(ClientId client, const std::shared_ptr<Map>& map, GroupId group) {
  std::lock_guard<std::mutex> lock(state_mutex_);
  if (group_.count(map.get())) return;
  registry_.push_back({client, map});
  group_[map.get()] = group.valid() ? group : GroupId::of_map(client, map->index());
}

std::shared_lock<std::shared_mutex> FusionManager::hold_links() const {
  return std::shared_lock<std::shared_mutex>(links_mutex_);
}

FusionState FusionManager::export_state() const {
  FusionState out;
  std::map<const Map*, MapKey> keys;
  std::vector<std::shared_ptr<Map>> alive;  // keeps the keyed maps valid below
  std::vector<StoredSeam> seams;
  {
    std::lock_guard<std::mutex> lock(state_mutex_);
    for (const auto& r : registry_)
      if (auto m = r.map.lock()) {
        keys[m.get()] = MapKey{r.client, m->index()};
        alive.push_back(std::move(m));
      }
    seams = seams_;
    for (const auto& [pair, seen] : last_link_)
      if (keys.count(pair.first) && keys.count(pair.second))
        out.last_links.push_back({keys.at(pair.first), keys.at(pair.second), seen});
    for (const auto& [map, seen] : keyframes_seen_)
      if (keys.count(map)) out.keyframes_seen.emplace_back(keys.at(map), seen);
    for (const auto& [pair, checker] : consistency_) {
      if (!keys.count(pair.first) || !keys.count(pair.second) || checker.tracked().empty()) continue;
      ConsistencyState c{keys.at(pair.first), keys.at(pair.second), {}};
      for (const auto& t : checker.tracked()) c.groups.emplace_back(t.members, t.count);
      out.consistency.push_back(std::move(c));
    }
  }
  for (const StoredSeam& s : seams) {
    const auto kept = s.kept_map.lock(), moved = s.moved_map.lock();
    if (!kept || !moved || !keys.count(kept.get()) || !keys.count(moved.get())) continue;
    SeamState ss;
    ss.kept_map = keys.at(kept.get());
    ss.moved_map = keys.at(moved.get());
    auto locks = lock_maps<std::shared_lock<std::shared_mutex>>({kept.get(), moved.get()});
    for (const SeamLink& l : s.seam.points)
      if (l.kept && l.moved && !l.kept->bad && !l.moved->bad) ss.links.emplace_back(l.kept->id, l.moved->id);
    for (const SeamEdge& e : s.seam.edges)
      if (e.kept && e.moved && !e.kept->bad && !e.moved->bad) ss.edges.push_back({e.kept->id, e.moved->id, e.weight});
    out.seams.push_back(std::move(ss));
  }
  return out;
}

void FusionManager::restore_state(const FusionState& state, const std::string& source) {
  // Everything is resolved and checked before anything is installed: a refused state leaves none.
  std::map<MapKey, std::shared_ptr<Map>> maps;
  {
    std::lock_guard<std::mutex> lock(state_mutex_);
    for (const auto& r : registry_)
      if (auto m = r.map.lock()) maps[MapKey{r.client, m->index()}] = std::move(m);
  }
  auto map_of = [&](MapKey k) -> const std::shared_ptr<Map>& {
    auto it = maps.find(k);
    if (it == maps.end()) throw InputError(source, "map fusion names " + name_of(k) + ", which is not in the snapshot");
    return it->second;
  };
  std::vector<StoredSeam> seams;
  for (const SeamState& ss : state.seams) {
    const auto& kept = map_of(ss.kept_map);
    const auto& moved = map_of(ss.moved_map);
    const std::string what = "the seam between " + name_of(ss.kept_map) + " and " + name_of(ss.moved_map);
    if (kept == moved || group_of(kept.get()) != group_of(moved.get()))
      throw InputError(source, what + " joins maps that are not two maps of one fused group");
    StoredSeam stored{kept, moved, {}};
    auto locks = lock_maps<std::shared_lock<std::shared_mutex>>({kept.get(), moved.get()});
    for (const auto& [a, b] : ss.links) {
      MapPointPtr pa = kept->map_point(a), pb = moved->map_point(b);
      if (!pa || !pb || pa->bad || pb->bad) throw InputError(source, what + " links a point its maps do not hold");
      stored.seam.points.push_back({std::move(pa), std::move(pb)});
    }
    for (const SeamEdgeState& e : ss.edges) {
      KeyFramePtr a = kept->keyframe(e.kept), b = moved->keyframe(e.moved);
      if (!a || !b) throw InputError(source, what + " names a keyframe its maps do not hold");
      stored.seam.edges.push_back({std::move(a), std::move(b), e.weight});
    }
    seams.push_back(std::move(stored));
  }
  std::vector<std::pair<std::pair<const Map*, const Map*>, ConsistencyChecker>> checkers;
  for (const ConsistencyState& c : state.consistency) {
    const auto& query = map_of(c.query);
    const auto& other = map_of(c.other);
    std::vector<ConsistencyChecker::Tracked> groups;
    {
      std::shared_lock<std::shared_mutex> lock(other->mutex);
      for (const auto& [members, count] : c.groups) {
        for (KeyFrameId id : members)
          if (!other->keyframe(id))
            throw InputError(source,
                             "map fusion's place recognition names a keyframe " + name_of(c.other) + " does not hold");
        groups.push_back({members, count});
      }
    }
    ConsistencyChecker checker(config_.consistency);
    checker.restore(std::move(groups));
    checkers.emplace_back(std::make_pair(query.get(), other.get()), std::move(checker));
  }
  std::vector<std::pair<const Map*, int>> seen;
  for (const auto& [key, n] : state.keyframes_seen) seen.emplace_back(map_of(key).get(), n);
  std::vector<std::pair<std::pair<const Map*, const Map*>, int>> links;
  for (const MapLinkState& l : state.last_links)
    links.emplace_back(std::make_pair(map_of(l.query).get(), map_of(l.other).get()), l.query_keyframes_at_link);

  std::lock_guard<std::mutex> lock(state_mutex_);
  for (auto& [pair, checker] : checkers) consistency_.insert_or_assign(pair, std::move(checker));
  for (const auto& [map, n] : seen) keyframes_seen_[map] = n;
  for (const auto& [pair, n] : links) last_link_[pair] = n;
  for (auto& s : seams) seams_.push_back(std::move(s));
}

}  // namespace cslam
