// keep_fusion_within_maps (declared in system/system_state.h).
#include "system/system_state.h"

#include <algorithm>
#include <map>
#include <set>

namespace cslam {

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
  f.seams.erase(std::remove_if(f.seams.begin(), f.seams.end(),
                               [&](const SeamState& s) { return gone(s.kept_map) || gone(s.moved_map); }),
                f.seams.end());
  for (SeamState& s : f.seams) {
    const Held &kept = held.at(s.kept_map), &moved = held.at(s.moved_map);
    s.links.erase(
        std::remove_if(s.links.begin(), s.links.end(),
                       [&](const auto& l) { return !kept.points.count(l.first) || !moved.points.count(l.second); }),
        s.links.end());
    s.edges.erase(std::remove_if(s.edges.begin(), s.edges.end(),
                                 [&](const SeamEdgeState& e) {
                                   return !kept.keyframes.count(e.kept) || !moved.keyframes.count(e.moved);
                                 }),
                  s.edges.end());
  }
  f.consistency.erase(std::remove_if(f.consistency.begin(), f.consistency.end(),
                                     [&](const ConsistencyState& c) { return gone(c.query) || gone(c.other); }),
                      f.consistency.end());
  for (ConsistencyState& c : f.consistency) {
    const Held& other = held.at(c.other);
    for (auto& [members, count] : c.groups)
      members.erase(
          std::remove_if(members.begin(), members.end(), [&](KeyFrameId id) { return !other.keyframes.count(id); }),
          members.end());
  }
  f.last_links.erase(std::remove_if(f.last_links.begin(), f.last_links.end(),
                                    [&](const MapLinkState& l) { return gone(l.query) || gone(l.other); }),
                     f.last_links.end());
  f.keyframes_seen.erase(
      std::remove_if(f.keyframes_seen.begin(), f.keyframes_seen.end(), [&](const auto& k) { return gone(k.first); }),
      f.keyframes_seen.end());
}

}  // namespace cslam
