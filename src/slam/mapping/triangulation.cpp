#include "slam/mapping/triangulation.h"

#include <cmath>

#include <Eigen/SVD>

#include "optimize/reprojection_chi2.h"
#include "slam/match/triangulation_search.h"

namespace cslam {

namespace {

Eigen::Matrix<double, 3, 4> projection_rows(const SE3& T_cam_world) {
  Eigen::Matrix<double, 3, 4> P;
  P.leftCols<3>() = T_cam_world.rotation().toRotationMatrix();
  P.col(3) = T_cam_world.translation();
  return P;
}

// Linear (DLT) triangulation from normalised image coordinates.
std::optional<Eigen::Vector3d> linear_triangulation(const Eigen::Vector2d& x1, const SE3& T1, const Eigen::Vector2d& x2,
                                                    const SE3& T2) {
  const auto P1 = projection_rows(T1);
  const auto P2 = projection_rows(T2);
  Eigen::Matrix4d A;
  A.row(0) = x1.x() * P1.row(2) - P1.row(0);
  A.row(1) = x1.y() * P1.row(2) - P1.row(1);
  A.row(2) = x2.x() * P2.row(2) - P2.row(0);
  A.row(3) = x2.y() * P2.row(2) - P2.row(1);
  Eigen::JacobiSVD<Eigen::Matrix4d> svd(A, Eigen::ComputeFullV);
  const Eigen::Vector4d X = svd.matrixV().col(3);
  if (std::abs(X.w()) < 1e-12) return std::nullopt;
  return Eigen::Vector3d(X.head<3>() / X.w());
}

// Reprojection check of a world point in one view, in units of the keypoint level's sigma^2.
bool reprojects(const FrameData& f, const SE3& T_cam_world, int i, const Eigen::Vector3d& p_world,
                const TriangulationConfig& c) {
  const StereoIntrinsics k{f.camera.fx, f.camera.fy, f.camera.cx, f.camera.cy, f.rgbd.bf};
  const double chi2 = reprojection_chi2(k, T_cam_world * p_world, f.features.undistorted[i], f.u_right[i],
                                        f.pyramid->inv_sigma2[f.features.keypoints[i].octave]);
  return chi2 <= (f.u_right[i] < 0 ? c.mono_chi2 : c.stereo_chi2);
}

}  // namespace

std::optional<Eigen::Vector3d> triangulate_pair(const FrameData& f1, const SE3& T1, int i1, const FrameData& f2,
                                                const SE3& T2, int i2, const TriangulationConfig& c) {
  const Eigen::Vector2d& u1 = f1.features.undistorted[i1];
  const Eigen::Vector2d& u2 = f2.features.undistorted[i2];
  const Eigen::Vector2d x1((u1.x() - f1.camera.cx) / f1.camera.fx, (u1.y() - f1.camera.cy) / f1.camera.fy);
  const Eigen::Vector2d x2((u2.x() - f2.camera.cx) / f2.camera.fx, (u2.y() - f2.camera.cy) / f2.camera.fy);
  // Parallax of the two rays, and of each view's own depth measurement (its virtual baseline).
  const Eigen::Vector3d ray1 = T1.rotation().conjugate() * Eigen::Vector3d(x1.x(), x1.y(), 1.0);
  const Eigen::Vector3d ray2 = T2.rotation().conjugate() * Eigen::Vector3d(x2.x(), x2.y(), 1.0);
  const double cos_rays = ray1.dot(ray2) / (ray1.norm() * ray2.norm());
  auto cos_depth = [](const FrameData& f, int i) {
    if (f.u_right[i] < 0 || f.depth[i] <= 0) return 2.0;  // no depth: never preferred
    const double baseline = f.rgbd.bf / f.camera.fx;
    return std::cos(2.0 * std::atan2(baseline / 2.0, double(f.depth[i])));
  };
  const double cos_depth1 = cos_depth(f1, i1), cos_depth2 = cos_depth(f2, i2);
  const double cos_depth_min = std::min(cos_depth1, cos_depth2);
  std::optional<Eigen::Vector3d> p;
  if (cos_rays > 0 && cos_rays < cos_depth_min && (cos_depth_min <= 1.0 || cos_rays < c.max_parallax_cos)) {
    p = linear_triangulation(x1, T1, x2, T2);
  } else if (cos_depth1 <= 1.0 && cos_depth1 <= cos_depth2) {
    p = T1.inverse() * f1.unproject(i1);
  } else if (cos_depth2 <= 1.0) {
    p = T2.inverse() * f2.unproject(i2);
  }
  if (!p || !p->allFinite()) return std::nullopt;
  if (!reprojects(f1, T1, i1, *p, c) || !reprojects(f2, T2, i2, *p, c)) return std::nullopt;
  // The distances from the two camera centres must agree with the two detection levels.
  const double dist1 = (*p - T1.inverse().translation()).norm();
  const double dist2 = (*p - T2.inverse().translation()).norm();
  if (dist1 <= 0 || dist2 <= 0) return std::nullopt;
  const double ratio_dist = dist2 / dist1;
  const double ratio_octave =
      f1.pyramid->scale[f1.features.keypoints[i1].octave] / f2.pyramid->scale[f2.features.keypoints[i2].octave];
  const double factor = c.scale_consistency * f1.pyramid->scale_factor;
  if (ratio_dist * factor < ratio_octave || ratio_dist > ratio_octave * factor) return std::nullopt;
  return p;
}

std::vector<MapPointPtr> create_new_map_points(Map& map, KeyFrame* kf, const TriangulationConfig& config) {
  std::vector<MapPointPtr> created;
  if (!config.enabled || kf->bad) return created;
  const FrameData& f1 = *kf->data;
  const double baseline = f1.rgbd.bf / f1.camera.fx;
  std::vector<char> used(f1.size(), 0);
  for (KeyFrame* other : kf->best_covisibles(std::size_t(config.neighbours))) {
    if (!other || other->bad || other == kf) continue;
    if ((other->center() - kf->center()).norm() < baseline) continue;  // too close for the depth's own baseline
    const FrameData& f2 = *other->data;
    for (const auto& [i1, i2] : search_for_triangulation(*kf, *other, {}, &used)) {
      const auto p = triangulate_pair(f1, kf->T_cam_world, i1, f2, other->T_cam_world, i2, config);
      if (!p) continue;
      auto mp = std::make_shared<MapPoint>(map.ids().next_map_point(), *p, kf, f1.colors[i1]);
      mp->first_keyframe_seq = kf->id.seq;
      Map::add_observation(kf, i1, mp);
      Map::add_observation(other, i2, mp);
      map.update_map_point(mp.get());
      map.add_map_point(mp);
      used[i1] = 1;
      created.push_back(std::move(mp));
    }
  }
  return created;
}

}  // namespace cslam
