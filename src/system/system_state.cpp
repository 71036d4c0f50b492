// keep_fusion_within_maps (declared in system/system_state.h).
#include "system/system_state.h"

#include <algorithm>
#include <map>
#include <set>

namespace cslam {

namespace {

template <class T, class Pred>
void erase_where(std::vector<T>& v, Pred pred) {
  v.erase(std::remove_if(v.begin(), v.end(), pred), v.end());
}

}  // namespace

void keep_fusion_within_maps(SystemState& state) {
  struct Held {
    std::set<MapPointId> points;
    std::set<KeyFrameId> keyframes;
  };
  std::map<MapKey, Held> held;
  for (const ClientSlamState& c : state.clients)
    for (const MapState& m : c.maps) {
      Held& h = held[MapKey{c.info.id, m.index}];
      for (const auto& p : m.points) h.points.insert(p.id);
      for (const auto& k : m.keyframes) h.keyframes.insert(k.id);
    }
  FusionState& f = state.fusion;
  auto gone = [&](MapKey k) { return !held.count(k); };
  erase_where(f.seams, [&](const SeamState& s) { return gone(s.kept_map) || gone(s.moved_map); });
  for (SeamState& s : f.seams) {
    const Held &kept = held.at(s.kept_map), &moved = held.at(s.moved_map);
    erase_where(s.links, [&](const auto& l) { return !kept.points.count(l.first) || !moved.points.count(l.second); });
    erase_where(s.edges, [&](const SeamEdgeState& e) {
      return !kept.keyframes.count(e.kept) || !moved.keyframes.count(e.moved);
    });
  }
  erase_where(f.consistency, [&](const ConsistencyState& c) { return gone(c.query) || gone(c.other); });
  for (ConsistencyState& c : f.consistency) {
    const Held& other = held.at(c.other);
    for (auto& group : c.groups) erase_where(group.first, [&](KeyFrameId id) { return !other.keyframes.count(id); });
  }
  erase_where(f.last_links, [&](const MapLinkState& l) { return gone(l.query) || gone(l.other); });
  erase_where(f.keyframes_seen, [&](const auto& k) { return gone(k.first); });
}

}  // namespace cslam
