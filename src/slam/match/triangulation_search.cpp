#include "slam/match/triangulation_search.h"

#include <algorithm>

#include "slam/features/matching.h"

namespace cslam {

namespace {
Eigen::Matrix3d intrinsics(const PinholeCamera& c) {
  Eigen::Matrix3d K;
  K << c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1;
  return K;
}
}  // namespace

Eigen::Matrix3d fundamental_21(const SE3& T_cam1_world, const PinholeCamera& cam1, const SE3& T_cam2_world,
                               const PinholeCamera& cam2) {
  const SE3 T_21 = T_cam2_world * T_cam1_world.inverse();
  const Eigen::Matrix3d R = T_21.rotation().toRotationMatrix();
  const Eigen::Matrix3d E = skew(T_21.translation()) * R;
  return intrinsics(cam2).inverse().transpose() * E * intrinsics(cam1).inverse();
}

std::vector<std::pair<int, int>> search_for_triangulation(const KeyFrame& kf1, const KeyFrame& kf2,
                                                          const TriangulationSearchParams& params,
                                                          const std::vector<char>* skip1) {
  const FrameData& f1 = *kf1.data;
  const FrameData& f2 = *kf2.data;
  const Eigen::Matrix3d F21 = fundamental_21(kf1.T_cam_world, f1.camera, kf2.T_cam_world, f2.camera);
  // Epipole of camera 1 in image 2.
  const Eigen::Vector3d c1_in_2 = kf2.T_cam_world * kf1.center();
  const bool epipole_valid = c1_in_2.z() > 1e-9;
  const Eigen::Vector2d epipole = epipole_valid ? f2.camera.project(c1_in_2) : Eigen::Vector2d(0, 0);
  const auto& sigma2 = f2.pyramid->sigma2;
  const auto& scale = f2.pyramid->scale;

  std::vector<int> match_of_1(f1.size(), -1);
  std::vector<char> taken_2(f2.size(), 0);
  RotationHistogram hist;
  auto it1 = f1.feature_vector.begin();
  auto it2 = f2.feature_vector.begin();
  while (it1 != f1.feature_vector.end() && it2 != f2.feature_vector.end()) {
    if (it1->first < it2->first) {
      it1 = f1.feature_vector.lower_bound(it2->first);
      continue;
    }
    if (it2->first < it1->first) {
      it2 = f2.feature_vector.lower_bound(it1->first);
      continue;
    }
    for (int i1 : it1->second) {
      if (kf1.map_points[i1] || (skip1 && (*skip1)[i1])) continue;
      const bool depth1 = f1.u_right[i1] >= 0;
      const Eigen::Vector2d& p1 = f1.features.undistorted[i1];
      const Eigen::Vector3d line = F21 * Eigen::Vector3d(p1.x(), p1.y(), 1.0);
      const double line_norm2 = line.x() * line.x() + line.y() * line.y();
      if (line_norm2 <= 0) continue;
      const Descriptor& d1 = f1.features.descriptors[i1];
      int best = params.max_distance + 1, best_i2 = -1;
      for (int i2 : it2->second) {
        if (taken_2[i2] || kf2.map_points[i2]) continue;
        const int d = hamming_distance(d1, f2.features.descriptors[i2]);
        if (d >= best) continue;
        const Eigen::Vector2d& p2 = f2.features.undistorted[i2];
        const int level2 = f2.features.keypoints[i2].octave;
        const double near_epipole = params.epipole_radius * scale[level2];
        if (!depth1 && f2.u_right[i2] < 0 && epipole_valid &&
            (p2 - epipole).squaredNorm() < near_epipole * near_epipole)
          continue;
        const double num = line.x() * p2.x() + line.y() * p2.y() + line.z();
        if (num * num / line_norm2 >= params.epipolar_chi2 * sigma2[level2]) continue;
        best = d;
        best_i2 = i2;
      }
      if (best_i2 >= 0) {
        match_of_1[i1] = best_i2;
        taken_2[best_i2] = 1;
        if (params.check_orientation)
          hist.add(f1.features.keypoints[i1].angle, f2.features.keypoints[best_i2].angle, i1);
      }
    }
    ++it1;
    ++it2;
  }
  if (params.check_orientation)
    for (int i1 : hist.outliers()) match_of_1[i1] = -1;
  std::vector<std::pair<int, int>> out;
  for (std::size_t i = 0; i < match_of_1.size(); ++i)
    if (match_of_1[i] >= 0) out.emplace_back(int(i), match_of_1[i]);
  return out;
}

}  // namespace cslam
