#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "common/run_program.h"
#include "core/error.h"
#include "io/trajectory_io.h"

using namespace cslam;

TEST(TrajectoryIo, RoundTrip) {
  Trajectory t;
  for (int i = 0; i < 5; ++i) {
    Eigen::Quaterniond q(Eigen::AngleAxisd(0.1 * i, Eigen::Vector3d(0.2, 1, 0.3).normalized()));
    t.push_back({1305031102.175304 + i / 30.0, SE3(q, Eigen::Vector3d(i * 0.1, -0.5, 1.25))});
  }
  const test::TempDir dir("cslam_traj_rt");
  const std::string path = dir / "trajectory.txt";
  write_tum_trajectory(path, t, "test");
  const Trajectory r = read_tum_trajectory(path);
  ASSERT_EQ(r.size(), t.size());
  for (size_t i = 0; i < t.size(); ++i) {
    EXPECT_NEAR(r[i].timestamp, t[i].timestamp, 1e-6);
    EXPECT_LT((r[i].T_world_cam.translation() - t[i].T_world_cam.translation()).norm(), 1e-6);
    EXPECT_LT(r[i].T_world_cam.rotation().angularDistance(t[i].T_world_cam.rotation()), 1e-6);
  }
  std::filesystem::remove(path);
}

TEST(TrajectoryIo, BadInput) {
  const test::TempDir dir("cslam_traj_bad");
  const std::string path = dir / "trajectory.txt";
  std::ofstream(path) << "1.0 0 0 0 0 0 0 1\n2.0 nan 0 0 0 0 0 1\n";
  try {
    read_tum_trajectory(path);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(":2:"), std::string::npos) << e.what();
  }
  std::ofstream(path) << "1.0 0 0 0 0 0 0\n";
  EXPECT_THROW(read_tum_trajectory(path), InputError);
  std::ofstream(path) << "1.0 0 0 0 0 0 0 0\n";
  EXPECT_THROW(read_tum_trajectory(path), InputError);  // zero quaternion
  Trajectory nan_traj{{1.0, SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(NAN, 0, 0))}};
  EXPECT_THROW(write_tum_trajectory(path, nan_traj), std::invalid_argument);
  std::filesystem::remove(path);
}
