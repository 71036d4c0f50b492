// Every cost function's derivatives checked against numeric differentiation.
#include <gtest/gtest.h>

#include <ceres/ceres.h>

#include "support/problems/optimize_problems.h"
#include "optimize/pose_param.h"

using namespace cslam;

namespace {

template <typename Functor, int kRes, int... kBlocks>
void compare_jacobians(const Functor& f, std::vector<double*> params) {
  ceres::AutoDiffCostFunction<Functor, kRes, kBlocks...> autodiff(new Functor(f));
  ceres::NumericDiffOptions nopts;
  ceres::NumericDiffCostFunction<Functor, ceres::CENTRAL, kRes, kBlocks...> numeric(new Functor(f),
                                                                                    ceres::TAKE_OWNERSHIP, kRes, nopts);
  const std::vector<int> sizes = {kBlocks...};
  std::vector<std::vector<double>> ja(sizes.size()), jn(sizes.size());
  std::vector<double*> pa, pn;
  for (size_t b = 0; b < sizes.size(); ++b) {
    ja[b].assign(kRes * sizes[b], 0);
    jn[b].assign(kRes * sizes[b], 0);
    pa.push_back(ja[b].data());
    pn.push_back(jn[b].data());
  }
  double ra[kRes], rn[kRes];
  ASSERT_TRUE(autodiff.Evaluate(params.data(), ra, pa.data()));
  ASSERT_TRUE(numeric.Evaluate(params.data(), rn, pn.data()));
  for (int i = 0; i < kRes; ++i) EXPECT_NEAR(ra[i], rn[i], 1e-9);
  for (size_t b = 0; b < sizes.size(); ++b)
    for (size_t i = 0; i < ja[b].size(); ++i)
      EXPECT_NEAR(ja[b][i], jn[b][i], 1e-5 * std::max(1.0, std::abs(jn[b][i]))) << "block " << b << " entry " << i;
}

}  // namespace

TEST(CostFunctions, ReprojectionJacobiansMatchNumeric) {
  const auto k = problems::tum_like_intrinsics();
  const SE3 T = problems::small_motion(0.3, {0.2, 1, 0.1}, {0.1, -0.2, 0.3});
  auto pose = to_param(T);
  double point[3] = {0.4, -0.3, 2.5};
  const ReprojectionCost<3> stereo(k, 300.0, 200.0, 290.0, 1.0 / 1.2);
  compare_jacobians<ReprojectionCost<3>, 3, 6, 3>(stereo, {pose.data(), point});
  const ReprojectionCost<2> mono(k, 300.0, 200.0, -1, 1.0);
  compare_jacobians<ReprojectionCost<2>, 2, 6, 3>(mono, {pose.data(), point});
}

TEST(CostFunctions, PoseOnlyJacobiansMatchNumeric) {
  const auto k = problems::tum_like_intrinsics();
  auto pose = to_param(problems::small_motion(-0.5, {1, 0.3, 0}, {0.5, 0.1, -0.2}));
  const PoseOnlyReprojectionCost<3> stereo(k, Eigen::Vector3d(-0.2, 0.5, 3.0), 250.0, 220.0, 240.0, 1.0);
  compare_jacobians<PoseOnlyReprojectionCost<3>, 3, 6>(stereo, {pose.data()});
  const PoseOnlyReprojectionCost<2> mono(k, Eigen::Vector3d(-0.2, 0.5, 3.0), 250.0, 220.0, -1, 1.0);
  compare_jacobians<PoseOnlyReprojectionCost<2>, 2, 6>(mono, {pose.data()});
}

TEST(PoseParam, RoundTrip) {
  const SE3 T = problems::small_motion(2.5, {0.3, -0.4, 0.8}, {1, 2, 3});
  const auto p = to_param(T);
  const SE3 back = from_param(p.data());
  EXPECT_LT(back.rotation().angularDistance(T.rotation()), 1e-12);
  EXPECT_LT((back.translation() - T.translation()).norm(), 1e-12);
}
