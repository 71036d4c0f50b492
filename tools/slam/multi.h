#pragma once
#include <string>

#include "core/cli.h"
#include "geometry/camera.h"
#include "lean_sim.h"

namespace cslam {
// Offline multi-client run: K clients and the fusion thread in one process, no network.
int run_multi_client(const CliArgs& args);
// The camera of a dataset folder (--camera, else what the folder says), with --readout applied.
PinholeCamera camera_for(const CliArgs& args, const std::string& dir);
// --depth-every, --depth-request-delay and --light-depth.
LeanStreamConfig lean_stream_config(const CliArgs& args);
}  // namespace cslam
