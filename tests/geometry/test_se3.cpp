#include <gtest/gtest.h>

#include "geometry/se3.h"

using namespace cslam;

namespace {
SE3 random_pose(int seed) {
  srand(seed);
  Eigen::Quaterniond q(Eigen::Vector4d::Random());
  return SE3(q.normalized(), Eigen::Vector3d::Random());
}
}  // namespace

TEST(SE3, ComposeInverseAct) {
  const SE3 a = random_pose(1), b = random_pose(2);
  const Eigen::Vector3d p(0.3, -1.2, 2.0);
  EXPECT_LT(((a * b) * p - a * (b * p)).norm(), 1e-12);
  EXPECT_LT(((a.inverse() * a) * p - p).norm(), 1e-12);
  EXPECT_LT((a.matrix() * b.matrix() - (a * b).matrix()).norm(), 1e-12);
}

TEST(Sim3, ComposeInverseAct) {
  const Sim3 s(Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitZ())), Eigen::Vector3d(1, 2, 3), 1.7);
  const Sim3 t(Eigen::Quaterniond(Eigen::AngleAxisd(-0.9, Eigen::Vector3d::UnitX())), Eigen::Vector3d(-1, 0, 2), 0.6);
  const Eigen::Vector3d p(0.5, 0.1, -0.7);
  EXPECT_LT(((s * t) * p - s * (t * p)).norm(), 1e-12);
  EXPECT_LT((s.inverse() * (s * p) - p).norm(), 1e-12);
  EXPECT_NEAR((s * t).scale(), 1.7 * 0.6, 1e-12);
  EXPECT_LT((s.matrix() * t.matrix() - (s * t).matrix()).norm(), 1e-12);
}

TEST(SE3, RotationAngle) {
  const SE3 a(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 1, 0).normalized())),
              Eigen::Vector3d::Zero());
  EXPECT_NEAR(a.rotation_angle(), 0.3, 1e-12);
}
