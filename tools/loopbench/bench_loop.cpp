// cslam-bench-loop: speed (and accuracy) of the loop-closing maths on synthetic data.
//  1. essential-graph optimisation: N keyframes on a drifted circle, chain edges, covisibility
//     edges to the next K keyframes (measured on the drifted poses, as the map holds them) and
//     one loop edge with the true relative pose; SE3 and Sim3 (with scale drift) graphs;
//  2. sim3_ransac on M matches with a fraction of wrong matches (fix_scale and 7 DoF);
//  3. refine_sim3 on the same matches starting from the RANSAC result, and its Ceres reference
//     refine_sim3_ceres beside it (time and the largest difference between the two).
// Each is repeated --runs times; median, min and max of wall-clock ms and of process CPU ms are
// printed (CPU time is the better figure when other jobs share the machine; threads = 1).
#include <sys/resource.h>

#include <cmath>
#include <cstdio>
#include <iostream>
#include <random>

#include "core/cli.h"
#include "core/error.h"
#include "core/stopwatch.h"
#include "core/stats.h"
#include "slam/loop/pose_graph.h"
#include "slam/loop/sim3_ransac.h"
#include "slam/loop/sim3_refine.h"

using namespace cslam;

namespace {

Sim3 rot(double angle, const Eigen::Vector3d& axis, const Eigen::Vector3d& t, double s = 1.0) {
  return Sim3(Eigen::Quaterniond(Eigen::AngleAxisd(angle, axis.normalized())), t, s);
}

struct Graph {
  std::vector<Sim3> truth;
  std::vector<PoseGraphNode> nodes;
  std::vector<PoseGraphEdge> edges;
};

// Circle of radius 10 m; odometry with 0.5 mrad/step yaw bias, noise, and (sim3) 0.2%/step scale drift.
Graph make_graph(int n, int covis, bool sim3, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> N(0.0, 1.0);
  Graph g;
  for (int i = 0; i < n; ++i) {
    const double a = 2.0 * M_PI * i / n;
    g.truth.push_back(rot(a + M_PI / 2, Eigen::Vector3d::UnitZ(),
                          Eigen::Vector3d(10 * std::cos(a), 10 * std::sin(a), 0.5 * std::sin(3 * a))));
  }
  const double drift = sim3 ? 1.002 : 1.0;
  double units = 1.0;
  g.nodes.push_back({g.truth[0], true});
  for (int i = 0; i + 1 < n; ++i) {
    if (i > 0) units *= drift;
    const Sim3 rigid = g.truth[i].inverse() * g.truth[i + 1] *
                       rot(0.005 + 0.001 * N(rng), Eigen::Vector3d(0.1 * N(rng), 0.1 * N(rng), 1),
                           0.003 * Eigen::Vector3d(N(rng), N(rng), N(rng)));
    g.nodes.push_back({g.nodes.back().S_world_node * Sim3(rigid.rotation(), units * rigid.translation(), 1.0), false});
  }
  // Chain and covisibility edges from the drifted poses (plus a little noise), one true loop edge.
  for (int i = 0; i < n; ++i)
    for (int j = i + 1; j <= std::min(n - 1, i + covis); ++j) {
      const Sim3 meas = g.nodes[i].S_world_node.inverse() * g.nodes[j].S_world_node *
                        rot(0.0005 * N(rng), Eigen::Vector3d(N(rng), N(rng), N(rng)),
                            0.001 * Eigen::Vector3d(N(rng), N(rng), N(rng)));
      g.edges.push_back({i, j, meas, j == i + 1 ? 1.0 : 0.5});
    }
  const Sim3 loop = g.truth[n - 1].inverse() * g.truth[0];
  g.edges.push_back({n - 1, 0, Sim3(loop.rotation(), units * loop.translation(), sim3 ? units : 1.0), 1.0});
  return g;
}

double max_error(const std::vector<Sim3>& est, const std::vector<Sim3>& truth) {
  double m = 0;
  for (size_t i = 0; i < est.size(); ++i) m = std::max(m, (est[i].translation() - truth[i].translation()).norm());
  return m;
}

std::vector<Sim3Correspondence> make_matches(const StereoIntrinsics& k, const Sim3& S_12, int n, double outliers,
                                             std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  std::normal_distribution<double> N(0.0, 1.0);
  auto unproject = [&](const Eigen::Vector2d& uv, double z) {
    return Eigen::Vector3d((uv.x() - k.cx) / k.fx * z, (uv.y() - k.cy) / k.fy * z, z);
  };
  std::vector<Sim3Correspondence> out;
  while (int(out.size()) < n) {
    const Eigen::Vector2d uv2(20 + 600 * U(rng), 20 + 440 * U(rng));
    const double z2 = 1.0 + 3.0 * U(rng);
    const Eigen::Vector3d p1 = S_12 * unproject(uv2, z2);
    if (p1.z() < 0.5) continue;
    Sim3Correspondence m;
    m.uv1 = Eigen::Vector2d(k.fx * p1.x() / p1.z() + k.cx, k.fy * p1.y() / p1.z() + k.cy);
    if (m.uv1.x() < 0 || m.uv1.y() < 0 || m.uv1.x() >= 640 || m.uv1.y() >= 480) continue;
    m.uv1 += 0.5 * Eigen::Vector2d(N(rng), N(rng));
    m.uv2 = uv2 + 0.5 * Eigen::Vector2d(N(rng), N(rng));
    m.p1 = unproject(m.uv1, p1.z() * (1 + 0.002 * p1.z() * N(rng)));
    m.p2 = unproject(m.uv2, z2 * (1 + 0.002 * z2 * N(rng)));
    if (U(rng) < outliers) {
      m.uv1 = Eigen::Vector2d(20 + 600 * U(rng), 20 + 440 * U(rng));
      m.p1 = unproject(m.uv1, S_12.scale() * (1.0 + 3.0 * U(rng)));
    }
    out.push_back(m);
  }
  return out;
}

void print(const char* what, const RepeatTiming& t) {
  const Summary w = summarize(t.wall), c = summarize(t.cpu);
  std::printf("%-46s wall median %7.2f [%7.2f, %7.2f]  cpu median %7.2f [%7.2f, %7.2f] ms (n=%d)\n", what, w.median,
              w.min, w.max, c.median, c.min, c.max, w.n);
}

int run(int argc, char** argv) {
  CliArgs args("cslam-bench-loop",
               "Benchmark of essential-graph optimisation, Sim3 RANSAC and Sim3 refinement on synthetic data.");
  args.option("runs", "repetitions of each measurement", "15")
      .option("nodes", "keyframes in the essential graph", "200")
      .option("covis", "covisibility edges from each keyframe to the next K", "4")
      .option("iterations", "pose-graph max iterations", "20")
      .option("threads", "Ceres threads for the pose graph", "1")
      .option("matches", "matches for RANSAC / refinement", "300")
      .option("outliers", "fraction of wrong matches", "0.5");
  if (!args.parse(argc, argv)) return 0;
  const int runs = args.get_int("runs"), nodes = args.get_int("nodes"), covis = args.get_int("covis");
  const int nmatches = args.get_int("matches");
  const double outliers = args.get_double("outliers");
  if (runs < 1 || nodes < 3 || covis < 1 || nmatches < 3 || outliers < 0 || outliers >= 1)
    throw ConfigError("need --runs >= 1, --nodes >= 3, --covis >= 1, --matches >= 3, 0 <= --outliers < 1");
  PoseGraphConfig pcfg;
  pcfg.max_iterations = args.get_int("iterations");
  pcfg.threads = args.get_int("threads");

  for (bool sim3 : {false, true}) {
    const Graph g = make_graph(nodes, covis, sim3, 7);
    pcfg.fix_scale = !sim3;
    RepeatTiming ms;
    PoseGraphResult r;
    for (int i = 0; i < runs; ++i) ms.measure([&] { r = optimize_pose_graph(g.nodes, g.edges, pcfg); });
    std::vector<Sim3> before;
    for (const auto& n : g.nodes) before.push_back(n.S_world_node);
    char label[128];
    std::snprintf(label, sizeof label, "pose graph %s, %d nodes, %zu edges", sim3 ? "Sim3" : "SE3", nodes,
                  g.edges.size());
    print(label, ms);
    std::printf("    iterations %d, converged %d, cost %.4g -> %.4g, max position error %.3f -> %.3f m\n", r.iterations,
                int(r.converged), r.initial_cost, r.final_cost, max_error(before, g.truth),
                max_error(r.S_world_node, g.truth));
  }

  const StereoIntrinsics k{517.3, 516.5, 318.6, 255.3, 40.0};
  for (bool fix_scale : {true, false}) {
    const Sim3 truth = rot(0.3, {0.2, 1.0, 0.1}, {0.3, -0.1, 0.2}, fix_scale ? 1.0 : 1.3);
    const auto matches = make_matches(k, truth, nmatches, outliers, 11);
    Sim3RansacConfig cfg;
    cfg.fix_scale = fix_scale;
    RepeatTiming ms, ms_refine, ms_ceres;
    Sim3RansacResult rr;
    Sim3RefineResult rf, rf_ceres;
    double largest_difference = 0;
    int iterations_sum = 0;
    for (int i = 0; i < runs; ++i) {
      cfg.seed = std::uint64_t(i + 1);
      ms.measure([&] { rr = sim3_ransac(matches, k, k, cfg); });
      iterations_sum += rr.iterations;
      ms_refine.measure([&] { rf = refine_sim3(rr.S_12, matches, k, k, fix_scale); });
      ms_ceres.measure([&] { rf_ceres = refine_sim3_ceres(rr.S_12, matches, k, k, fix_scale); });
      largest_difference =
          std::max(largest_difference, rf.S_12.rotation().angularDistance(rf_ceres.S_12.rotation()) +
                                           (rf.S_12.translation() - rf_ceres.S_12.translation()).norm() +
                                           std::abs(std::log(rf.S_12.scale() / rf_ceres.S_12.scale())));
    }
    char label[128];
    std::snprintf(label, sizeof label, "sim3_ransac %s, %d matches, %.0f%% wrong", fix_scale ? "SE3" : "Sim3", nmatches,
                  100 * outliers);
    print(label, ms);
    std::printf(
        "    last run: success %d, inliers %d, mean samples %.1f, rot err %.3f deg, trans err %.4f m, scale %.4f (true "
        "%.2f)\n",
        int(rr.success), rr.num_inliers, double(iterations_sum) / runs,
        rr.S_12.rotation().angularDistance(truth.rotation()) * 180 / M_PI,
        (rr.S_12.translation() - truth.translation()).norm(), rr.S_12.scale(), truth.scale());
    std::snprintf(label, sizeof label, "refine_sim3 %s, %d matches", fix_scale ? "SE3" : "Sim3", nmatches);
    print(label, ms_refine);
    std::printf(
        "    last run: inliers %d, Huber cost of inliers %.4g -> %.4g, rot err %.3f deg, trans err %.4f m, scale "
        "%.4f\n",
        rf.num_inliers, rf.initial_cost, rf.final_cost,
        rf.S_12.rotation().angularDistance(truth.rotation()) * 180 / M_PI,
        (rf.S_12.translation() - truth.translation()).norm(), rf.S_12.scale());
    std::snprintf(label, sizeof label, "refine_sim3_ceres %s, %d matches (reference)", fix_scale ? "SE3" : "Sim3",
                  nmatches);
    print(label, ms_ceres);
    std::printf(
        "    largest difference to refine_sim3 over the runs: %.2e (rotation rad + translation m + log-scale)\n",
        largest_difference);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return run_main("cslam-bench-loop", argc, argv, run); }
