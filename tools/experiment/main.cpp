// cslam-experiment: reproduces the paper's Tables II and III and its figures. For every
// configuration (single client; K clients x overlap rate) and repeat it runs the SLAM with the
// project's programs (offline or over the network), evaluates trajectories and reconstructions
// against ground truth and writes report.md, results.csv, results.json and SVG figures.
#include "core/cli.h"
#include "experiment_options.h"
#include "experiment_runner.h"

using namespace cslam;
using namespace cslam::experiment;

namespace {

int run(int argc, char** argv) {
  CliArgs args(
      "cslam-experiment",
      "Runs the paper's experiment matrix (single client; K clients x overlap rate eta) with the cslam programs, "
      "evaluates SLAM time, APE of the combined trajectory, map fusion and dense reconstruction accuracy, and writes "
      "OUT/report.md (Tables II and III), OUT/results.csv, OUT/results.json and OUT/figures/*.svg. "
      "Exit code 0: every run succeeded; 3: report written but some runs failed; 1/2: error.");
  declare_options(args);
  if (!args.parse(argc, argv)) return 0;
  ExperimentOptions options = options_from(args, argc, argv);
  const int failed = run_experiment(options);
  return failed == 0 ? 0 : 3;
}

}  // namespace

int main(int argc, char** argv) { return run_main("cslam-experiment", argc, argv, run); }
