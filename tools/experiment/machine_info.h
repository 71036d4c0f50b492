#pragma once
// The machine a report was measured on: cores, CPU model, memory, load averages, source revision.
#include <string>

namespace cslam::experiment {

struct MachineInfo {
  int cores = 0;
  std::string cpu_model, kernel;
  double memory_gb = 0;
};
MachineInfo machine_info();

// "/proc/loadavg" as "1.02 0.88 0.61" and the 1-minute value (NaN if unreadable).
std::string load_average_text();
double load_average_1min();

// "abc1234" or "abc1234 + uncommitted changes" of the source tree; "unknown" without git.
// Runs git with its output in log_path.
std::string source_revision(const std::string& source_dir, const std::string& log_path);

// Current UTC time, "2026-11-21 14:03 UTC".
std::string utc_now();

}  // namespace cslam::experiment
