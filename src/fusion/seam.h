#pragma once
// The seam between two maps joined by a fusion. Each client's map stays its own object with one
// writer set (its local mapping and loop closing), so the fused group is held together by seams:
// the same physical points found in both maps around the match (linked, and moved onto one
// position), and the cross-map covisibility they imply (keyframe pairs with their shared-point
// count). The group's global BA estimates every linked pair as one point.
#include <vector>

#include "slam/map/map.h"

namespace cslam {

struct SeamConfig {
  int neighbours = 10;       // covisible keyframes taken on each side of the match
  double radius = 3.0;       // projection search radius (pixels at level 0)
  int min_edge_weight = 15;  // shared points for a cross-map covisibility edge
};

struct SeamLink {
  MapPointPtr kept, moved;  // kept: point of the group that did not move
};
struct SeamEdge {
  KeyFramePtr kept, moved;
  int weight = 0;
};
struct Seam {
  std::vector<SeamLink> points;
  std::vector<SeamEdge> edges;
};

// In two steps, so that the maps are held exclusively only while the links are written:
// match_seam [both maps locked at least shared; the moved map already transformed into the kept
// map's frame] projects each side's neighbourhood points into the other side's keyframes; a point
// whose match already carries a point of the other map is the same point; each point keeps its
// partner of most votes (both directions vote). link_seam [unique locks on both maps] links the
// pairs whose points are still good (the moved copy takes the kept copy's position); their
// observers on both sides count towards the cross-map edges.
std::vector<SeamLink> match_seam(KeyFrame& kept_kf, KeyFrame& moved_kf, const SeamConfig& config = {});
Seam link_seam(Map& kept_map, Map& moved_map, const std::vector<SeamLink>& pairs, const SeamConfig& config = {});

// Both steps at once [unique locks on both maps].
Seam connect_seam(Map& kept_map, KeyFrame& kept_kf, Map& moved_map, KeyFrame& moved_kf, const SeamConfig& config = {});

}  // namespace cslam
