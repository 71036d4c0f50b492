#pragma once
// The essential graph of a map for loop correction: every keyframe is a node; edges are the
// spanning tree, loop edges, strong covisibility edges (weight >= threshold) and the new loop
// connections. Edges are measured from the poses before correction (`measured_T_cam_world`),
// except the new loop connections, which are measured from the corrected poses.
// The caller holds the map mutex.
#include <map>
#include <set>
#include <vector>

#include "slam/loop/pose_graph.h"
#include "slam/map/map.h"

namespace cslam {

struct EssentialGraph {
  std::vector<KeyFrame*> keyframes;  // node i
  std::map<KeyFrame*, int, ById> index;
  std::vector<PoseGraphNode> nodes;
  std::vector<PoseGraphEdge> edges;
  int spanning_edges = 0, loop_edges = 0, covisibility_edges = 0, new_loop_edges = 0;
};

struct EssentialGraphInput {
  // Poses the nodes start from (corrected ones for the loop neighbourhood), by keyframe.
  std::map<KeyFrame*, SE3, ById> initial_T_cam_world;
  // Poses the edges are measured from (before correction), by keyframe; others use T_cam_world.
  std::map<KeyFrame*, SE3, ById> measured_T_cam_world;
  // New links created by the loop (keyframe -> keyframes it is now connected to across the loop).
  std::map<KeyFrame*, std::set<KeyFrame*, ById>, ById> new_connections;
  std::set<KeyFrame*, ById> fixed;
  int min_covisibility_weight = 100;
};

EssentialGraph build_essential_graph(const Map& map, const EssentialGraphInput& input);

}  // namespace cslam
