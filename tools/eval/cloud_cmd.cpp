// cslam-eval cloud: accuracy of a reconstructed cloud against a reference cloud (the paper's
// Table III): one-sided and symmetric Hausdorff distance, C2C mean/median/95th percentile,
// completeness, optionally after CloudCompare-style bounding-box centre + scale matching.
#include <cstdio>
#include <iostream>

#include <nlohmann/json.hpp>

#include "cloud/cloud_metrics.h"
#include "cloud/ply_io.h"
#include "core/cli.h"
#include "core/error.h"
#include "core/stopwatch.h"
#include "io/trajectory_io.h"

namespace cslam {

namespace {

// The rigid transform that took a trajectory to its aligned copy (cslam-eval ate --aligned):
// aligned_i = T * estimate_i for every pose; taken from the first pose pair with equal stamps.
SE3 alignment_between(const std::string& estimate_path, const std::string& aligned_path) {
  const Trajectory est = read_tum_trajectory(estimate_path), aligned = read_tum_trajectory(aligned_path);
  for (const auto& a : aligned)
    for (const auto& e : est)
      if (e.timestamp == a.timestamp) return a.T_world_cam * e.T_world_cam.inverse();
  throw InputError(aligned_path, "no pose with the same time stamp as in " + estimate_path);
}

nlohmann::json distance_json(const DistanceStats& s) {
  return {{"n", s.n}, {"mean", s.mean}, {"median", s.median}, {"p95", s.p95}, {"max", s.max}, {"rmse", s.rmse}};
}

}  // namespace

int cmd_cloud(int argc, char** argv) {
  CliArgs args(
      "cslam-eval cloud",
      "Cloud-to-cloud distances of TEST against REF (metres): Hausdorff TEST->REF, REF->TEST and symmetric; "
      "mean/median/95th percentile of TEST->REF nearest-neighbour distances (C2C); completeness = share of REF "
      "points within 2 cm / 5 cm of TEST.");
  args.positional("REF", "reference cloud, PLY (e.g. scene.ply or the ground-truth-pose cloud)")
      .positional("TEST", "cloud to evaluate, PLY")
      .flag("match-bbox",
            "first translate TEST so the bounding-box centres coincide and scale it about that centre so the "
            "bounding-box diagonals are equal (the paper's CloudCompare step)")
      .option("move-from",
              "with --move-to: move TEST by the rigid transform that takes this trajectory (TUM) to the "
              "--move-to one (e.g. a SLAM trajectory and its copy aligned by cslam-eval ate --aligned)",
              "")
      .option("move-to", "the aligned trajectory for --move-from", "")
      .option("threads", "threads for the nearest-neighbour queries", "2")
      .flag("json", "print JSON instead of a table");
  if (!args.parse(argc, argv, 2)) return 0;
  const std::string ref_path = args.positionals()[0], test_path = args.positionals()[1];
  const ColoredCloud ref = read_ply(ref_path);
  ColoredCloud test = read_ply(test_path);
  if (args.get("move-from").empty() != args.get("move-to").empty())
    throw ConfigError("cslam-eval cloud: --move-from and --move-to go together");
  if (!args.get("move-from").empty()) {
    const SE3 T = alignment_between(args.get("move-from"), args.get("move-to"));
    const Eigen::Matrix3f R = T.R().cast<float>();
    const Eigen::Vector3f t = T.translation().cast<float>();
    for (auto& p : test.points) p = R * p + t;
  }
  if (ref.empty()) throw InputError(ref_path, "cloud has no points");
  if (test.empty()) throw InputError(test_path, "cloud has no points");
  CloudCompareConfig cfg;
  cfg.match_bbox = args.flag_set("match-bbox");
  cfg.threads = args.get_int("threads");
  Stopwatch sw;
  const CloudComparison c = compare_clouds(ref.points, test.points, cfg);
  const double ms = sw.ms();
  if (args.flag_set("json")) {
    nlohmann::json j;
    j["ref_points"] = c.ref_points;
    j["test_points"] = c.test_points;
    j["hausdorff"] = {{"test_to_ref", c.hausdorff_test_to_ref},
                      {"ref_to_test", c.hausdorff_ref_to_test},
                      {"symmetric", c.hausdorff_symmetric}};
    j["c2c_test_to_ref"] = distance_json(c.test_to_ref);
    j["c2c_ref_to_test"] = distance_json(c.ref_to_test);
    for (const auto& [thr, share] : c.completeness)
      j["completeness"][std::to_string(int(thr * 100 + 0.5)) + "cm"] = share;
    j["bbox_matched"] = c.bbox_matched;
    if (c.bbox_matched) {
      j["bbox"] = {{"scale", c.bbox.scale},
                   {"center_ref", {c.bbox.center_ref.x(), c.bbox.center_ref.y(), c.bbox.center_ref.z()}},
                   {"center_test", {c.bbox.center_test.x(), c.bbox.center_test.y(), c.bbox.center_test.z()}}};
    }
    j["time_ms"] = ms;
    std::cout << j.dump(2) << "\n";
    return 0;
  }
  std::printf("REF  %s: %zu points\nTEST %s: %zu points\n", ref_path.c_str(), c.ref_points, test_path.c_str(),
              c.test_points);
  if (c.bbox_matched) {
    const Eigen::Vector3f d = c.bbox.center_ref - c.bbox.center_test;
    std::printf("bbox matching: scale %.6f about the TEST centre, translation %.4f %.4f %.4f m\n", c.bbox.scale, d.x(),
                d.y(), d.z());
  }
  std::printf("Hausdorff (m): TEST->REF %.6f  REF->TEST %.6f  symmetric %.6f\n", c.hausdorff_test_to_ref,
              c.hausdorff_ref_to_test, c.hausdorff_symmetric);
  std::printf("%-12s %10s %10s %10s %10s %10s\n", "C2C (m)", "mean", "median", "p95", "max", "rmse");
  for (const auto& [name, s] :
       {std::pair<const char*, DistanceStats>{"TEST->REF", c.test_to_ref}, {"REF->TEST", c.ref_to_test}})
    std::printf("%-12s %10.6f %10.6f %10.6f %10.6f %10.6f\n", name, s.mean, s.median, s.p95, s.max, s.rmse);
  std::printf("completeness (REF points within):");
  for (const auto& [thr, share] : c.completeness) std::printf("  %.0f cm %.2f%%", thr * 100, share * 100);
  std::printf("\n(%.0f ms)\n", ms);
  return 0;
}

}  // namespace cslam
