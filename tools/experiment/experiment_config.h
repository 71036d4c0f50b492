#pragma once
// Options of cslam-experiment and the matrix of configurations they expand to.
#include <limits>
#include <string>
#include <vector>

namespace cslam::experiment {

// kLive: network mode with the clients streaming live (cslam-client --live: the dataset's own
// clock, newest frame only when out of credit; the server skips stale frames).
enum class RunMode { kOffline, kNetwork, kLive };
const char* to_string(RunMode mode);
RunMode parse_mode(const std::string& text);  // "offline" | "network" | "live"; throws ConfigError

struct ReconOptions {
  bool enabled = true;
  double voxel = 0.02;       // voxel-grid leaf (m) of both clouds
  int stride = 4;            // back-project every n-th pixel
  double max_depth = 4.0;    // metres
  bool keep_clouds = false;  // write each run's SLAM cloud (and the ground-truth cloud) as PLY
};

struct ExperimentOptions {
  // Data: exactly one of these. dataset: one sequence split with the paper's ranges;
  // datasets: one folder per client (no split); synthetic_dir: cslam-synth output (generated if missing).
  std::string dataset;
  std::vector<std::string> datasets;
  std::string synthetic_dir, synth_preset = "demo";
  std::string scene_ply;  // exact surface for reconstruction accuracy (synthetic: DIR/scene.ply)
  std::string out_dir;
  std::vector<int> clients{1, 2, 3};
  std::vector<double> overlaps_percent{0.5, 2.5, 5, 10};
  RunMode mode = RunMode::kNetwork;
  int repeat = 1;
  bool quick = false;
  double timeout_s = 900;  // per run (SLAM processes only)
  std::string rate = "max";
  int depth_every = 1;        // network/live: cslam-client --depth-every (lean stream when > 1)
  double byte_budget_mb = 0;  // network/live: cslam-client --byte-budget (MB/s; 0: none)
  std::string camera;         // passed to the SLAM programs if set
  std::string bin_dir;        // where cslam-slam, cslam-server, cslam-client, cslam-synth live
  ReconOptions recon;
  std::string command_line;  // as given, for the report
};

// Values in --overlaps are percent ("5" or "5%" = 5 %). Throws ConfigError naming the bad item.
std::vector<double> parse_overlaps(const std::string& text);
// "1,2,3" -> {1, 2, 3}; each >= 1 and <= max_clients, no duplicates. Throws ConfigError.
std::vector<int> parse_client_counts(const std::string& text, int max_clients = 16);

// One client of a run: its dataset and its frames (1-based, inclusive, of the associated pairs).
struct ClientSpec {
  int id = 1;
  std::string dataset;
  int first = 1, last = 1;
  int count() const { return last - first + 1; }
};

struct RunConfig {
  std::string name;   // folder/file-safe: single, k2_eta5, single_robot_1, k3
  std::string label;  // table text: "single", "2 clients", "single (robot_2)"
  int clients = 1;
  double overlap_percent = std::numeric_limits<double>::quiet_NaN();  // NaN: not a split
  bool split = false;                                                 // clients share one dataset (the paper's split)
  std::vector<ClientSpec> specs;
};

// Split mode: K = 1 is the whole sequence ("single"); K >= 2 once per overlap rate.
// Datasets mode: K = 1 is one single run per dataset; K >= 2 uses the first K datasets.
// frame_counts: associated RGB-D pairs per dataset (one entry in split mode).
std::vector<RunConfig> build_matrix(const ExperimentOptions& options, const std::vector<std::string>& dataset_dirs,
                                    const std::vector<int>& frame_counts);

// "0.5" -> "0.5", "10" -> "10", "2.50" -> "2.5": overlap rates in names and tables.
std::string overlap_text(double percent);

}  // namespace cslam::experiment
