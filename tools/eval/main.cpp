// cslam-eval: trajectory and dataset evaluation (ATE, RPE, the paper's split) and cloud accuracy.
#include <cstdio>
#include <iostream>

#include <nlohmann/json.hpp>

#include "core/cli.h"
#include "core/error.h"
#include "eval/split.h"
#include "eval/trajectory_eval.h"
#include "io/trajectory_io.h"

using namespace cslam;

namespace cslam {
int cmd_cloud(int argc, char** argv);   // cloud_cmd.cpp
int cmd_events(int argc, char** argv);  // events_cmd.cpp
}  // namespace cslam

namespace {

nlohmann::json stats_json(const ErrorStats& s) {
  return {{"n", s.n},           {"max", s.max},   {"min", s.min}, {"mean", s.mean},
          {"median", s.median}, {"rmse", s.rmse}, {"std", s.std}};
}

void print_stats(const char* unit, const ErrorStats& s) {
  std::printf("%-6s %8s %10s %10s %10s %10s %10s %10s\n", unit, "n", "max", "min", "mean", "median", "rmse", "std");
  std::printf("%-6s %8d %10.6f %10.6f %10.6f %10.6f %10.6f %10.6f\n", "", s.n, s.max, s.min, s.mean, s.median, s.rmse,
              s.std);
}

int cmd_ate(int argc, char** argv) {
  CliArgs args("cslam-eval ate", "Absolute pose error (translation, metres) of EST against GT after alignment.");
  args.positional("GT", "ground-truth trajectory, TUM format")
      .positional("EST", "estimated trajectory, TUM format")
      .option("align", "se3 | sim3 | none", "se3")
      .option("max-dt", "maximum timestamp difference for association (s)", "0.02")
      .option("per-pose", "write 'timestamp error_m' per associated pose to this file", "")
      .multi_option("also",
                    "more GT EST pairs evaluated with the same single alignment (a fused group: one\n"
                    "      pair per client, each associated on its own), e.g. --also gt2.txt est2.txt")
      .multi_option("aligned",
                    "write each estimate (EST, then the --also ones) transformed by the alignment to these files")
      .flag("json", "print JSON instead of a table");
  if (!args.parse(argc, argv, 2)) return 0;
  std::vector<std::pair<Trajectory, Trajectory>> pairs;
  {
    Trajectory gt = read_tum_trajectory(args.positionals()[0]);  // ground truth first: its errors are reported first
    Trajectory est = read_tum_trajectory(args.positionals()[1]);
    pairs.emplace_back(std::move(gt), std::move(est));
  }
  const auto also = args.get_multi("also");
  if (also.size() % 2 != 0) throw ConfigError("--also takes pairs: GT EST [GT EST ...]");
  for (size_t i = 0; i < also.size(); i += 2) {
    Trajectory gt = read_tum_trajectory(also[i]);
    Trajectory est = read_tum_trajectory(also[i + 1]);
    pairs.emplace_back(std::move(gt), std::move(est));
  }
  const auto r = compute_ate_joint(pairs, parse_alignment(args.get("align")), args.get_double("max-dt"));
  const auto aligned_out = args.get_multi("aligned");
  if (!aligned_out.empty() && aligned_out.size() != pairs.size())
    throw ConfigError("--aligned needs one output file per estimate (" + std::to_string(pairs.size()) + ")");
  for (size_t i = 0; i < aligned_out.size(); ++i) {
    Trajectory moved = pairs[i].second;
    for (auto& p : moved) p.T_world_cam = apply_sim3_to_pose(r.T_gt_est, p.T_world_cam);
    write_tum_trajectory(aligned_out[i], moved, "aligned to ground truth");
  }
  if (args.has("per-pose")) {
    std::FILE* f = std::fopen(args.get("per-pose").c_str(), "w");
    if (!f) throw InputError(args.get("per-pose"), "cannot write");
    std::fprintf(f, "# timestamp ape_m\n");
    for (size_t i = 0; i < r.errors.size(); ++i) std::fprintf(f, "%.6f %.6f\n", r.timestamps[i], r.errors[i]);
    std::fclose(f);
  }
  if (args.flag_set("json")) {
    nlohmann::json j = stats_json(r.stats);
    j["align"] = args.get("align");
    j["scale"] = r.T_gt_est.scale();
    std::cout << j.dump(2) << "\n";
  } else {
    std::printf("APE translation (m), %s alignment, scale %.4f\n", args.get("align").c_str(), r.T_gt_est.scale());
    print_stats("m", r.stats);
  }
  return 0;
}

int cmd_rpe(int argc, char** argv) {
  CliArgs args("cslam-eval rpe", "Relative pose error of EST against GT over a time delta.");
  args.positional("GT", "ground-truth trajectory, TUM format")
      .positional("EST", "estimated trajectory, TUM format")
      .option("delta", "time between the two poses of a pair, e.g. 1s or 0.5", "1s")
      .option("max-dt", "maximum timestamp difference for association (s)", "0.02")
      .flag("json", "print JSON instead of a table");
  if (!args.parse(argc, argv, 2)) return 0;
  std::string d = args.get("delta");
  if (!d.empty() && d.back() == 's') d.pop_back();
  double delta = 0;
  try {
    delta = std::stod(d);
  } catch (const std::exception&) {
    throw ConfigError("--delta expects seconds, e.g. 1s");
  }
  if (!(delta > 0)) throw ConfigError("--delta must be positive");
  const auto r = compute_rpe(read_tum_trajectory(args.positionals()[0]), read_tum_trajectory(args.positionals()[1]),
                             delta, args.get_double("max-dt"));
  if (args.flag_set("json")) {
    std::cout << nlohmann::json{{"delta_s", delta},
                                {"translation_m", stats_json(r.translation)},
                                {"rotation_deg", stats_json(r.rotation)}}
                     .dump(2)
              << "\n";
  } else {
    std::printf("RPE over %.3f s\n", delta);
    print_stats("m", r.translation);
    print_stats("deg", r.rotation);
  }
  return 0;
}

int cmd_split(int argc, char** argv) {
  CliArgs args("cslam-eval split",
               "Frame ranges (1-based, inclusive) of the paper's K-client split with overlap rate ETA.");
  args.option("frames", "number of associated RGB-D frames N")
      .option("clients", "number of clients K")
      .option("overlap", "overlap rate eta, as a fraction (0.05) or percent (5%)")
      .flag("json", "print JSON");
  if (!args.parse(argc, argv, 2)) return 0;
  const double eta = parse_overlap_rate(args.get("overlap"));
  const auto r = split_sequence(args.get_int("frames"), args.get_int("clients"), eta);
  if (args.flag_set("json")) {
    nlohmann::json j;
    j["delta"] = r.delta;
    for (const auto& fr : r.ranges) j["ranges"].push_back({fr.first, fr.last});
    std::cout << j.dump() << "\n";
  } else {
    std::printf("# N=%d K=%d eta=%.4f delta=%.2f frames\n", args.get_int("frames"), args.get_int("clients"), eta,
                r.delta);
    for (size_t k = 0; k < r.ranges.size(); ++k)
      std::printf("client %zu: %d %d\n", k + 1, r.ranges[k].first, r.ranges[k].last);
  }
  return 0;
}

const char* kUsage =
    "Usage: cslam-eval COMMAND [options]\n"
    "Commands:\n"
    "  ate GT EST [--align se3|sim3|none] [--max-dt 0.02] [--json]   absolute pose error\n"
    "  rpe GT EST [--delta 1s] [--json]                              relative pose error\n"
    "  split --frames N --clients K --overlap ETA                    the paper's client frame ranges\n"
    "  cloud REF.ply TEST.ply [--match-bbox] [--json]                Hausdorff / C2C / completeness of a cloud\n"
    "  events STATS.json --gt GT [--offset S|auto --est EST]         loop / fusion transforms vs ground truth\n"
    "Run 'cslam-eval COMMAND --help' for a command's options.\n";

int run(int argc, char** argv) {
  if (argc < 2 || std::string(argv[1]) == "--help" || std::string(argv[1]) == "-h") {
    std::cout << kUsage;
    return argc < 2 ? 2 : 0;
  }
  const std::string cmd = argv[1];
  if (cmd == "ate") return cmd_ate(argc, argv);
  if (cmd == "rpe") return cmd_rpe(argc, argv);
  if (cmd == "split") return cmd_split(argc, argv);
  if (cmd == "cloud") return cslam::cmd_cloud(argc, argv);
  if (cmd == "events") return cslam::cmd_events(argc, argv);
  std::cerr << "cslam-eval: unknown command '" << cmd << "'\n" << kUsage;
  return 2;
}

}  // namespace

// Errors name the subcommand: "cslam-eval ate: ...".
int main(int argc, char** argv) {
  const std::string program = argc < 2 ? "cslam-eval" : "cslam-eval " + std::string(argv[1]);
  return run_main(program.c_str(), argc, argv, run);
}
