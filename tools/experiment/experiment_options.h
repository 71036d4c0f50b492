#pragma once
// Command line of cslam-experiment -> ExperimentOptions (validated; --quick fills in the reduced
// matrix where an option was not given).
#include "core/cli.h"
#include "experiment_config.h"

namespace cslam::experiment {

void declare_options(CliArgs& args);

// Throws ConfigError with a one-line message on a bad or inconsistent option.
ExperimentOptions options_from(const CliArgs& args, int argc, char** argv);

// The command line re-quoted for a shell (for "reproduce with" lines).
std::string shell_command(int argc, char** argv);

}  // namespace cslam::experiment
