#include "slam/map/keyframe.h"

#include <algorithm>

namespace cslam {

std::vector<KeyFrame*> KeyFrame::best_covisibles(std::size_t n) const {
  std::vector<KeyFrame*> out;
  for (size_t i = 0; i < ordered_connections.size() && i < n; ++i) out.push_back(ordered_connections[i].second);
  return out;
}

std::vector<KeyFrame*> KeyFrame::covisibles() const { return best_covisibles(ordered_connections.size()); }

std::vector<KeyFrame*> KeyFrame::covisibles_with_weight(int min_weight) const {
  std::vector<KeyFrame*> out;
  for (const auto& [w, kf] : ordered_connections) {
    if (w < min_weight) break;
    out.push_back(kf);
  }
  return out;
}

int KeyFrame::weight(KeyFrame* other) const {
  auto it = connections.find(other);
  return it == connections.end() ? 0 : it->second;
}

int KeyFrame::tracked_map_points(int min_obs) const {
  int n = 0;
  for (const auto& mp : map_points)
    if (mp && !mp->bad && (min_obs <= 0 || mp->num_obs >= min_obs)) ++n;
  return n;
}

std::set<MapPoint*> KeyFrame::map_point_set() const {
  std::set<MapPoint*> out;
  for (const auto& mp : map_points)
    if (mp && !mp->bad) out.insert(mp.get());
  return out;
}

int KeyFrame::index_of(const MapPoint* mp) const {
  auto it = mp->observations.find(const_cast<KeyFrame*>(this));
  return it == mp->observations.end() ? -1 : it->second;
}

double KeyFrame::scene_median_depth() const {
  std::vector<double> depths;
  const Eigen::Matrix3d R = T_cam_world.R();
  const Eigen::Vector3d t = T_cam_world.translation();
  for (const auto& mp : map_points)
    if (mp && !mp->bad) depths.push_back((R * mp->position + t).z());
  if (depths.empty()) return 0;
  std::nth_element(depths.begin(), depths.begin() + depths.size() / 2, depths.end());
  return depths[depths.size() / 2];
}

}  // namespace cslam
