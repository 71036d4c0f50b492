// Geometry: a rendered depth image back-projected with the ground-truth pose lands on the scene
// surface (scene.ply samples, point-to-plane with the sample normals; and the analytic faces).
#include <algorithm>
#include <cmath>
#include <unordered_map>

#include <gtest/gtest.h>

#include "support/synth/renderer.h"
#include "support/synth/surface_sampling.h"
#include "support/synth/synth_config.h"
#include "support/synth/trajectory_planner.h"
#include "synth_test_util.h"

using namespace cslam;
using namespace cslam::synth;

namespace {

// Nearest surface sample by a uniform grid, distance measured to the sample's tangent plane.
class CloudIndex {
 public:
  CloudIndex(const SurfacePoints& cloud, double cell) : cloud_(cloud), cell_(cell) {
    for (size_t i = 0; i < cloud.size(); ++i) grid_[key(cloud.points[i].cast<double>())].push_back(static_cast<int>(i));
  }
  // Point-to-plane distance to the nearest sample within one cell (infinity if none).
  double distance(const Eigen::Vector3d& p) const {
    const long cx = cell_index(p.x()), cy = cell_index(p.y()), cz = cell_index(p.z());
    double best = 1e9;
    int best_i = -1;
    for (long dx = -1; dx <= 1; ++dx)
      for (long dy = -1; dy <= 1; ++dy)
        for (long dz = -1; dz <= 1; ++dz) {
          auto it = grid_.find(pack(cx + dx, cy + dy, cz + dz));
          if (it == grid_.end()) continue;
          for (int i : it->second) {
            const double d = (cloud_.points[i].cast<double>() - p).squaredNorm();
            if (d < best) {
              best = d;
              best_i = i;
            }
          }
        }
    if (best_i < 0) return 1e9;
    return std::abs(cloud_.normals[best_i].cast<double>().dot(p - cloud_.points[best_i].cast<double>()));
  }

 private:
  long cell_index(double v) const { return static_cast<long>(std::floor(v / cell_)); }
  static long long pack(long x, long y, long z) { return ((x + 4096) << 26) | ((y + 4096) << 13) | (z + 4096); }
  long long key(const Eigen::Vector3d& p) const {
    return pack(cell_index(p.x()), cell_index(p.y()), cell_index(p.z()));
  }
  const SurfacePoints& cloud_;
  double cell_;
  std::unordered_map<long long, std::vector<int>> grid_;
};

std::vector<Eigen::Vector3d> back_project(const cv::Mat& depth, const PinholeCamera& cam, const SE3& T_world_cam,
                                          int step) {
  std::vector<Eigen::Vector3d> out;
  for (int v = 0; v < depth.rows; v += step)
    for (int u = 0; u < depth.cols; u += step) {
      const double z = cam.depth_from_raw(depth.at<std::uint16_t>(v, u));
      if (z > 0) out.push_back(T_world_cam * cam.unproject(u, v, z));
    }
  return out;
}

double median(std::vector<double> v) {
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

}  // namespace

TEST(SynthGeometry, DepthOfAWallFacingCameraIsExact) {
  SceneConfig sc;
  sc.furniture = 0;
  const Scene scene = make_scene(sc);
  const PinholeCamera cam = synthetic_camera(64, 48);
  const Renderer renderer(scene, cam);
  // Camera at x = 2 looking along -x at the wall x = 0: depth 2 m everywhere on the wall.
  const SE3 T_world_cam = camera_pose(Eigen::Vector3d(2.0, 3.0, 1.5), 3.14159265358979, 0.0);
  const RenderedFrame f = renderer.render(T_world_cam);
  int exact = 0;
  for (int v = 0; v < f.depth.rows; ++v)
    for (int u = 0; u < f.depth.cols; ++u) exact += f.depth.at<std::uint16_t>(v, u) == 10000;
  EXPECT_EQ(exact, 64 * 48);
  // Pixels are filled with texture (not the black of "nothing hit").
  EXPECT_GT(cv::mean(f.bgr)[0] + cv::mean(f.bgr)[1] + cv::mean(f.bgr)[2], 30.0);
}

TEST(SynthGeometry, BackProjectedDepthLandsOnSceneSurface) {
  SynthConfig c = synth_preset("test-small");
  const Scene scene = make_scene(c.scene);
  const TrajectoryPlan plan = plan_trajectories(scene, c.trajectory);
  const SurfacePoints cloud = sample_surface_points(scene, 0.01);
  // Round trip through the PLY file, as consumers read it.
  test::TempDir tmp;
  write_ply(tmp / "scene.ply", cloud);
  const SurfacePoints loaded = read_ply(tmp / "scene.ply");
  ASSERT_EQ(loaded.size(), cloud.size());
  const CloudIndex index(loaded, 0.02);
  const Renderer renderer(scene, c.camera);
  std::vector<double> to_ply, to_faces, shifted;
  for (const auto& robot : plan.robots)
    for (size_t i = 0; i < robot.trajectory.size(); i += 10) {
      const SE3& T = robot.trajectory[i].T_world_cam;
      const RenderedFrame f = renderer.render(T);
      for (const auto& p : back_project(f.depth, c.camera, T, 4)) {
        to_ply.push_back(index.distance(p));
        to_faces.push_back(scene.distance_to_surface(p));
      }
      // The same depth with a pose 3 cm off must not pass: the test can fail.
      const SE3 T_off(T.rotation(), T.translation() + Eigen::Vector3d(0.03, 0.0, 0.0));
      for (const auto& p : back_project(f.depth, c.camera, T_off, 8)) shifted.push_back(scene.distance_to_surface(p));
    }
  ASSERT_GT(to_ply.size(), 10000u);
  const double med_ply = median(to_ply), med_faces = median(to_faces);
  std::printf(
      "median point-to-surface: %.3f mm (scene.ply, point-to-plane), %.3f mm (analytic faces), %.1f mm with a 3 cm "
      "pose error\n",
      med_ply * 1e3, med_faces * 1e3, median(shifted) * 1e3);
  EXPECT_LT(med_ply, 0.002);
  EXPECT_LT(med_faces, 0.002);
  EXPECT_GT(median(shifted), 0.005);
}

TEST(SynthGeometry, SurfaceSamplesAreUniformAndOnFaces) {
  SceneConfig sc;
  sc.furniture = 4;
  const Scene scene = make_scene(sc);
  const SurfacePoints cloud = sample_surface_points(scene, 0.01);
  // Room area alone (floor, ceiling, walls) at 1 cm spacing, minus the floor under furniture.
  const double room_area = 2 * sc.width * sc.depth + 2 * (sc.width + sc.depth) * sc.height;
  EXPECT_GT(cloud.size(), 0.9 * room_area / 1e-4);
  EXPECT_LT(cloud.size(), 1.3 * room_area / 1e-4);
  for (size_t i = 0; i < cloud.size(); i += 997) {
    EXPECT_LT(scene.distance_to_surface(cloud.points[i].cast<double>()), 1e-5);
    EXPECT_NEAR(cloud.normals[i].norm(), 1.0f, 1e-5f);
  }
}
