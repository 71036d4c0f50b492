#pragma once
// Runs the SLAM of one configuration with the project's programs: offline (cslam-slam, single or
// multi-client) or over the network (cslam-server + one cslam-client per client on loopback).
// Logs go to the run folder, outputs to RUN_DIR/out; nothing is evaluated here.
#include <string>

#include "experiment_config.h"

namespace cslam::experiment {

struct RunOutcome {
  bool ok = false;
  std::string error;          // one line: which process, its exit status, the end of its log
  double process_wall_s = 0;  // first process started to last process exited
};

// Programs are taken from options.bin_dir. Never throws for a failing run (reported in the
// outcome); throws Interrupted if the harness is interrupted (children already stopped).
RunOutcome run_slam(const RunConfig& config, const ExperimentOptions& options, const std::string& run_dir);

// Where a run's outputs are: RUN_DIR/out.
std::string run_output_dir(const std::string& run_dir);

}  // namespace cslam::experiment
