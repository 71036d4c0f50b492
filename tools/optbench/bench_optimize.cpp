// cslam-bench-optimize: time per call of the optimisers against their Ceres references on
// synthetic problems of the sizes the SLAM pipeline gives them (tests/optimize/fixtures.h):
//  1. pose-only optimisation (tracking, 3-4 calls per frame): N observations, outliers, depth
//     on most keypoints; optimize_pose vs optimize_pose_ceres;
//  2. bundle adjustment (local BA per keyframe, global BA): F free and K fixed keyframes,
//     P points; bundle_adjust vs bundle_adjust_ceres.
// Every problem is solved --runs times by both; median, min and max of wall-clock and process
// CPU ms are printed, with the largest difference between the two solutions (poses, points'
// reprojections) so a speed-up never hides a different answer.
#include <sys/resource.h>

#include <cstdio>
#include <random>
#include <sstream>

#include "core/cli.h"
#include "core/error.h"
#include "core/stopwatch.h"
#include "core/stats.h"
#include "optimize/ceres_reference.h"
#include "support/problems/optimize_problems.h"
#include "optimize/schur_ba.h"
#include "optimize/sparse_ba.h"

using namespace cslam;

namespace {

void print(const std::string& what, const RepeatTiming& t) {
  const Summary w = summarize(t.wall), c = summarize(t.cpu);
  std::printf("  %-34s wall median %8.3f [%8.3f, %8.3f]  cpu median %8.3f [%8.3f, %8.3f] ms (n=%d)\n", what.c_str(),
              w.median, w.min, w.max, c.median, c.min, c.max, w.n);
}

void bench_pose(int n, int runs, double outliers, double stereo, bool with_reference) {
  const auto k = problems::tum_like_intrinsics();
  std::mt19937 rng(1000 + n);
  // Several different problems, cycled, so the figures are not those of one lucky instance.
  std::vector<problems::PoseProblem> problems;
  for (int i = 0; i < 8; ++i) problems.push_back(problems::random_pose_problem(rng, n, outliers, stereo));
  RepeatTiming fast, ref;
  double worst = 0;
  int inlier_diff = 0;
  for (int r = 0; r < runs; ++r) {
    const auto& p = problems[r % problems.size()];
    PoseOptimizationResult a, b;
    fast.measure([&] { a = optimize_pose(p.start, p.obs, k); });
    if (!with_reference) continue;
    ref.measure([&] { b = optimize_pose_ceres(p.start, p.obs, k); });
    worst = std::max({worst, (a.T_cam_world.translation() - b.T_cam_world.translation()).norm(),
                      a.T_cam_world.rotation().angularDistance(b.T_cam_world.rotation())});
    for (size_t i = 0; i < a.inlier.size(); ++i) inlier_diff += a.inlier[i] != b.inlier[i];
  }
  std::printf("pose-only, %d observations, %.0f%% outliers, %.0f%% with depth:\n", n, 100 * outliers, 100 * stereo);
  print("optimize_pose (fixed-size LM)", fast);
  if (!with_reference) return;
  print("optimize_pose_ceres (reference)", ref);
  std::printf("    speed-up (median cpu) %.1fx; largest pose difference %.2g; inlier flags differing %d\n",
              summarize(ref.cpu).median / std::max(1e-9, summarize(fast.cpu).median), worst, inlier_diff);
}

struct BaSolver {
  const char* name;
  BaResult (*solve)(const BaProblem&);
};

const BaSolver kBaSolvers[] = {
    {"bundle_adjust", [](const BaProblem& p) { return bundle_adjust(p); }},
    {"sparse",
     [](const BaProblem& p) { return bundle_adjust_sparse(p, {}, nullptr, SparseBaLinearSolver::kSparseSchur); }},
    {"sparse-dense-schur",
     [](const BaProblem& p) { return bundle_adjust_sparse(p, {}, nullptr, SparseBaLinearSolver::kDenseSchur); }},
    {"sparse-iterative-schur",
     [](const BaProblem& p) { return bundle_adjust_sparse(p, {}, nullptr, SparseBaLinearSolver::kIterativeSchur); }},
    {"reference", [](const BaProblem& p) { return bundle_adjust_ceres(p); }},
};

void bench_ba(int free_cams, int fixed_cams, int points, double visibility, int runs,
              const std::vector<std::string>& solvers) {
  std::mt19937 rng(7 + free_cams);
  const problems::BaSynthetic s =
      problems::random_ba_problem(rng, free_cams, fixed_cams, points, 0.05, 0.85, visibility);
  const BaProblem& p = s.problem;
  std::printf("bundle adjustment, %d free + %d fixed keyframes, %zu points, %zu observations (%.1f per point):\n",
              free_cams, fixed_cams, p.points.size(), p.observations.size(),
              double(p.observations.size()) / p.points.size());
  std::vector<std::pair<std::string, RepeatTiming>> timings;
  std::vector<BaResult> results;
  for (const std::string& name : solvers) {
    const BaSolver* solver = nullptr;
    for (const auto& b : kBaSolvers)
      if (name == b.name) solver = &b;
    if (!solver) throw ConfigError("--ba-solvers: unknown solver '" + name + "'");
    RepeatTiming t;
    BaResult r;
    for (int i = 0; i < runs; ++i) t.measure([&] { r = solver->solve(p); });
    std::string label = name;
    if (name == "bundle_adjust")
      label += free_cams > kMaxDenseSchurCameras ? " (block-sparse Schur LM)" : " (Schur LM)";
    print(label, t);
    timings.emplace_back(name, t);
    results.push_back(std::move(r));
  }
  if (results.size() < 2) return;
  // Every solver's answer against the first one's.
  const BaResult& a = results.front();
  for (size_t k = 1; k < results.size(); ++k) {
    const BaResult& b = results[k];
    double worst_pose = 0;
    for (size_t c = 0; c < p.cameras.size(); ++c)
      worst_pose = std::max({worst_pose, (a.T_cam_world[c].translation() - b.T_cam_world[c].translation()).norm(),
                             a.T_cam_world[c].rotation().angularDistance(b.T_cam_world[c].rotation())});
    int inlier_diff = 0;
    for (size_t i = 0; i < a.inlier.size(); ++i) inlier_diff += a.inlier[i] != b.inlier[i];
    std::printf(
        "    %s / %s: cpu %.1fx; iterations %d vs %d; cost %.6g vs %.6g; largest pose difference %.2g; inlier flags "
        "differing %d\n",
        timings[k].first.c_str(), timings[0].first.c_str(),
        summarize(timings[k].second.cpu).median / std::max(1e-9, summarize(timings[0].second.cpu).median), b.iterations,
        a.iterations, b.final_cost, a.final_cost, worst_pose, inlier_diff);
  }
}

std::vector<std::string> split_names(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) out.push_back(item);
  return out;
}

