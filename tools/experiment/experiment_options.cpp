#include "experiment_options.h"

#include <cmath>
#include <filesystem>

#include <unistd.h>

#include "codec/byte_budget.h"
#include "core/error.h"

namespace cslam::experiment {

namespace {

std::string own_directory() {
  std::error_code ec;
  const auto exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  return ec ? std::string(".") : exe.parent_path().string();
}

}  // namespace

void declare_options(CliArgs& args) {
  args.option("dataset",
              "one TUM-layout sequence, split into K clients with the paper's ranges (e.g. ../shared/data/tum_fr1_rpy)",
              "")
      .multi_option("datasets",
                    "one dataset folder per client instead (no split), e.g. cslam-synth's robot_1 robot_2 robot_3")
      .option("synthetic",
              "cslam-synth output folder (robot_K + scene.ply); generated with --synth-preset if it does not exist", "")
      .option("synth-preset", "preset for generating --synthetic (demo | test-small)", "")
      .option("scene", "exact surface (PLY) to measure the reconstructions against; default: scene.ply of --synthetic",
              "")
      .option("out", "report folder (report.md, results.csv, results.json, figures/, runs/)")
      .option("clients", "client counts, e.g. 1,2,3 (1 = the single-client baseline); --quick: 1,2", "")
      .option("overlaps", "overlap rates eta in percent, e.g. 0.5,2.5,5,10 (split mode); --quick: 5", "")
      .option(
          "mode",
          "network (cslam-server + cslam-client processes over loopback) | live (network, clients streaming live at\n"
          "      the dataset's own clock, --rate ignored) | offline (cslam-slam)",
          "network")
      .option("repeat", "runs per configuration (medians and min-max are reported); --quick: 1", "")
      .flag("quick",
            "reduced matrix for CI: K = 1 and 2 at one eta, 1 repeat, coarse reconstruction; without data options "
            "it generates and uses the small synthetic scene (cslam-synth --preset test-small) in OUT")
      .option("timeout",
              "seconds per run before its processes are stopped and the run is reported as failed; --quick: 180", "")
      .option("rate", "client send rate in network mode: frames/s or 'max'", "max")
      .option("depth-every",
              "network/live: every cslam-client sends a lean stream (cslam-client --depth-every K): full frames every "
              "K-th frame and when the server asks, light frames (H.264 colour, depth at 1/4 of each axis) between; 1: "
              "every frame full",
              "1")
      .option("byte-budget",
              "network/live: every cslam-client spends this many MB/s on finer colour for the full frames the server "
              "expects to become keyframes (cslam-client --byte-budget); 0: none",
              "0")
      .option("camera",
              "camera preset or file for the dataset (default: DATASET/camera.yaml, else its calibration.txt (fx fy cx "
              "cy), else the TUM camera its folder name says (freiburg1..3, fr1..3), else tum1)",
              "")
      .option("bin-dir",
              "folder of cslam-slam, cslam-server, cslam-client, cslam-synth (default: this program's folder)", "")
      .option("recon-voxel", "voxel size (m) of the reconstructions for Table III; --quick: 0.04", "")
      .option("recon-stride", "back-project every n-th pixel; --quick: 8", "")
      .option("recon-max-depth", "maximum depth (m) used in the reconstructions", "4.0")
      .flag("no-recon", "skip the reconstructions (Table III n/a)")
      .flag("keep-clouds",
            "also write each run's SLAM-pose cloud and the ground-truth-pose clouds (PLY) under OUT/runs");
}

std::string shell_command(int argc, char** argv) {
  std::string out;
  for (int i = 0; i < argc; ++i) {
    const std::string a = argv[i];
    const bool plain =
        !a.empty() && a.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-+=/.,:%@") ==
                          std::string::npos;
    std::string q = a;
    if (!plain) {
      q = "'";
      for (char c : a) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
      q += "'";
    }
    out += (i ? " " : "") + q;
  }
  return out;
}

ExperimentOptions options_from(const CliArgs& args, int argc, char** argv) {
  const std::string p = "cslam-experiment: ";
  ExperimentOptions o;
  o.quick = args.flag_set("quick");
  o.dataset = args.get("dataset");
  o.datasets = args.get_multi("datasets");
  o.synthetic_dir = args.get("synthetic");
  o.scene_ply = args.get("scene");
  o.out_dir = args.get("out");
  const int sources = int(!o.dataset.empty()) + int(!o.datasets.empty()) + int(!o.synthetic_dir.empty());
  if (sources > 1) throw ConfigError(p + "give only one of --dataset, --datasets, --synthetic");
  if (sources == 0) {
    if (!o.quick)
      throw ConfigError(p + "no data: give --dataset DIR, --datasets DIR1 DIR2 ... or --synthetic DIR (see --help)");
    o.synthetic_dir = o.out_dir + "/synthetic_test-small";  // --quick alone: the small synthetic scene
  }
  o.synth_preset = args.has("synth-preset") ? args.get("synth-preset") : (sources == 0 ? "test-small" : "demo");
  if (o.synth_preset != "demo" && o.synth_preset != "test-small")
    throw ConfigError(p + "--synth-preset must be demo or test-small, got '" + o.synth_preset + "'");
  if (!o.scene_ply.empty() && !std::filesystem::exists(o.scene_ply))
    throw ConfigError(p + "--scene " + o.scene_ply + " does not exist");

  o.clients = parse_client_counts(args.has("clients") ? args.get("clients") : o.quick ? "1,2" : "1,2,3");
  o.overlaps_percent = parse_overlaps(args.has("overlaps") ? args.get("overlaps") : o.quick ? "5" : "0.5,2.5,5,10");
  o.mode = parse_mode(args.get("mode"));
  o.repeat = args.has("repeat") ? args.get_int("repeat") : 1;
  if (o.repeat < 1 || o.repeat > 100) throw ConfigError(p + "--repeat must be 1..100");
  o.timeout_s = args.has("timeout") ? args.get_double("timeout") : o.quick ? 180 : 900;
  if (!(o.timeout_s > 0)) throw ConfigError(p + "--timeout must be positive seconds");
  o.rate = args.get("rate");
  if (o.rate != "max") {
    const double r = args.get_double("rate");
    if (!(r > 0)) throw ConfigError(p + "--rate must be positive frames/s or 'max'");
  }
  o.depth_every = args.get_int("depth-every");
  if (o.depth_every < 1) throw ConfigError(p + "--depth-every must be >= 1");
  o.byte_budget_mb = args.get_double("byte-budget");
  try {
    ByteBudgetConfig{o.byte_budget_mb * 1e6}.validate();  // the rule cslam-client applies to it
  } catch (const ConfigError& e) {
    throw ConfigError(p + "--byte-budget: " + e.what());
  }
  o.camera = args.get("camera");
  o.bin_dir = args.has("bin-dir") ? args.get("bin-dir") : own_directory();
  o.recon.enabled = !args.flag_set("no-recon");
  o.recon.keep_clouds = args.flag_set("keep-clouds");
  o.recon.voxel = args.has("recon-voxel") ? args.get_double("recon-voxel") : o.quick ? 0.04 : 0.02;
  o.recon.stride = args.has("recon-stride") ? args.get_int("recon-stride") : o.quick ? 8 : 4;
  o.recon.max_depth = args.get_double("recon-max-depth");
  if (!(o.recon.voxel > 0) || o.recon.stride < 1 || !(o.recon.max_depth > 0.3))
    throw ConfigError(p + "--recon-voxel must be > 0, --recon-stride >= 1, --recon-max-depth > 0.3");

  std::vector<std::string> programs;
  if (o.mode == RunMode::kOffline)
    programs = {"cslam-slam"};
  else
    programs = {"cslam-server", "cslam-client"};
  if (!o.synthetic_dir.empty() && !std::filesystem::exists(o.synthetic_dir + "/scene.ply"))
    programs.push_back("cslam-synth");
  for (const auto& prog : programs) {
    const std::string path = o.bin_dir + "/" + prog;
    if (::access(path.c_str(), X_OK) != 0)
      throw ConfigError(p + path + " not found or not executable (build it: cmake --build build --target " + prog +
                        ", or give --bin-dir)");
  }
  o.command_line = shell_command(argc, argv);
  return o;
}

}  // namespace cslam::experiment
