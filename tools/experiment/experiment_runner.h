#pragma once
// The whole experiment: resolves the data (generating the synthetic scene if asked), expands the
// matrix, runs every configuration `repeat` times (in rounds), evaluates each run as it finishes,
// and writes the report. A failing run is recorded with its error and the next one starts.
#include "experiment_config.h"

namespace cslam::experiment {

// Returns the number of failed runs. Throws ConfigError / InputError for bad options or data
// (before any run), Interrupted if the harness was interrupted (children stopped, partial
// results.csv/json written).
int run_experiment(const ExperimentOptions& options);

}  // namespace cslam::experiment
