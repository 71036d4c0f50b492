// Real data: clouds of tum_fr1_rpy built from ground-truth poses of the even and of the odd
// frames of the same two seconds must agree (a wrong pose convention, undistortion or
// association would pull them apart while the camera turns).
#include <gtest/gtest.h>

#include "cloud/cloud_metrics.h"
#include "common/test_data.h"
#include "dense/trajectory_recon.h"
#include "io/tum_dataset.h"

using namespace cslam;

TEST(TumRecon, OverlappingRangesAgreeUnderGroundTruthPoses) {
  CSLAM_REQUIRE_TUM_RPY();
  const std::string dir = cslam::test::tum_rpy_dir();
  const Trajectory gt = read_tum_trajectory(dir + "/groundtruth.txt");
  const TumDataset ds = open_tum_dataset(dir);
  ASSERT_GT(ds.pairs.size(), 100u);
  // Ground-truth poses nearest to the even (or odd) RGB-D pairs of the first two seconds.
  auto poses_of = [&](int parity) {
    Trajectory out;
    for (size_t i = size_t(parity); i < ds.pairs.size() && ds.pairs[i].rgb_time < ds.pairs[0].rgb_time + 2.0; i += 2)
      for (const auto& p : gt)
        if (std::abs(p.timestamp - ds.pairs[i].rgb_time) < 0.006) out.push_back(p);
    return out;
  };
  DenseConfig cfg;
  cfg.stride = 4;
  cfg.max_depth = 3.0;
  const DenseResult a = reconstruct_from_trajectories({{dir, poses_of(0), camera_tum_fr1()}}, cfg);
  const DenseResult b = reconstruct_from_trajectories({{dir, poses_of(1), camera_tum_fr1()}}, cfg);
  EXPECT_GE(a.counts.used, 25);
  EXPECT_GE(b.counts.used, 25);
  EXPECT_GT(a.counts.no_image, 0);  // poses within 6 ms of a frame: some lose it to a closer one
  ASSERT_GT(a.cloud.size(), 20000u);
  const CloudComparison c = compare_clouds(a.cloud.points, b.cloud.points);
  EXPECT_LT(c.test_to_ref.median, 0.01) << "clouds of overlapping ranges disagree";
  EXPECT_LT(c.test_to_ref.p95, 0.03);
  EXPECT_GT(c.completeness[0].second, 0.9);  // share within 2 cm
}
