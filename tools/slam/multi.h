#pragma once
#include "core/cli.h"

namespace cslam {
// Offline multi-client run: K clients and the fusion thread in one process, no network.
int run_multi_client(const CliArgs& args);
}  // namespace cslam
