#pragma once
// KeyFrame and MapPoint. Their immutable parts (ids, FrameData) can be read freely; every
// mutable member is guarded by the owning Map's mutex (shared for reads, unique for writes).
// Graph links between keyframes are raw pointers that the Map removes before a keyframe is
// erased; ownership lives in the Map's tables (and in trajectory records, for culled keyframes).
#include <cstdint>
#include <map>
#include <memory>
#include <set>
#include <vector>

#include <boost/container/flat_map.hpp>

#include "core/ids.h"
#include "geometry/se3.h"
#include "slam/map/frame_data.h"

namespace cslam {

class KeyFrame;

class MapPoint {
 public:
  MapPoint(MapPointId id, const Eigen::Vector3d& position, KeyFrame* reference, cv::Vec3b color)
      : id(id), position(position), reference(reference), color(color) {}

  const MapPointId id;
  Eigen::Vector3d position;
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  Descriptor descriptor{};
  double min_distance = 0, max_distance = 0;
  // keyframe -> keypoint index, sorted by keyframe id (the order std::map had). A flat sorted
  // vector: a point has a handful of observations, and every hot loop (local map, BA set-up,
  // descriptor, snapshot copy) walks them; a tree spread them over the heap.
  boost::container::flat_map<KeyFrame*, int, ById> observations;
  int num_obs = 0;  // stereo/RGB-D observations count twice (ORB-SLAM2)
  // Bumped on every change of `observations` (Map::add/erase_observation, bad, replaced): the
  // distinctive descriptor depends on that set alone, so Map::update_map_point recomputes it only
  // when the set changed since `descriptor_version`.
  std::uint32_t observations_version = 0;
  std::uint32_t descriptor_version = ~std::uint32_t(0);
  KeyFrame* reference = nullptr;
  int visible = 1, found = 1;
  bool bad = false;
  std::shared_ptr<MapPoint> replaced;  // set when fused into another point
  cv::Vec3b color;
  std::uint32_t first_keyframe_seq = 0;
  // The pyramid scale of the reference observation's keypoint, kept for that observation
  // (keyframe id, keypoint): Map::update_map_point needs it on every update, and reading the
  // keypoint is a cache miss.
  KeyFrameId scale_keyframe;
  int scale_keypoint = -1;
  double reference_scale = 1;

  double found_ratio() const { return double(found) / double(visible); }
  bool in_keyframe(KeyFrame* kf) const { return observations.count(kf) > 0; }
  // Level at which a keypoint of this point would be detected from `distance`.
  int predict_level(double distance, const ScalePyramid& pyramid) const {
    return pyramid.predict_level(distance, max_distance);
  }
  double min_valid_distance() const { return 0.8 * min_distance; }
  double max_valid_distance() const { return 1.2 * max_distance; }
};
using MapPointPtr = std::shared_ptr<MapPoint>;

// A keyframe's map point per keypoint (null if none). Read like a vector; every change goes
// through set / reset, which bump version(): a reader that listed the slots (Tracker's local map)
// knows they still hold the same points while the version is the same.
class MapPointSlots {
 public:
  explicit MapPointSlots(std::size_t n) : slots_(n) {}
  const MapPointPtr& operator[](std::size_t i) const { return slots_[i]; }
  std::size_t size() const { return slots_.size(); }
  std::vector<MapPointPtr>::const_iterator begin() const { return slots_.begin(); }
  std::vector<MapPointPtr>::const_iterator end() const { return slots_.end(); }
  void set(std::size_t i, MapPointPtr mp) {
    slots_[i] = std::move(mp);
    ++version_;
  }
  void reset(std::size_t i) {
    slots_[i].reset();
    ++version_;
  }
  std::uint64_t version() const { return version_; }

 private:
  std::vector<MapPointPtr> slots_;
  std::uint64_t version_ = 0;
};

class KeyFrame {
 public:
  KeyFrame(KeyFrameId id, std::shared_ptr<const FrameData> data, const SE3& T_cam_world)
      : id(id), data(std::move(data)), T_cam_world(T_cam_world), map_points(this->data->size()) {}

  const KeyFrameId id;
  const std::shared_ptr<const FrameData> data;

  SE3 T_cam_world;
  MapPointSlots map_points;  // per keypoint, null if none

  // Covisibility: weight = number of shared map points.
  std::map<KeyFrame*, int, ById> connections;
  std::vector<std::pair<int, KeyFrame*>> ordered_connections;  // weight descending
  // Spanning tree and loop edges.
  std::shared_ptr<KeyFrame> parent;
  std::set<KeyFrame*, ById> children;
  std::set<KeyFrame*, ById> loop_edges;
  bool first_connection = true;
  // The keyframe tracking created this one against, and the pose relative to it; kept until local
  // mapping connects it (parent set), so corrections made meanwhile can carry it along.
  std::shared_ptr<KeyFrame> creation_reference;
  SE3 T_cam_creation_ref;

  bool bad = false;
  int no_erase = 0;  // > 0 while loop closing / fusion use it (culling is deferred)
  bool erase_requested = false;
  SE3 T_cam_parent;  // valid once bad: pose relative to its parent

  SE3 T_world_cam() const { return T_cam_world.inverse(); }
  // The keyframe whose correction this one follows: its spanning-tree parent, or, before local
  // mapping has connected it, the keyframe it was tracked against.
  KeyFrame* anchor() const { return parent ? parent.get() : creation_reference.get(); }
  bool awaiting_connection() const { return !parent && creation_reference; }
  // T_world_cam().translation() without building the inverse (and normalising its rotation).
  Eigen::Vector3d center() const { return -(T_cam_world.rotation().conjugate() * T_cam_world.translation()); }
  double timestamp() const { return data->timestamp; }

  std::vector<KeyFrame*> best_covisibles(std::size_t n) const;
  std::vector<KeyFrame*> covisibles() const;
  std::vector<KeyFrame*> covisibles_with_weight(int min_weight) const;
  int weight(KeyFrame* other) const;
  // Map points with at least min_obs observations (RGB-D observations count twice).
  int tracked_map_points(int min_obs) const;
  std::set<MapPoint*> map_point_set() const;
  int index_of(const MapPoint* mp) const;
  // Median depth of its map points in this camera.
  double scene_median_depth() const;
  // Keypoints near (u, v) within r, for projection searches.
  std::vector<int> features_in_area(double u, double v, double r, int min_level = -1, int max_level = -1) const {
    return data->grid.features_in_area(u, v, r, min_level, max_level);
  }
};
using KeyFramePtr = std::shared_ptr<KeyFrame>;

}  // namespace cslam