int run(int argc, char** argv) {
  CliArgs args("cslam-bench-optimize",
               "Time per call of the pose-only and bundle-adjustment solvers against their Ceres references.");
  args.option("runs", "repetitions of each measurement", "30")
      .option("pose-sizes", "observation counts of the pose-only problems (comma-separated)", "100,300,600")
      .option("outliers", "fraction of gross outliers in the pose-only problems", "0.15")
      .option("stereo", "fraction of observations with depth", "0.85")
      .option("ba", "bundle-adjustment problems as FREExFIXEDxPOINTS, comma-separated",
              "10x5x1000,20x10x3000,40x10x6000")
      .option("visibility", "probability that a keyframe which could see a point observes it", "0.35")
      .option("ba-solvers",
              "bundle adjusters to time: bundle_adjust, sparse, sparse-dense-schur, sparse-iterative-schur, reference",
              "bundle_adjust,reference")
      .flag("no-reference", "time only the fast pose solver (the BA solvers are chosen by --ba-solvers)");
  if (!args.parse(argc, argv)) return 0;
  const int runs = args.get_int("runs");
  const double outliers = args.get_double("outliers"), stereo = args.get_double("stereo"),
               visibility = args.get_double("visibility");
  if (runs < 1 || outliers < 0 || outliers >= 1 || stereo < 0 || stereo > 1 || visibility <= 0 || visibility > 1)
    throw ConfigError("need --runs >= 1, 0 <= --outliers < 1, 0 <= --stereo <= 1, 0 < --visibility <= 1");
  const bool reference = !args.flag_set("no-reference");
  for (const std::string& size : split_names(args.get("pose-sizes"))) {
    const int n = std::stoi(size);
    if (n < 3) throw ConfigError("--pose-sizes: each size must be >= 3");
    bench_pose(n, runs, outliers, stereo, reference);
  }
  std::stringstream ss(args.get("ba"));
  std::string item;
  while (std::getline(ss, item, ',')) {
    int f = 0, k = 0, p = 0;
    char x1 = 0, x2 = 0;
    std::stringstream is(item);
    if (!(is >> f >> x1 >> k >> x2 >> p) || x1 != 'x' || x2 != 'x' || f < 1 || k < 0 || p < 1)
      throw ConfigError("--ba: expected FREExFIXEDxPOINTS, got '" + item + "'");
    bench_ba(f, k, p, visibility, std::max(3, runs / 5), split_names(args.get("ba-solvers")));
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return run_main("cslam-bench-optimize", argc, argv, run); }
