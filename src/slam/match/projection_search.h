#pragma once
// Matching of map points to keypoints, guided by poses (projection) or by the vocabulary (BoW).
// All functions read map data: the caller holds the map mutex (shared), except fuse() and
// apply_fuse(), which write (unique).
#include <vector>

#include "slam/map/map.h"
#include "slam/map/frame.h"

namespace cslam {

// Visibility test of a map point from a camera pose (ORB-SLAM2's frustum check).
struct ProjectedPoint {
  bool visible = false;
  Eigen::Vector2d uv;
  double u_right = -1;
  double view_cos = 0;
  int predicted_level = 0;
};
ProjectedPoint project_map_point(const MapPoint& mp, const SE3& T_cam_world, const FrameData& frame,
                                 double min_view_cos = 0.5);

// Matches the previous frame's points into the current frame projected with its predicted pose
// (motion model). Returns the number of new matches.
int search_by_projection(Frame& current, const Frame& last, double radius, bool check_orientation);

// Matches local map points (not yet matched in `current`) by projection. Increments `visible`
// of every point in the frustum. Returns the number of new matches. `points` are the local
// keyframes' slots holding them: the caller holds the map's shared lock, so no slot changes, and
// a point's reference count is touched only when it is matched.
int search_local_points(Frame& current, const std::vector<const MapPointPtr*>& points, double radius);

// Matches a keyframe's map points to a frame's keypoints under the same vocabulary nodes.
// Result: per frame keypoint, the matched point (null if none). Returns the number of matches.
int search_by_bow(const KeyFrame& kf, const FrameData& frame, std::vector<MapPointPtr>& matches, double nn_ratio,
                  bool check_orientation = true);

// Projects keyframe `source`'s points into frame `current` at `T_cam_world` to add matches
// (relocalisation). `already` holds points already matched. Returns the number of new matches.
int search_by_projection_keyframe(Frame& current, const KeyFrame& source, const std::set<MapPoint*>& already,
                                  double radius, int max_distance);

// Keypoint of `kf` that map point `mp` projects onto and matches (frustum, scale, reprojection and
// descriptor checks; radius th x scale), or -1. Reads only: shared lock.
int match_point_in_keyframe(const MapPoint& mp, const KeyFrame& kf, double th = 3.0);

// Projects points into a keyframe and fuses duplicates: a point whose best keypoint already has
// a point is merged with it (the one with more observations survives), otherwise an observation
// is added. Requires the unique map lock. Returns the number of fused/added points.
int fuse(Map& map, KeyFrame* kf, const std::vector<MapPointPtr>& points, double radius = 3.0);

// fuse() in two steps, so that the matching, its costly part, runs under the shared lock and only
// the writes under the unique one. match_for_fuse [shared]: for each point, in order, that is not
// bad and not yet in kf, the keypoint it matches. apply_fuse [unique]: fuses or adds each match in
// order, skipping a point that is bad or in kf by then. fuse() is apply_fuse(match_for_fuse(..)):
// no match depends on an earlier one's write (a match reads the point and kf's pose and features,
// never kf's slots, and a point an earlier write touches is bad or in kf by then).
struct FuseMatch {
  MapPointPtr point;
  int index = -1;  // keypoint of the keyframe
};
std::vector<FuseMatch> match_for_fuse(KeyFrame* kf, const std::vector<MapPointPtr>& points, double radius = 3.0);
int apply_fuse(Map& map, KeyFrame* kf, const std::vector<FuseMatch>& matches);

}  // namespace cslam
